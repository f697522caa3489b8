"""The truth isolates the technique: what differs between the truth and a technique is shadows, not shading.

Smooth shading (vertex normals from the normal map's own differences) makes
the lit truth equal the techniques' unshadowed shading; a soft light is
normalised so that a plane receives E, as the technique assumes; the
exposure never clips; the reflection fraction carries its estimator's
weights (checked on a tilted plane against an independent quadrature); an
open tile's border is shaded alike; and each frame's perfect-shadows floor
measures what of an image score is not the shadows'.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from hzval.bake import maps as bake
from hzval.cli import main as cli
from hzval.core import shading
from hzval.scene import spec as sc
from hzval.techniques import horizon, surface
from hzval.truth import plane as truth
from tests.helpers import make_scene


def rough(n=48, sigma=1.2, seed=5):
    from scipy.ndimage import gaussian_filter

    h = gaussian_filter(np.random.default_rng(seed).random((n, n)), sigma, mode="wrap")
    return ((h - h.min()) / (h.max() - h.min())).astype(np.float32)


def lit_difference(h, depth, shading_, azimuth, boundary="wrap"):
    """Mean exposed |truth - unshadowed shading| over the pixels the truth sees fully lit."""
    scn = make_scene(
        h.shape, depth, boundary, effects=("shadow", "diffuse"), spp=16, shading=shading_, elevation=40.0
    )
    fr = truth.Truth(scn, h).render(azimuth)
    plain, _ = surface.Unshadowed(scn, bake.bake(h, bake.BakeParams(depth=depth, boundary=boundary))).render(
        azimuth
    )
    lit = fr.layers["visibility"] == 1.0
    assert lit.mean() > 0.3
    return float((np.abs(fr.image - plain.image).mean(-1)[lit]).mean() * shading.exposure(scn))


@pytest.mark.parametrize("azimuth", [0.0, 135.0])
def test_smooth_shading_makes_the_lit_truth_the_techniques_shading(variant, azimuth):
    """On rough ground (about 4 texels of relief over 1-2 texel bumps) the faceted truth differs from
    the normal-mapped shading where both are lit by 0.013-0.014 of white; the smooth truth, whose
    shading normal is the vertex normals' bilinear interpolation, agrees to float rounding (2e-8)."""
    h = rough()
    smooth = lit_difference(h, 4 / 48, "smooth", azimuth)
    faceted = lit_difference(h, 4 / 48, "faceted", azimuth)
    assert smooth < 1e-5
    assert faceted > 0.006


def test_open_border_is_shaded_as_the_normal_map_shades_it(variant):
    """A bowl on an open tile: the mesh's flat half-texel skirt takes the border texels' one-sided
    normals, so smooth shading there is the normal map's; faceted, the skirt is flat."""
    r, c = np.mgrid[0:20, 0:24].astype(np.float64)
    h = (((r - 9.5) / 10) ** 2 + ((c - 11.5) / 12) ** 2).astype(np.float32)
    out = {}
    for shade in ("smooth", "faceted"):
        scn = make_scene(h.shape, 0.2, "open", effects=("diffuse",), spp=16, elevation=40.0, shading=shade)
        T = truth.Truth(scn, h).render(180.0).image[..., 0]
        A = (
            horizon.Horizon(scn, bake.bake(h, bake.BakeParams(depth=0.2, boundary="open")))
            .render(180.0)
            .image[..., 0]
        )
        border = np.zeros(h.shape, bool)
        border[:, [0, -1]] = border[[0, -1], :] = True
        out[shade] = np.abs(T - A)[border].mean() * shading.exposure(scn)
    assert out["smooth"] < 0.004 and out["faceted"] > 3 * out["smooth"], out


def test_a_soft_light_gives_a_plane_facing_it_its_irradiance(variant):
    """A 20-degree disk light on a flat plane: each sampled direction carries 2 E / (1 + cos rho),
    so the plane shows albedo / pi * E * sin(e), as the technique computes from the disk's centre."""
    h = np.full((16, 16), 0.5, np.float32)
    for elevation in (40.0, 90.0):
        scn = make_scene(
            h.shape,
            0.1,
            "wrap",
            effects=("diffuse",),
            kind="soft",
            radius=20.0,
            elevation=elevation,
            spp=64,
            albedo=0.7,
            irradiance=2.0,
        )
        t = truth.Truth(scn, h).render(30.0).image
        a = horizon.Horizon(scn, bake.bake(h, bake.BakeParams(depth=0.1))).render(30.0).image
        expect = 0.7 / math.pi * 2.0 * math.sin(math.radians(elevation))
        assert a.mean() == pytest.approx(expect, rel=1e-5)
        assert t.mean() == pytest.approx(expect, rel=0.003)
    assert shading.disk_sample_irradiance(1.0, 20.0) == pytest.approx(2 / (1 + math.cos(math.radians(20))))


