"""Reflection occlusion on a model (issue 29, item 4): the truth's glossy lobe traced against the
displaced model, and the horizon map's Toolbag fade with the base mesh's interpolated vertex normal.

- The unit quad whose UVs are its (x, y) is the plane: its truth ``R`` is the plane truth's (the
  same rays and random streams: equal to float rounding, a few samples aside) and the horizon
  map's fade ``o`` is the plane's pixel for pixel, so ``reflection_mae`` is too.
- The same surface on a quad mirrored in u or with its UVs turned 90 degrees (the photo mirrored
  or turned back) gives the same ``R``, ``o`` and ``reflection_mae``.
- On a sphere the fade is Toolbag's ``saturate(1 + fade dot(r, n_vertex))^2`` with ``n_vertex``
  each sample's interpolated normal (the horizon map zeroed), sample for sample; with the tile's
  constant z in its place it would differ by far.
- ``hzval sweep --mesh sphere --effects shadow,diffuse,reflection_occlusion`` (its perspective view)
  writes a finite ``reflection_mae`` per frame; the memory estimate counts the lobe's rays.
"""

import dataclasses
import json
import math

import numpy as np
import pytest

from hzval.bake.maps import BakeParams, bake
from hzval.cli import main as cli
from hzval.core import budget, resources
from hzval.core import conventions as cv
from hzval.core.errors import InputError
from hzval.geometry import model
from hzval.scene import spec as sc
from hzval.techniques import registry as technique
from hzval.techniques.horizon import DEFAULT_FADE
from hzval.truth import plane as truth
from hzval.truth.model import ModelTruth

EFFECTS = "shadow,diffuse,reflection_occlusion"


def _scene(n=48, **kw):
    base = dict(
        size=n,
        depth=0.08,
        spp=4,
        azimuths="30",
        boundary="open",
        camera="orthographic",
        view_elevation=60,
        view_azimuth=-90,
        resolution=(n, n),
        effects=EFFECTS,
    )
    base.update(kw)
    return sc.override(sc.Scene(), **base)


def _context(scene, h, points, horizon_zero=False):
    b = bake(h, BakeParams(depth=scene.material.depth, boundary=scene.material.boundary))
    if horizon_zero:
        b = dataclasses.replace(b, horizon=np.zeros_like(b.horizon))
    rows, cols = h.shape
    return technique.Context(scene, h, b, sc.load_albedo(scene.material, rows, cols), points=points)


def _quad(uvs):
    p = np.array([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], float)
    return model.build("quad", p, np.array(uvs, float), np.array([(0, 1, 2), (0, 2, 3)]))


QUADS = {
    "xy": ([(0, 0), (1, 0), (1, 1), (0, 1)], lambda a: a),
    "mirrored-u": ([(1, 0), (0, 0), (0, 1), (1, 1)], lambda a: a[:, ::-1]),
    "turned-90": ([(1, 0), (1, 1), (0, 1), (0, 0)], np.rot90),
}


def _quad_run(scene, h, name):
    """``(seen, R, o)`` of the horizon map on the quad ``name`` carrying ``h``."""
    uvs, turn = QUADS[name]
    hq = np.ascontiguousarray(turn(h))
    mt = ModelTruth(scene, hq, _quad(uvs))
    tech = technique.get("horizon").build(_context(scene, hq, mt.samples()))
    az = scene.light.azimuths_deg[0]
    return (
        mt.seen,
        mt.render(az).layers["reflection_occlusion"],
        tech.render(az).layers["reflection_occlusion"],
    )


def test_the_xy_quads_reflection_is_the_planes(variant):
    scene = _scene()
    h = sc.load_material_height(scene.material).height
    seen, R, o = _quad_run(scene, h, "xy")
    plane = truth.Truth(scene, h)
    az = scene.light.azimuths_deg[0]
    p = plane.render(az)
    op = technique.get("horizon").build(_context(scene, h, None)).render(az).layers["reflection_occlusion"]
    Rp = p.layers["reflection_occlusion"]
    m = seen & (p.mask if p.mask is not None else True)
    assert m.mean() > 0.8
    assert 0.3 < Rp[m].mean() < 0.99  # the relief blocks part of the lobe
    assert np.abs(R - Rp)[m].mean() < 1e-4  # the same rays and streams
    assert abs(R[m].mean() - Rp[m].mean()) < 1e-4
    np.testing.assert_allclose(o[m], op[m], atol=1e-4)
    mae, mae_p = np.abs(o - R)[m].mean(), np.abs(op - Rp)[m].mean()
    assert mae > 0.01 and abs(mae - mae_p) <= 0.01 * mae_p


