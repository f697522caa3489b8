"""The fitted horizon map (hzval.techniques.fitted.fit, hzval.techniques.fitted.horizon_fit, ``hzval fit``).

The forward model is the horizon technique's own kernel, bit for bit; its
gradient is the finite difference's; a flat surface (V = 1, s = 0) has
nothing to fit; a fit lowers the training error, keeps the sines in [0, 1]
and, stored in 8 bits, beats the 8-bit baked map; its files are the bake's
layout, which ``--horizon-map`` reads back as they were written; the
technique is opt-in, cached by digest, and splits a frame's error.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from hzval.bake import maps as bake
from hzval.cli import main as cli
from hzval.core import conventions as cv
from hzval.core import resources
from hzval.core.errors import InputError
from hzval.io import external
from hzval.pipeline import sweep
from hzval.scene import lookup
from hzval.scene import spec as sc
from hzval.techniques import horizon
from hzval.techniques import registry as technique
from hzval.techniques.fitted import fit, horizon_fit
from hzval.techniques.fitted import store as fitted_store
from hzval.techniques.fitted import training as fitted_training

FEW = "20,40@0:270:90"  # 8 training lights: fast fits for the tests
HELD = "30@45:225:180"


def _setup(n=24, spp=1, depth=0.1, height=None):
    from hzval.materials.bricks import bricks

    scene = sc.override(sc.Scene(), size=n, depth=depth, spp=spp, effects="shadow")
    h = bricks(n) if height is None else height
    return scene, h, bake.bake(h, bake.BakeParams(depth=depth).validate())


def test_parse_lights():
    lights = fitted_training.parse_lights(fitted_training.TRAINING_LIGHTS)
    assert len(lights) == 96 and {e for e, _ in lights} == {10.0, 20.0, 40.0, 60.0}
    assert all(e != 30.0 for e, _ in lights)  # none is a light of the default sweep
    held = fitted_training.parse_lights(fitted_training.HELD_OUT_LIGHTS)
    assert [a for _, a in held] == [-52.5 + 15 * i for i in range(8)] and {e for e, _ in held} == {25.0}
    assert fitted_training.parse_lights("10@0;20@0,90") == ((10.0, 0.0), (20.0, 0.0), (20.0, 90.0))
    for bad in ("", "10", "95@0", "x@0", "10@5:0:1"):
        with pytest.raises(InputError):
            fitted_training.parse_lights(bad)


@pytest.mark.parametrize("spp", [1, 3])
def test_forward_model_is_the_techniques_own_bit_for_bit(variant, spp):
    """The fit's F (straight-through clamp, parameters with gradients on) has the render's bits."""
    import drjit as dr
    import mitsuba as mi

    scene, h, b = _setup(spp=spp)
    lights = ((20.0, 10.0), (35.0, 200.0), (60.0, -75.0))
    model = fit._Model(scene, b, 8.0, "float", [])
    p = mi.TensorXf(lookup.aligned(b.horizon))
    dr.enable_grad(p)
    model.set_parameters(p)
    F = np.asarray(dr.detach(model.factor(lights, 0, model.P))).reshape(len(lights), *h.shape)
    ref = horizon.Horizon(fitted_training.fit_scene(scene), b, None)
    for i, (e, az) in enumerate(lights):
        want = ref.render(az, elevation_deg=e).layers["factor"]
        if spp == 1:
            assert np.array_equal(F[i], want)
        else:  # a pixel's mean: block_sum against the render's loop, the same sum in another order
            np.testing.assert_allclose(F[i], want, rtol=0, atol=2e-7)


@pytest.mark.parametrize("path", ["exact", "gpu"])
def test_shadow_factor_is_the_kernels_former_arithmetic(variant, path):
    """horizon.shadow_factor, which the shading kernel now calls, gives the render the bits of the
    expression it replaced: clip(fma(Lz - dot(h, w), k, 1), 0, 1)."""
    import drjit as dr
    import mitsuba as mi

    scene, h, b = _setup(n=16)
    ap = horizon.Horizon(fitted_training.fit_scene(scene), b, None, path=path)
    y, x = np.mgrid[0:16, 0:16]
    xs, ys = (x + 0.3).ravel().astype(np.float32), (16 - y - 0.6).ravel().astype(np.float32)
    u, v = (mi.Float(c) for c in cv.tangent_to_uv(xs, ys, 16, 16))
    for e, az in ((25.0, -52.5), (45.0, 100.0)):
        uni = ap._uniforms(az, e, True, {})
        s = horizon._dot(ap._fetch(u, v)["horizon"], uni["w"])
        former = dr.clip(dr.fma(uni["L"].z - s, uni["k"], 1.0), 0.0, 1.0)
        now = ap.sample(xs, ys, az, e)["factor"]
        assert np.array_equal(np.asarray(former), now)


def test_straight_through_factor_keeps_the_values(variant):
    import drjit as dr
    import mitsuba as mi

    h = [mi.Float([0.1, 0.9, 0.5]) for _ in range(8)]
    w = [mi.Float(0.25) if c in (1, 2) else mi.Float(0.0) for c in range(8)]
    plain, s0 = horizon.shadow_factor(h, w, mi.Float(0.3), mi.Float(8.0))
    st, s1 = horizon.shadow_factor(h, w, mi.Float(0.3), mi.Float(8.0), straight_through=True)
    assert np.array_equal(np.asarray(plain), np.asarray(st)) and np.array_equal(
        np.asarray(s0), np.asarray(s1)
    )
    # the gradient passes a saturated clamp (s = 0.45: F = 0 below, 8 (0.3 - 0.45) + 1 = -0.2)
    x = mi.Float(0.9)
    dr.enable_grad(x)
    F, _ = horizon.shadow_factor(
        [x] + [mi.Float(0.0)] * 7,
        [mi.Float(0.5)] + [mi.Float(0.0)] * 7,
        mi.Float(0.3),
        mi.Float(8.0),
        straight_through=True,
    )
    dr.backward(F)
    assert float(np.asarray(F)[0]) == 0.0 and float(np.asarray(dr.grad(x))[0]) == pytest.approx(-4.0)


def test_gradient_matches_finite_differences(variant):
    """d loss / d h at a texel whose F is not saturated: the AD gradient against a central difference."""
    import drjit as dr
    import mitsuba as mi

    cols = np.arange(24)
    ridges = np.tile(0.5 + 0.5 * np.sin(2 * np.pi * cols / 12), (24, 1)).astype(np.float32)
    scene, h, b = _setup(spp=1, height=ridges, depth=0.1)
    lights = ((5.0, 30.0),)
    V = [np.full(h.shape, 0.5, np.float32)]
    model = fit._Model(scene, b, 1.0, "float", V)  # k = 1 and a low light: few saturated pixels
    base = b.horizon.astype(np.float64)

    def loss_of(hz):
        p = mi.TensorXf(lookup.aligned(hz))
        dr.enable_grad(p)
        model.set_parameters(p)
        value = model.backward([0], lights, 1.0)
        return value, np.asarray(dr.grad(p)).reshape(hz.shape)

    _, grad = loss_of(base.astype(np.float32))
    F = np.asarray(dr.detach(model.factor(lights, 0, model.P))).reshape(h.shape)
    inner = (F > 0.05) & (F < 0.95)
    ok = inner & np.roll(inner, 1, 0) & np.roll(inner, -1, 0) & np.roll(inner, 1, 1) & np.roll(inner, -1, 1)
    r, c = (int(i[0]) for i in np.nonzero(ok))
    ch = 0  # channels 0 and 1 carry this light's weights (30 deg)
    eps = 1e-3
    up, _ = loss_of(_bump(base, r, c, ch, eps))
    down, _ = loss_of(_bump(base, r, c, ch, -eps))
    assert grad[r, c, ch] != 0.0
    assert grad[r, c, ch] == pytest.approx((up - down) / (2 * eps), rel=0.05)
    assert np.all(grad[..., 3:7] == 0.0)  # channels 90..270 deg carry no weight toward 30 deg


def _bump(hz, r, c, ch, eps):
    out = hz.copy()
    out[r, c, ch] += eps
    return out.astype(np.float32)


def test_flat_surface_has_nothing_to_fit(variant):
    """No relief: V = 1 for every light above the horizon, the baked sines are 0 and F = 1: the loss is
    0, its gradient too, and the fit returns the bake."""
    scene, h, b = _setup(n=16, height=np.zeros((16, 16), np.float32))
    r = fit.fit(h, b, scene, lights=FEW, held_out=HELD, progress=False)
    assert np.array_equal(r.horizon, b.horizon) and np.all(r.horizon == 0.0)
    assert (
        {k: v for k, v in r.mae["training"].items() if k != "per_light"}
        == {"baked": 0.0, "fitted": 0.0, "lights_worse": 0}
        and all(p["baked"] == p["fitted"] == 0.0 for p in r.mae["training"]["per_light"])
        and r.loss[0] == 0.0
        and r.converged
    )


def test_fit_lowers_the_error_and_keeps_the_range(variant):
    scene, h, b = _setup(n=24, spp=2)
    r = fit.fit(h, b, scene, lights=FEW, held_out=HELD, progress=False)
    assert r.mae["training"]["fitted"] < 0.8 * r.mae["training"]["baked"]
    assert r.horizon.shape == b.horizon.shape and r.horizon.min() >= 0.0 and r.horizon.max() <= 1.0
    assert r.loss[-1] < r.loss[0] and r.epochs == len(r.loss) == len(r.epoch_seconds) and r.k == 8.0
    record = r.record()
    assert len(record["lights"]["training"]) == 8 and record["storage"] == "float"
    # the reported error is the sweep's: the technique rendering the fitted map
    V = fitted_training.visibility(scene, h, r.lights)
    assert fitted_training.mean_error(scene, b, r.horizon, r.lights, V, r.k) == pytest.approx(
        r.mae["training"]["fitted"]
    )


def test_u8_fit_is_stored_in_8_bits_and_beats_the_8_bit_bake(variant):
    scene, h, b = _setup(n=24, spp=2)
    r = fit.fit(h, b, scene, lights=FEW, held_out=HELD, storage="u8", progress=False)
    q = r.horizon * 255.0
    assert np.array_equal(q, np.rint(q))  # what the 8-bit texture holds
    assert r.mae["training"]["fitted"] < r.mae["training"]["baked"]
    V = fitted_training.visibility(scene, h, r.lights)
    u8 = fitted_training.mean_error(
        scene, b, bake_u8 := horizon.hz_storage.get("u8").roundtrip(b.horizon), r.lights, V, 8.0
    )
    assert r.mae["training"]["baked"] == pytest.approx(u8) and bake_u8.dtype == np.float32


def test_fit_k_moves_k_within_its_range(variant):
    scene, h, b = _setup(n=24, spp=1)
    r = fit.fit(h, b, scene, lights=FEW, held_out="", fit_k=True, k=8.0, progress=False)
    assert r.fit_k and 1.0 <= r.k <= fit.MAX_K and r.k != 8.0 and "held_out" not in r.mae


def test_files_are_the_bakes_layout_and_read_back_exactly(variant, tmp_path):
    scene, h, b = _setup(n=16)
    r = fit.fit(h, b, scene, lights=FEW, held_out="", progress=False)
    fitted_store.write_fit(r, tmp_path, input_info={"test": True})
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "fit.json",
        "horizon0.exr",
        "horizon0.png",
        "horizon1.exr",
        "horizon1.png",
    ]
    raw = external.read_layers([tmp_path / "horizon0.exr", tmp_path / "horizon1.exr"])
    assert np.array_equal(external.to_hzval(raw, external.Encoding()), r.horizon)
    sines, record = fitted_store.read_fit(tmp_path)
    assert np.array_equal(sines, r.horizon) and record["mae"] == json.loads(json.dumps(r.mae))
    png = external.read_layers([tmp_path / "horizon0.png", tmp_path / "horizon1.png"])
    assert np.max(np.abs(png - r.horizon)) <= 0.5 / 255 + 1e-7


def test_memory_estimate_refuses_what_cannot_fit(monkeypatch):
    assert (
        fitted_training.estimate_bytes(2048, 2048, 16, 96)
        > fitted_training.estimate_bytes(512, 512, 16, 96)
        > 0
    )
    monkeypatch.setattr(resources, "available_bytes", lambda: 2 * 2**30)
    with pytest.raises(InputError, match="GiB"):
        fitted_training.check_fits("x.png", 2048, 2048, 16, 96)
    assert fitted_training.check_fits("x.png", 64, 64, 16, 96) < 2 * 2**30


def test_cli_fit_writes_the_map_and_refuses_bad_lights(variant, tmp_path, capsys):
    out = tmp_path / "fit"
    assert (
        cli.main(["fit", "--material", "bricks", "--size", "16", "--lights", "x@0", "--out", str(out)]) == 2
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--lights" in err[0] and not out.exists()
    assert (
        cli.main(
            [
                "fit",
                "--material",
                "bricks",
                "--size",
                "16",
                "--lights",
                FEW,
                "--held-out",
                HELD,
                "--storage",
                "u8",
                "--quiet",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    record = json.loads((out / "fit.json").read_text())
    assert record["storage"] == "u8" and record["input"]["builtin"] == "bricks" and record["epochs"] >= 1
    assert set(record["mae"]) == {"training", "held_out"}


def test_horizon_fit_is_opt_in_cached_and_splits_the_error(variant, tmp_path):
    scene = sc.override(sc.Scene(), size=16, depth=0.1, spp=2, azimuths="0,90")
    assert "horizon-fit" not in [t.name for t in technique.select(None, scene)]
    opts = sweep.Options(
        techniques=("horizon", "horizon-fit"), settings={"horizon-fit": {"lights": FEW, "held_out": ""}}
    )
    m = sweep.run(scene, tmp_path, options=opts, progress=False)
    assert m["techniques"]["horizon-fit"]["parameters"]["fit"]["cached"] is False
    for f in m["frames"]:
        base, fitted = f["techniques"]["horizon"], f["techniques"]["horizon-fit"]
        assert fitted["split"]["bake_loss"] == pytest.approx(
            base["visibility_mae"] - fitted["visibility_mae"]
        )
        assert fitted["split"]["representation"] == fitted["visibility_mae"]
    again = sweep.run(scene, tmp_path, options=opts, progress=False)
    assert again["techniques"]["horizon-fit"]["parameters"]["fit"]["cached"] is True
    assert [f["techniques"]["horizon-fit"]["visibility_mae"] for f in again["frames"]] == [
        f["techniques"]["horizon-fit"]["visibility_mae"] for f in m["frames"]
    ]
    assert horizon_fit.FittedHorizon.frame_extras({"horizon": {"visibility_mae": 0.1}}) == {}


def test_the_pull_toward_the_bake_keeps_the_map_nearer_it(variant):
    scene, h, b = _setup(n=24, spp=1)
    free = fit.fit(h, b, scene, lights=FEW, held_out="", prior=0.0, progress=False)
    held = fit.fit(h, b, scene, lights=FEW, held_out="", prior=1.0, progress=False)
    assert held.settings["prior"] == 1.0 and free.settings["prior"] == 0.0
    assert np.mean(np.abs(held.horizon - b.horizon)) < 0.5 * np.mean(np.abs(free.horizon - b.horizon))
    assert free.mae["training"]["fitted"] <= held.mae["training"]["fitted"]


@pytest.mark.parametrize("boundary", ["wrap", "open"])
def test_one_truth_set_up_renders_every_elevation_as_a_fresh_one(variant, boundary):
    """fitted_training.visibility sets the truth up once, for its lowest elevation: each higher elevation's V
    is
    the V of a truth set up for that elevation, bit for bit."""
    import dataclasses

    from hzval.truth import plane as truth

    scene, h, _ = _setup(n=20, spp=2)
    scene = sc.override(scene, boundary=boundary)
    lights = ((12.0, 30.0), (35.0, 200.0), (35.0, 10.0), (70.0, -45.0))
    shared = fitted_training.visibility(scene, h, lights)
    base = fitted_training.fit_scene(scene)
    for (e, az), v in zip(lights, shared):
        fresh = truth.Truth(
            dataclasses.replace(base, light=dataclasses.replace(base.light, elevation_deg=e)), h
        )
        assert np.array_equal(fresh.render(az).layers["visibility"], v)
    assert not all(np.array_equal(shared[0], v) for v in shared[1:])  # the lights differ