@pytest.mark.parametrize(
    "effects",
    [("shadow", "diffuse", "ambient"), ("shadow", "ambient"), ("shadow", "diffuse", "specular", "ambient")],
)
def test_the_exposure_never_clips_what_the_declared_effects_can_produce(variant, effects):
    """The exposure maps the largest radiance of the declared effects to 1: no truth pixel of an
    ambient scene reaches the clip, yet the brightest are within a factor 2 of it."""
    from hzval.materials.bricks import bricks

    h = bricks(64)
    scn = sc.override(sc.Scene(), size=64, effects=",".join(effects), spp=4, elevation=60.0)
    shown = truth.Truth(scn, h).render(0.0).image * shading.exposure(scn)
    assert (shown >= 1.0).mean() < 0.01 and shown.max() <= 1.0 + 1e-5
    assert shown.max() > 0.5
    E = scn.light.irradiance
    diffuse = "diffuse" in effects
    expect = (E / math.pi if diffuse else E) + 0.04 * E * ("specular" in effects) + E / math.pi
    assert shading.max_radiance(scn) == pytest.approx(expect)


def _tilted_reflection_reference(tilt_deg: float, n: int = 2_000_000, seed: int = 7) -> tuple[float, float]:
    """The escaping share of the Blinn-Phong lobe of a plane tilted by ``tilt`` about y, seen from +z,
    by an independent quadrature: half vectors from pdf(h) = (alpha + 1) / (2 pi) cos^alpha,
    weighted by f cos / pdf ~ wo.h; a direction below the horizontal is blocked (the tilted plane
    itself never blocks a direction above it). Returns (weighted, unweighted)."""
    from hzval.core.shading import SPECULAR_EXPONENT

    rng = np.random.default_rng(seed)
    b = math.radians(tilt_deg)
    nrm = np.array([math.sin(b), 0.0, math.cos(b)])
    t1 = np.array([math.cos(b), 0.0, -math.sin(b)])
    t2 = np.array([0.0, 1.0, 0.0])
    cos_h = rng.random(n) ** (1.0 / (SPECULAR_EXPONENT + 1))
    sin_h, phi = np.sqrt(1 - cos_h**2), 2 * math.pi * rng.random(n)
    hv = (sin_h * np.cos(phi))[:, None] * t1 + (sin_h * np.sin(phi))[:, None] * t2 + cos_h[:, None] * nrm
    v = np.array([0.0, 0.0, 1.0])
    wo = 2 * (hv @ v)[:, None] * hv - v
    above = wo @ nrm > 0
    w = np.where(above, hv @ v, 0.0)
    escapes = above & (wo[:, 2] > 0)
    return float(np.sum(w * escapes) / np.sum(w)), float(np.mean(escapes))


@pytest.mark.parametrize("tilt", [35.0, 40.0])
def test_reflection_fraction_on_a_tilted_plane_carries_the_estimators_weight(variant, tilt):
    """A plane tilted by 35 or 40 degrees reflects the view ray 70-80 degrees from the zenith, and part
    of its lobe dips below the horizontal. The truth's R matches the weighted quadrature to 0.006
    (0.925 and 0.773); the unweighted share the truth computed before (0.909 and 0.737) is 0.016
    and 0.036 off."""
    n = 24
    x = np.tile(np.arange(n, dtype=np.float32), (n, 1))
    depth = math.tan(math.radians(tilt)) * (n - 1) / n  # H * depth * cols rises tan(tilt) a texel
    h = x / (n - 1)
    scn = make_scene(h.shape, depth, "open", effects=("reflection_occlusion",), spp=256, shading="faceted")
    R = truth.Truth(scn, h).render(0.0).layers["reflection_occlusion"][2:-2, 2:-2]
    # the ramp rises toward +x, so its normal leans toward -x: mirror the reference's tilt
    weighted, unweighted = _tilted_reflection_reference(tilt)
    assert abs(weighted - unweighted) > 0.008
    assert float(R.mean()) == pytest.approx(weighted, abs=0.006)


def test_every_frame_records_its_perfect_shadows_floor(variant, tmp_path, any_map):
    """frames[i].floor: the unshadowed shading times the truth's V, scored against the truth. On a
    flat map it is exactly 0; on the bricks it is below every technique's score at azimuth 0, where
    the horizon map's false shadows dominate, and the report shows it beside the scores."""
    np.save(tmp_path / "flat.npy", np.full((16, 16), 0.5, np.float32))
    out = tmp_path / "flat"
    assert (
        cli.main(
            [
                "sweep",
                str(tmp_path / "flat.npy"),
                "--azimuths",
                "0",
                "--spp",
                "2",
                "--quiet",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    f = json.loads((out / "metrics.json").read_text())["frames"][0]
    assert f["floor"]["rmse"] == pytest.approx(0, abs=1e-6) and f["floor"]["flip_mean"] == pytest.approx(
        0, abs=1e-6
    )
    out = tmp_path / "bricks"
    assert (
        cli.main(["sweep", "--size", "64", "--azimuths", "0,45", "--spp", "4", "--quiet", "--out", str(out)])
        == 0
    )
    m = json.loads((out / "metrics.json").read_text())
    assert m["exposure"]["scale"] == pytest.approx(math.pi)
    f0 = m["frames"][0]
    assert set(f0["floor"]) == {"flip_mean", "rmse", "psnr_db", "delta_e2000_mean"}
    h0 = f0["techniques"]["horizon"]
    assert f0["floor"]["flip_mean"] < h0["flip_mean"] and f0["floor"]["rmse"] < h0["rmse"]
    html = (out / "index.html").read_text(encoding="utf-8")
    assert "floor FLIP" in html and "shading &amp; noise" in html