def test_mirrored_and_turned_quads_give_the_same_reflection(variant):
    scene = _scene()
    h = sc.load_material_height(scene.material).height
    runs = {name: _quad_run(scene, h, name) for name in QUADS}
    seen0, R0, o0 = runs["xy"]
    mae0 = np.abs(o0 - R0)[seen0].mean()
    for name, (seen, R, o) in runs.items():
        np.testing.assert_array_equal(seen, seen0)
        assert abs(R[seen].mean() - R0[seen].mean()) < 0.002, name
        assert np.abs(o - o0)[seen].mean() < 0.002, name
        mae = np.abs(o - R)[seen].mean()
        assert abs(mae - mae0) <= 0.005 * mae0 + 1e-4, name


def _sphere_fade(frames, xy, normal_map, spp, up):
    """Per pixel, Toolbag's fade with the horizon at 0: ``saturate(1 + fade dot(r, up))^2``, ``r`` the
    view reflected about the normal map carried into the world by each sample's frame, ``up`` each
    sample's vertex normal (``(N, 3)``) or one vector for all (NumPy, from the seed's formula)."""
    t, b, n, v = (frames[:, 3 * k : 3 * k + 3].astype(np.float64) for k in range(4))
    nt = cv.bilinear_at(normal_map, xy[:, 0], xy[:, 1], "wrap")
    nt /= np.linalg.norm(nt, axis=1, keepdims=True)
    ns = t * nt[:, :1] + b * nt[:, 1:2] + n * nt[:, 2:]
    r = 2.0 * np.sum(ns * v, axis=1, keepdims=True) * ns - v
    o = np.clip(1.0 + DEFAULT_FADE * np.sum(r * np.broadcast_to(up, r.shape), axis=1), 0.0, 1.0) ** 2
    return o.reshape(-1, spp).mean(axis=1)


def test_the_fade_uses_the_interpolated_vertex_normal(variant):
    """A sphere in perspective, the horizon map zeroed (``s_r = 0``: Toolbag's own term): the
    technique's ``o`` is the seed's formula with each sample's interpolated vertex normal, pixel for
    pixel, and far from the same formula with the tile's constant z."""
    scene = _scene(
        n=32,
        boundary="wrap",
        mesh="sphere",
        camera="perspective",
        view_elevation=35,
        view_azimuth=-30,
        resolution=(64, 64),
        spp=2,
    )
    h = sc.load_material_height(scene.material).height
    mt = ModelTruth(scene, h, model.load("sphere"))
    samples = mt.samples()
    ctx = _context(scene, h, samples, horizon_zero=True)
    o = technique.get("horizon").build(ctx).render(30.0).layers["reflection_occlusion"].ravel()
    xy = np.stack([samples.x, samples.y], -1).astype(np.float64)
    own = _sphere_fade(samples.frames, xy, ctx.bake.normal, scene.spp, samples.frames[:, 6:9])
    flat = _sphere_fade(samples.frames, xy, ctx.bake.normal, scene.spp, np.array([0.0, 0.0, 1.0]))
    seen = mt.seen.ravel()
    assert seen.mean() > 0.4
    assert np.abs(o - own)[seen].max() < 1e-4
    assert np.abs(o - flat)[seen].mean() > 0.1
    assert (np.abs(o - flat)[seen] > 0.2).mean() > 0.1


def test_a_sweep_on_the_sphere_scores_reflection_every_frame(tmp_path):
    out = tmp_path / "sphere"
    args = [
        "sweep",
        "--size",
        "32",
        "--spp",
        "2",
        "--azimuths",
        "-30,30,90",
        "--quiet",
        "--resolution",
        "64x64",
        "--mesh",
        "sphere",
        "--effects",
        EFFECTS,
        "--out",
        str(out),
    ]
    assert cli.main(args) == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["camera"]["kind"] == "perspective"
    assert "reflection_occlusion" in m["simulated"]["truth"]
    assert "reflection_occlusion" in m["simulated"]["horizon"]
    maes = [f["techniques"]["horizon"]["reflection_mae"] for f in m["frames"]]
    assert len(maes) == 3 and all(math.isfinite(x) and 0.0 < x < 1.0 for x in maes)
    assert all("reflection_mae" not in f["techniques"]["pom"] for f in m["frames"])
    assert "|o−R|" in (out / "index.html").read_text(encoding="utf-8")


