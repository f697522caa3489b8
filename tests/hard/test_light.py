"""Light at the hard angles: grazing, zenith, below the horizon; azimuths on channel directions,
bin edges, 360 and -0. For the truth (hzval.truth.plane.Truth) and the approximation on both paths.

What each must give, known in advance:
* every value finite; V, F in [0, 1]; images >= 0;
* below or on the horizon (e <= 0): no light at all (V = 0, image = 0; F = 0 once
  Lz <= -1/k, eq. 5.4);
* zenith: fully lit. Nothing lies above a height field and every triangle of the
  mesh faces +z, so V = 1; the map's horizon sines are < 1 = Lz, so F = 1 (the
  GPU path's zenith weights are ~1/255, see test_precision);
* V and the exact path's F never decrease as the light rises at a fixed
  azimuth (a ray at a higher elevation from the same point is above the lower
  one everywhere along the azimuth, and a triangle that faces a light at e
  faces it at every e' in [e, 90]; F = clamp(k (Lz - s) + 1) with s fixed);
* azimuths 360, 720 and -0 are azimuth 0 exactly;
* the exact path is continuous across channel directions and bin edges.
"""

import math

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

import hzval.bake as B
from hzval.techniques.horizon import Horizon

from ._ref import assert_unit, make_scene, truth

pytestmark = pytest.mark.hard

CHANNELS = tuple(45.0 * c for c in range(8))
BIN_EDGES = (11.25, 33.75, 348.75, -11.25, 191.25)  # 32 bins of 11.25 degrees
AZIMUTHS = CHANNELS + BIN_EDGES + (22.5, 360.0, 720.0, -0.0, -360.0)
GRAZING = (0.0, 0.5, 1.0, 2.0)
BELOW = (-90.0, -30.0, -0.5)
ELEVATIONS = BELOW + GRAZING + (30.0, 90.0)
N = 16


@pytest.fixture(scope="module")
def bumps(variant):
    """Smooth periodic bumps, 1.5 texels of relief, and their bake (wrap)."""
    rng = np.random.default_rng(21)
    h = gaussian_filter(rng.random((N, N)), 1.5, mode="wrap")
    h = ((h - h.min()) / (h.max() - h.min())).astype(np.float32)
    depth = 1.5 / N
    return h, depth, B.bake(h, B.BakeParams(depth=depth))


@pytest.fixture(scope="module")
def truth_frames(bumps):
    h, depth, _ = bumps
    out = {}
    for el in ELEVATIONS:
        t = truth(h, depth, "wrap", elevation=el, spp=4, effects=("shadow", "diffuse"))
        for az in AZIMUTHS:
            out[az, el] = t.render(az)
    return out


@pytest.fixture(scope="module")
def approx_frames(bumps):
    h, depth, baked = bumps
    sc = make_scene((N, N), depth, "wrap", effects=("shadow", "diffuse"), spp=4)
    out = {}
    for path in ("exact", "gpu"):
        a = Horizon(sc, baked, path=path)
        for el in ELEVATIONS:
            for az in AZIMUTHS:
                out[path, az, el] = a.render(az, elevation_deg=el)
    return out


def test_truth_is_finite_in_range_dark_below_and_lit_at_the_zenith(truth_frames):
    for (az, el), f in truth_frames.items():
        V = f.layers["visibility"]
        assert_unit(V, (az, el))
        assert np.isfinite(f.image).all() and (f.image >= 0).all()
        assert np.isfinite(f.variance["visibility"]).all()
        if el <= 0:
            assert np.all(V == 0.0) and np.all(f.image == 0.0), (az, el)
        if el == 90.0:
            assert np.all(V == 1.0), az
    # the grazing lights do shadow part of the map, and light part of it
    V = np.stack([truth_frames[az, 2.0].layers["visibility"] for az in CHANNELS])
    assert 0.05 < V.mean() < 0.95


def test_truth_never_darkens_as_the_light_rises(truth_frames):
    for az in AZIMUTHS:
        V = np.stack([truth_frames[az, el].layers["visibility"] for el in ELEVATIONS])
        assert np.all(np.diff(V, axis=0) >= 0), az


@pytest.mark.parametrize("same", [360.0, 720.0, -0.0, -360.0])
def test_truth_azimuth_0_360_and_minus_0_are_one_light(truth_frames, same):
    for el in GRAZING + (30.0,):
        assert np.array_equal(
            truth_frames[same, el].layers["visibility"], truth_frames[0.0, el].layers["visibility"]
        ), el


@pytest.mark.parametrize("path", ["exact", "gpu"])
def test_approximation_is_finite_in_range_dark_below_and_lit_at_the_zenith(approx_frames, bumps, path):
    assert bumps[2].horizon.max() < 0.9
    for az in AZIMUTHS:
        for el in ELEVATIONS:
            f = approx_frames[path, az, el]
            F = f.layers["factor"]
            assert_unit(F, (path, az, el))
            assert np.isfinite(f.image).all() and (f.image >= 0).all()
            if el <= 0:
                assert np.all(f.image == 0.0), (az, el)
            if el <= -30:
                assert np.all(F == 0.0), (az, el)  # Lz <= -1/k
            if el == 90.0:
                assert np.all(F == 1.0), az
            if path == "exact" and 0 < el:
                # s <= max h over the channels; F = 1 where Lz >= s
                s_max = bumps[2].horizon.max()
                if math.sin(math.radians(el)) >= s_max:
                    assert np.all(F == 1.0), (az, el)


def test_exact_factor_never_decreases_as_the_light_rises(approx_frames):
    for az in AZIMUTHS:
        F = np.stack([approx_frames["exact", az, el].layers["factor"] for el in ELEVATIONS])
        assert np.all(np.diff(F, axis=0) >= 0), az


@pytest.mark.parametrize("path", ["exact", "gpu"])
@pytest.mark.parametrize("same", [360.0, 720.0, -0.0, -360.0])
def test_approximation_azimuth_0_360_and_minus_0_are_one_light(approx_frames, path, same):
    for el in ELEVATIONS:
        a, b = approx_frames[path, same, el], approx_frames[path, 0.0, el]
        np.testing.assert_allclose(a.layers["factor"], b.layers["factor"], rtol=0, atol=1e-6)
        np.testing.assert_allclose(a.image, b.image, rtol=0, atol=1e-6)


def test_exact_path_is_continuous_across_channel_directions_and_bin_edges(bumps):
    """s(phi) is linear between channel directions with slope (h_c+1 - h_c) * 4 / pi per radian,
    so a step of 1e-3 degrees moves F by at most k * 1e-3 * pi/180 * 4/pi = 1.8e-4 (plus float32)."""
    h, depth, baked = bumps
    a = Horizon(make_scene((N, N), depth, "wrap", spp=1), baked)
    step = 1e-3
    bound = 8.0 * math.radians(step) * 4 / math.pi + 1e-5
    for az in CHANNELS + BIN_EDGES + (360.0,):
        for el in (1.0, 20.0):
            F = [a.render(az + d, elevation_deg=el).layers["factor"] for d in (-step, 0.0, step)]
            assert np.abs(F[1] - F[0]).max() <= bound and np.abs(F[2] - F[1]).max() <= bound, (az, el)
