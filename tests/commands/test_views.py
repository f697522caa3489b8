"""Views other than straight down: the camera's rays, the truth along them, the techniques' lookups.

Known answers: a plane seen obliquely is fully lit and read at the exact
point; a wall's shadow seen from 45 degrees lands where geometry puts it;
trilinear filtering picks the level a plane at a known distance calls for;
the camera record rebuilds the rays; and an independent march of the
recorded rays (tests/oracles/march_check.py) agrees with the truth's V.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from hzval.bake import maps as bake
from hzval.core.errors import InputError
from hzval.io import codecs
from hzval.scene import camera as hz_camera
from hzval.scene import files as scene_files
from hzval.scene import lookup
from hzval.scene import spec as sc
from hzval.techniques import registry as technique
from hzval.truth import plane as truth

ROOT = Path(__file__).resolve().parents[2]


def _record_rays(rec: dict, rows_px: int, cols_px: int):
    """The rays of every pixel centre rebuilt from a camera record by the documented mapping alone."""
    eye, target, up = (np.array(rec[k], float) for k in ("eye", "target", "up"))
    f = (target - eye) / np.linalg.norm(target - eye)
    r = np.cross(f, up)
    r /= np.linalg.norm(r)
    t = np.cross(r, f)
    row, col = np.divmod(np.arange(rows_px * cols_px), cols_px)
    u = (2 * (col + 0.5) / cols_px - 1)[:, None]
    v = (1 - 2 * (row + 0.5) / rows_px)[:, None]
    if rec["kind"] == "perspective":
        tan = math.tan(math.radians(rec["fov_deg"]) / 2)
        d = f + u * tan * r + v * tan * (rows_px / cols_px) * t
        return np.broadcast_to(eye, d.shape), d / np.linalg.norm(d, axis=1, keepdims=True)
    w, h = rec["film_size"]
    o = eye + u * (w / 2) * r + v * (h / 2) * t
    return o, np.broadcast_to(f, o.shape)


@pytest.mark.parametrize(
    "cam",
    [
        hz_camera.Camera(kind="orthographic", elevation_deg=30, azimuth_deg=20),
        hz_camera.Camera(kind="perspective", elevation_deg=35, fov_deg=50, resolution=(40, 30)),
        hz_camera.Camera(),
    ],
)
def test_the_record_rebuilds_the_rays(cam):
    view = cam.view(24, 32, (1.0, 5.0))
    rec = json.loads(json.dumps(view.record()))
    W, H = rec["resolution"]
    half = np.full((H * W, 1), 0.5)
    o, d = view.rays_at(*view.film_coordinates(np.arange(H * W), half, half))
    o2, d2 = _record_rays(rec, H, W)
    # rays are lines: compare directions, and the origins' offset across the rays
    np.testing.assert_allclose(d, d2, atol=1e-9)
    off = o - o2
    np.testing.assert_allclose(off - np.sum(off * d, axis=1, keepdims=True) * d, 0, atol=1e-7)


def test_the_top_record_is_the_top_views_positions():
    cam = hz_camera.Camera(supersampling=2)
    view = cam.view(8, 12)
    assert view.record()["resolution"] == [24, 16]
    o, d = _record_rays(view.record(), 16, 24)
    x, y = hz_camera.sample_positions(8, 12, cam, 1, 0)  # one jittered sample a pixel
    assert np.all(np.abs(o[:, 0] - x) <= 0.25 + 1e-6) and np.all(np.abs(o[:, 1] - y) <= 0.25 + 1e-6)
    np.testing.assert_allclose(d, [[0, 0, -1]] * len(d))


def _flat_scene(cam, **kw):
    return dataclasses.replace(
        sc.Scene(material=sc.MaterialSpec(depth=0.05, boundary="wrap")), camera=cam, spp=4, **kw
    ).validate()


def test_a_plane_seen_obliquely_is_fully_lit_and_read_at_the_exact_point():
    h = np.full((32, 32), 0.5, np.float32)
    z0 = 0.5 * 0.05 * 32
    for cam in (
        hz_camera.Camera(kind="orthographic", elevation_deg=25, azimuth_deg=-70),
        hz_camera.Camera(kind="perspective", elevation_deg=35),
    ):
        scene = _flat_scene(cam)
        T = truth.Truth(scene, h)
        frame = T.render(15.0)
        assert frame.mask.all()
        np.testing.assert_array_equal(frame.layers["visibility"], 1.0)
        # the truth's hits are where the rays meet the plane z0, wrapped into the tile
        o, d = T.view.rays(scene.spp, scene.seed, 0, 32 * 32)
        xy, hit = T.view.plane_points(o, d, z0)
        assert hit.all()
        ex, ey = xy[:, 0] % 32, xy[:, 1] % 32
        dx = (T.hits[0] - ex + 16) % 32 - 16
        dy = (T.hits[1] - ey + 16) % 32 - 16
        assert np.max(np.hypot(dx, dy)) < 2e-3
        # the techniques' plane is the surface: they read it at the truth's own points
        b = bake.bake(h, bake.BakeParams(depth=0.05, boundary="wrap"))
        ctx = technique.Context(scene, h, b, sc.load_albedo(scene.material, 32, 32))
        s = ctx.samples()
        assert np.max(np.abs((s.x - T.hits[0] + 16) % 32 - 16)) < 2e-3
        for name in technique.defaults():
            F = technique.get(name).build(ctx).render(15.0).layers["factor"]
            np.testing.assert_allclose(F, 1.0, atol=1e-6)


def test_a_walls_shadow_seen_from_45_degrees_lands_where_geometry_puts_it():
    """scenes/wall.png: a ridge of texel centres at x = 40.5, 8 texels high, on flat ground; the
    light from +x at 30 degrees throws its shadow to x = 40.5 - 8 / tan(30) = 26.64."""
    base = scene_files.load_scene(ROOT / "scenes" / "wall.toml")
    scene = dataclasses.replace(
        base, camera=hz_camera.Camera(kind="orthographic", elevation_deg=45, azimuth_deg=-120), spp=4
    ).validate()
    h = sc.load_material_height(scene.material).height
    T = truth.Truth(scene, h)
    T.render(0.0)
    seen = T.seen_samples
    x, y = T.hits
    (kept,) = T._kept
    o, n, ns, valid = kept.o, kept.n, kept.ns, None
    z = np.asarray(o.z) - T.lift
    L = T.light_directions(0.0)[0]
    V = np.asarray(T._visible(kept.o, kept.n, L, math.radians(30), math.radians(30)))
    ground = seen & (z < 1e-3) & (y > 8) & (y < 56)
    edge = 40.5 - 8 / math.tan(math.radians(30))
    shadow = ground & (x > edge + 0.75) & (x < 39.4)
    lit = ground & (x < edge - 0.75)
    assert shadow.sum() > 100 and lit.sum() > 100
    assert V[shadow].max() == 0.0
    assert V[lit].min() == 1.0
    del ns, valid, n


def test_trilinear_picks_the_level_a_plane_at_a_known_distance_calls_for(variant):
    """A camera straight down, 2 tile widths (128 texels) above a 64-texel tile, 90 degrees across 64
    pixels: a pixel at the centre covers 2 * 128 * tan(45) / 64 = 4 texels, level log2(4) = 2."""
    cam = hz_camera.Camera(
        kind="perspective", elevation_deg=90, fov_deg=90, distance=2.0, resolution=(64, 64)
    )
    view = cam.view(64, 64, (0.0, 0.0))
    fp = view.footprints(0.0).reshape(64, 64, 4)
    centre = fp[31:33, 31:33].reshape(-1, 4)
    np.testing.assert_allclose(np.hypot(centre[:, 0], centre[:, 1]), 4.0, rtol=2e-3)
    rng = np.random.default_rng(3)
    data = rng.random((64, 64, 2)).astype(np.float32)
    exact = np.full((64 * 64, 4), 0.0, np.float32)
    exact[:, 0], exact[:, 3] = 4.0, -4.0  # 4 texels a pixel, both axes
    samples = lookup.Samples(np.zeros(1, np.float32), np.zeros(1, np.float32), 64, 64, 1, exact)
    tex = lookup.Filtered(data, "wrap", lookup.Lookup(filter="trilinear"), samples)
    level2 = lookup.mip_chain(data)[2]  # 16 x 16
    import drjit as dr
    import mitsuba as mi

    r, c = np.divmod(np.arange(16 * 16), 16)
    uv = mi.Point2f(
        mi.Float(((c + 0.5) / 16).astype(np.float32)), mi.Float(((r + 0.5) / 16).astype(np.float32))
    )
    vals = tex.eval(uv, dr.zeros(mi.UInt32, 16 * 16))
    got = np.stack([np.asarray(v) for v in vals], axis=-1)
    np.testing.assert_allclose(got, level2.reshape(-1, 2), atol=1e-6)
    # the max chain of the horizon channels is never below the average
    avg, mx = lookup.mip_chain(data), lookup.mip_chain(data, slice(0, 1))
    assert all(
        np.all(m[..., 0] >= a[..., 0] - 1e-7) and np.array_equal(m[..., 1], a[..., 1])
        for a, m in zip(avg, mx)
    )


def _march_check():
    from tests.oracles import march_check

    return march_check


@pytest.mark.parametrize(
    "camera_kind,boundary,parallax", [("orthographic", "wrap", "occlusion"), ("perspective", "open", "none")]
)
def test_an_independent_march_of_the_recorded_rays_agrees_with_the_truth(
    tmp_path, camera_kind, boundary, parallax
):
    from hzval.pipeline import sweep

    cam = hz_camera.Camera(kind=camera_kind, elevation_deg=45 if camera_kind == "orthographic" else 35)
    scene = sc.override(
        sc.Scene(), height="gravel", size=64, boundary=boundary, azimuths="-45,30", spp=4, parallax=parallax
    )
    scene = dataclasses.replace(scene, camera=cam).validate()
    result = sweep.run(scene, tmp_path / "s", progress=False)
    assert result["camera"]["kind"] == camera_kind
    report = _march_check().check(tmp_path / "s", spp=4)
    assert report["mean_abs_diff"] < 0.035
    # what no ray sees is NaN in V's file and left out of the metrics
    V = codecs.read_exr(tmp_path / "s" / result["frames"][0]["files"]["visibility"])
    V = next(iter(V.values())) if isinstance(V, dict) else V
    seen = np.isfinite(V)
    assert seen.mean() == pytest.approx(result["view"]["seen_fraction"], abs=1e-9)
    if boundary == "open":
        assert 0.2 < seen.mean() < 0.95
    view = result["view"]
    assert view["parallax_error_texels"]["mean"] >= 0
    if parallax == "occlusion":
        assert view["parallax_error_texels"]["mean"] < 0.1
    h = result["frames"][0]["techniques"]["horizon"]
    assert 0 <= h["perfect_parallax_mae"] <= 1


def test_parallax_mapping_brings_the_lookup_toward_the_truths_point():
    h = sc.load_material_height(sc.MaterialSpec(height="bricks", size=64)).height
    errors = {}
    for p in ("none", "offset", "occlusion"):
        scene = _flat_scene(
            hz_camera.Camera(kind="orthographic", elevation_deg=40), lookup=lookup.Lookup(parallax=p)
        )
        T = truth.Truth(scene, h)
        s = lookup.samples_for(scene, 64, 64, h)
        d = np.hypot((s.x - T.hits[0] + 32) % 64 - 32, (s.y - T.hits[1] + 32) % 64 - 32)
        errors[p] = float(d.mean())
    assert errors["occlusion"] < 0.1 * errors["none"]
    assert errors["offset"] < errors["none"]


def test_view_settings_are_checked():
    with pytest.raises(InputError, match="elevation"):
        hz_camera.Camera(kind="orthographic", elevation_deg=0).validate("x")
    with pytest.raises(InputError, match="--view-elevation"):
        sc.override(sc.Scene(), view_elevation=30.0)
    with pytest.raises(InputError, match="perspective"):
        dataclasses.replace(
            sc.Scene(effects=("shadow", "specular")), camera=hz_camera.Camera(kind="perspective")
        ).validate()
    with pytest.raises(InputError, match="lookup.filter"):
        lookup.Lookup(filter="cubic").validate("x")


def test_a_scene_file_places_the_camera(tmp_path):
    p = tmp_path / "s.toml"
    p.write_text(
        '[camera]\nkind = "perspective"\nelevation_deg = 35\nresolution = [40, 30]\n'
        '[lookup]\nfilter = "anisotropic"\nparallax = "offset"\n'
    )
    s = scene_files.load_scene(p)
    assert s.camera.kind == "perspective" and s.camera.resolution == (40, 30)
    assert s.camera.image_shape(64, 64) == (30, 40)
    assert s.lookup.filter == "anisotropic" and s.lookup.parallax == "offset"


def test_hzval_views_sweeps_each_view_and_plots_the_errors(tmp_path):
    from hzval.commands import views

    scene = sc.override(sc.Scene(), height="gravel", size=32, azimuths="0", spp=1)
    data = views.run(
        scene, tmp_path / "v", views=["top", "ortho-45"], lookups=["bilinear", "parallax"], progress=False
    )
    got = [(r["view"], r["lookup"]) for r in data["rows"]]
    assert got == [("top", "bilinear"), ("ortho-45", "bilinear"), ("ortho-45", "parallax")]
    oblique = {r["lookup"]: r for r in data["rows"] if r["view"] == "ortho-45"}
    assert (
        oblique["parallax"]["parallax_error_texels"]["mean"]
        < oblique["bilinear"]["parallax_error_texels"]["mean"]
    )
    assert oblique["bilinear"]["footprint_texels"]["p50"] == pytest.approx(math.sqrt(2), rel=1e-3)
    for name in ("views.json", "index.html", "plots/views.png", "ortho-45/parallax/index.html"):
        assert (tmp_path / "v" / name).is_file(), name
    assert "ortho-45" in (tmp_path / "v" / "index.html").read_text()
    with pytest.raises(InputError, match="--views"):
        views.run(scene, tmp_path / "w", views=["sideways"], progress=False)