def test_the_memory_estimate_counts_the_lobe(variant, monkeypatch):
    """The estimate before allocating counts the reflection's rays: a budget that holds the sphere
    without them refuses it with them, in one line naming the tolerance."""
    plain = _scene(
        n=32,
        boundary="wrap",
        mesh="sphere",
        camera="perspective",
        view_elevation=35,
        view_azimuth=-30,
        resolution=(64, 64),
        spp=2,
        effects="shadow,diffuse",
    )
    lobe = dataclasses.replace(plain, effects=tuple(EFFECTS.split(",")))
    assert budget.model_sample_bytes(lobe.declares("reflection_occlusion")) > budget.model_sample_bytes(
        plain.declares("reflection_occlusion")
    )
    h = sc.load_material_height(plain.material).height
    sphere = model.load("sphere")
    from hzval.geometry import displace

    triangles, mesh_bytes = displace.estimate(
        sphere,
        h.shape,
        "wrap",
        height=h,
        depth=plain.material.depth,
        tolerance=plain.material.truth_tolerance,
    )
    base = mesh_bytes + budget.MODEL_BYTES_PER_TRIANGLE * triangles
    pixels = 64 * 64 * plain.spp
    monkeypatch.setattr(
        resources,
        "available_bytes",
        lambda: base + budget.model_sample_bytes(plain.declares("reflection_occlusion")) * pixels + 1,
    )
    ModelTruth(plain, h, sphere)
    with pytest.raises(InputError, match="truth-tolerance"):
        ModelTruth(lobe, h, sphere)


def test_specular_in_perspective_on_a_model_is_each_samples_own_view(variant):
    """The per-sample view that the fade reads also serves ``specular`` in perspective on a model:
    where the truth sees the light, its Blinn-Phong shading is the techniques' at its own hits."""
    from hzval.techniques import surface

    scene = _scene(
        n=32,
        boundary="wrap",
        mesh="sphere",
        camera="perspective",
        view_elevation=35,
        view_azimuth=-30,
        resolution=(64, 64),
        spp=2,
        effects="shadow,diffuse,specular",
    )
    h = sc.load_material_height(scene.material).height
    mt = ModelTruth(scene, h, model.load("sphere"))
    plain = surface.unshadowed(_context(scene, h, mt.samples("truth")))
    t = mt.render(30.0)
    lit = mt.seen & (t.layers["visibility"] == 1.0)
    assert lit.mean() > 0.2
    img = plain.render(30.0)[0].image
    assert np.abs(t.image - img)[lit].max() < 1e-4
    assert img[lit].max() > 1.2 * np.percentile(img[lit], 50)  # a highlight, not diffuse alone


def test_the_plane_still_refuses_a_perspective_reflection():
    with pytest.raises(InputError, match="perspective camera"):
        _scene(camera="perspective", view_elevation=35, view_azimuth=-30).validate()
    _scene(mesh="sphere", camera="perspective", view_elevation=35, view_azimuth=-30).validate()


def test_a_smooth_sphere_blocks_nothing_of_the_lobe_that_faces_the_camera(variant):
    """A flat map on a sphere: a convex surface with no relief, so the lobe (exponent 64, about 10
    degrees wide) is blocked only where it dips below the base surface's horizon, near the
    silhouette: ``R = 1`` where the vertex normal faces the camera within 25 degrees (the
    lobe would need a half vector 32 degrees off the normal, a share of 2e-5, to reach the
    horizon), below 1 where it grazes. "1" to float32 rounding: exactly 1 on the LLVM backend, a few
    ulp below it on CUDA, whose single-precision division and square root are approximate."""
    scene = _scene(
        n=32,
        boundary="wrap",
        mesh="sphere",
        camera="perspective",
        view_elevation=35,
        view_azimuth=-30,
        resolution=(64, 64),
        spp=4,
        effects="shadow,reflection_occlusion",
    )
    mt = ModelTruth(scene, np.zeros((32, 32), np.float32), model.load("sphere"))
    R = mt.render(30.0).layers["reflection_occlusion"].ravel()
    f = mt.samples("truth").frames
    nv = np.sum(f[:, 6:9] * f[:, 9:12], axis=1).reshape(-1, scene.spp).min(axis=1)
    facing, grazing = mt.seen.ravel() & (nv > 0.9), mt.seen.ravel() & (nv < 0.3)
    assert facing.sum() > 300 and grazing.sum() > 20
    assert R[facing].min() >= (1.0 - 1e-6 if variant.startswith("cuda") else 1.0)
    assert R[grazing].min() < 0.95  # the lobe's lower edge goes below the horizon there
