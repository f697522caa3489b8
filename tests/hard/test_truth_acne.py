"""The truth on noisy maps: no shadow acne at grazing light, on mesh vertices (samples exactly on
texel centres) or at jittered samples; and a soft light of tiny radius converges to the hard one.

The reference is the displaced mesh's exact horizon in float64 (:func:`tests.hard._ref.mesh_horizon_tan`).
A sample is certainly in shadow when its own triangle faces away from the light or the surface
at least 0.05 texel away rises above the ray, by more than 3e-3 in tangent (0.17 degrees at
grazing: the truth's ray starts 1.2e-4 texels above the surface, which hides at most
1.2e-4 / 0.05 = 2.4e-3 of an occluder's tangent at that distance); certainly lit when both
stay as far below and nothing closer rises above the ray. Samples moved a few ulps off a mesh
vertex sit beside creases whose occlusion is a matter of those ulps: they, and the few within
the margin, are left out (counted, and bounded). Every certain sample must agree.
"""

import math

import numpy as np
import pytest

from hzval.core import conventions as cv
from hzval.scene import camera as hz_camera
from hzval.scene import spec as sc
from hzval.truth.samples import off_edge_lines as _off_edge_lines

from ._ref import classify, mesh_horizon_tan, mesh_triangles, texel_centres_flat, truth

pytestmark = pytest.mark.hard

N = 24
MARGIN = 3e-3
#: Azimuths along mesh edges (0, 90: rows and columns; 45: the quads' diagonals) and between.
AZIMUTHS = (0.0, 45.0, 90.0, 37.0, 200.0)


@pytest.fixture(scope="module")
def noise(variant):
    """A 24x24 uniform-noise map with 1 texel of relief (slopes up to 1:1)."""
    return np.random.default_rng(7).random((N, N)).astype(np.float32), 1.0 / N


def per_sample_visibility(t, azimuth):
    (st,) = t._kept  # a small image: one band, kept between frames
    return np.asarray(t._visible(st.o, st.n, *t.light_directions(azimuth, st)))


@pytest.mark.parametrize(
    "boundary,elevation,where",
    [
        ("open", 2.0, "vertices"),
        ("open", 2.0, "jittered"),
        ("wrap", 5.0, "vertices"),
        ("open", 0.5, "vertices"),
    ],
)
def test_no_acne_and_no_leaks_at_grazing_light(noise, boundary, elevation, where):
    h, depth = noise
    if where == "vertices":
        xs, ys = texel_centres_flat(N, N)
        t = truth(h, depth, boundary, positions=(xs, ys), elevation=elevation, spp=1)
    else:
        t = truth(h, depth, boundary, elevation=elevation, spp=4)
        xs, ys = hz_camera.sample_positions(N, N, sc.Camera(), 4, 0)
    if where == "vertices":
        assert t.moved_off_edges == xs.size
    mx, my, _ = _off_edge_lines(xs, ys, N, N, t.edge_level)
    # the truth's mesh carries a margin for 10 degrees and hops beyond it; the reference
    # sees its own margin only, so it gets one wide enough for the ray to clear the top
    ref_margin = math.ceil((1.0 + 1e-3) / math.tan(math.radians(elevation))) + 2
    tris = mesh_triangles(
        cv.heights_in_texels(h, depth), boundary, margin=ref_margin if boundary == "wrap" else None
    )
    left_out = 0
    for az in AZIMUTHS:
        V = per_sample_visibility(t, az)
        ref = mesh_horizon_tan(tris, mx, my, az)
        lit, shadowed = classify(ref, elevation, MARGIN)
        assert lit.sum() >= 0.02 * V.size and shadowed.sum() >= 0.02 * V.size, az  # both occur
        assert np.all(V[lit] == 1.0), (az, "false shadows (acne)", np.flatnonzero(lit & (V == 0)))
        assert np.all(V[shadowed] == 0.0), (az, "light leaks", np.flatnonzero(shadowed & (V == 1)))
        left_out += int((~(lit | shadowed)).sum())
    print(f"{boundary}, {elevation} deg, {where}: {left_out} of {V.size * len(AZIMUTHS)} samples left out")
    assert left_out <= 0.05 * V.size * len(AZIMUTHS)


@pytest.mark.parametrize("radius", [0.1, 0.01, 0.001])
def test_soft_light_of_tiny_radius_converges_to_the_hard_one(noise, radius):
    """A disk light of radius rho differs from the hard light only for samples whose horizon along
    the azimuth is within about rho of the elevation: every certain sample (by 3e-3 in tangent,
    i.e. 0.17 degrees, more than rho) keeps the hard answer; the pixel means converge."""
    h, depth = noise
    e = 5.0
    hard = truth(h, depth, "open", elevation=e, spp=4)
    soft = truth(h, depth, "open", elevation=e, spp=4, kind="soft", radius=radius)
    xs, ys = hz_camera.sample_positions(N, N, sc.Camera(), 4, 0)
    mx, my, _ = _off_edge_lines(xs, ys, N, N, hard.edge_level)
    tris = mesh_triangles(cv.heights_in_texels(h, depth), "open")
    diffs = []
    for az in (0.0, 37.0, 200.0):
        Vh, Vs = per_sample_visibility(hard, az), per_sample_visibility(soft, az)
        lit, shadowed = classify(mesh_horizon_tan(tris, mx, my, az), e, MARGIN)
        certain = lit | shadowed
        assert np.array_equal(Vs[certain], Vh[certain]), az
        diffs.append(np.abs(Vs - Vh).mean())
        ph, ps = hard.render(az).layers["visibility"], soft.render(az).layers["visibility"]
        assert np.abs(ph - ps).mean() <= (~certain).mean() + 1e-12
    assert max(diffs) <= 0.02
