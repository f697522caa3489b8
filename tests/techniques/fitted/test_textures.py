"""A per-pixel technique's textures fitted to the truth (hzval.techniques.fitted.textures, the NAME-fit
techniques, ``hzval fit --technique``), the block storage of their textures, and the floor's place in
the rankings.

The forward model is each technique's own render, bit for bit; its gradient is the finite
difference's where the factor is smooth; the micro-shadowing fits reach the per-texel optimum that
an exhaustive search over the 256 levels, written here from the techniques' renders alone, finds;
a fit never does worse than the bake on its training lights; its files read back as written.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from hzval.bake import maps as bake
from hzval.cli import main as cli
from hzval.core import conventions as cv
from hzval.metrics import facing as hzfacing
from hzval.pipeline import records
from hzval.report import ranking
from hzval.scene import spec as sc
from hzval.techniques import perpixel
from hzval.techniques import registry as technique
from hzval.techniques.fitted import fit, textures
from hzval.techniques.fitted import store as fitted_store
from hzval.techniques.fitted import training as fitted_training

FEW = "20,40@0:270:90"  # 8 training lights: fast fits for the tests
HELD = "30@45:225:180"
FITTABLE = ("microshadow-filament", "microshadow-hdrp", "bent-cone", "ssbump")


def _setup(n=24, spp=1, depth=0.1, material="bricks"):
    from hzval.materials import generate

    scene = sc.override(sc.Scene(), size=n, depth=depth, spp=spp, effects="shadow")
    h = generate(material, n, seed=1).height
    return scene, h, bake.bake(h, bake.BakeParams(depth=depth).validate())


# --------------------------------------------------------------------------
# Storage
# --------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("texture", "storage", "bytes_per_texel"),
    [
        ("ao", "float", 4.0),
        ("ao", "u8", 1.0),
        ("ao", "bc4", 0.5),
        ("bent-normal", "u8", 3.0),
        ("bent-normal", "bc5", 1.0),
    ],
)
def test_bytes_per_texel_are_the_formats(texture, storage, bytes_per_texel):
    t = perpixel.TEXTURES[texture]
    channels = 3 if t.signed else 1
    assert perpixel.texture_bytes(t, storage, 64, 32, channels) / (64 * 32) == bytes_per_texel


def test_ssbump_block_formats_bytes(variant):
    from hzval.techniques.ssbump import SSBump

    t = SSBump.texture("ssbump")
    assert t.storages == ("float", "u8", "bc1", "bc7")
    assert perpixel.texture_bytes(t, "bc1", 32, 32, 3) / 1024 == 0.5
    assert perpixel.texture_bytes(t, "bc7", 32, 32, 3) / 1024 == 1.0


def test_block_storage_keeps_the_values_and_rebuilds_a_unit_z(variant):
    scene, h, b = _setup(32)
    ao = perpixel.stored(b.mean_cos2, "bc4")
    # BC4: 8 levels between each 4x4 block's two end points
    assert ao.shape == b.mean_cos2.shape and np.abs(ao - b.mean_cos2).mean() < 0.015
    assert np.abs(ao - b.mean_cos2).max() < 0.06
    bent = perpixel.stored(b.bent_normal, "bc5", signed=True)
    assert np.allclose(np.linalg.norm(bent, axis=-1), 1.0, atol=1e-5) and (bent[..., 2] >= 0).all()
    assert np.abs(bent - b.bent_normal).mean() < 0.01 and np.abs(bent - b.bent_normal).max() < 0.1
    # the z a BC5 shader rebuilds is the baked one where x and y survive the blocks
    assert np.abs(bent[..., 2] - b.bent_normal[..., 2]).mean() < 0.01


def test_metrics_record_the_bytes_per_texel_of_the_formats(variant, tmp_path):
    from hzval.pipeline import sweep

    scene = sc.override(sc.Scene(), size=16, effects="shadow", azimuths="0")
    opts = sweep.Options(
        techniques=("bent-cone", "ssbump"),
        settings={
            "bent-cone": {"storage": {"bent-normal": "bc5", "ao": "bc4"}},
            "ssbump": {"storage": {"ssbump": "bc1"}},
        },
    )
    result = sweep.run(scene, tmp_path / "run", options=opts, progress=False)
    t = result["techniques"]
    assert t["bent-cone"]["parameters"]["bytes_per_texel"] == {"bent-normal": 1.0, "ao": 0.5}
    assert t["bent-cone"]["texture_bytes_per_texel"] == 1.5
    assert t["ssbump"]["texture_bytes_per_texel"] == 0.5


def test_a_storage_a_texture_does_not_have_is_refused(variant):
    from hzval.core.errors import InputError
    from hzval.techniques.microshadow_hdrp import MicroshadowHDRP

    with pytest.raises(InputError, match="ao-storage"):
        MicroshadowHDRP.check_settings(bake.BakeParams(), {"storage": {"ao": "bc5"}})


# --------------------------------------------------------------------------
# The forward model
# --------------------------------------------------------------------------


@pytest.mark.parametrize("name", FITTABLE)
def test_forward_model_is_the_techniques_own_render(variant, name):
    """The fit's F, straight-through on, has the render's values (spp 1: the same samples, one each)."""
    scene, h, b = _setup(24)
    cls = technique.get(name)
    lights = ((20.0, 10.0), (35.0, 200.0))
    model = textures.TextureModel(scene, b, cls, {}, [np.zeros(h.shape, np.float32)] * len(lights), lights)
    model.upload({t: model.tech.stored_plane(t) for t in cls.textures})
    F = np.asarray(model.factor(lights, 0, model.P)).reshape(len(lights), *h.shape)
    ref = cls(fitted_training.fit_scene(scene), b, None)
    for i, (e, az) in enumerate(lights):
        assert np.allclose(F[i], ref.render(az, elevation_deg=e).layers["factor"], atol=1e-6), name


def test_ssbump_gradient_is_the_finite_differences(variant):
    """d loss / d S at a texel where F is not clamped: AD against a central difference."""
    import drjit as dr
    import mitsuba as mi

    from hzval.scene import lookup

    scene, h, b = _setup(16)
    cls = technique.get("ssbump")
    lights = ((30.0, 20.0),)
    V = [np.full(h.shape, 0.5, np.float32)]
    model = textures.TextureModel(scene, b, cls, {}, V, lights)
    model.masks, model.W = None, None  # every pixel counts: a smooth sum

    def loss_of(S_):
        p = mi.TensorXf(lookup.aligned(S_.astype(np.float32)))
        dr.enable_grad(p)
        model.set_parameters({"ssbump": p})
        value = model.backward([0], lights, 1.0)
        return value, np.asarray(dr.grad(p)).reshape(S_.shape)

    base = b.ssbump.astype(np.float64)
    _, grad = loss_of(base)
    # a texel whose neighbourhood's F is nowhere clamped (the clamp's gradient passes straight through)
    F = np.asarray(model.factor(lights, 0, model.P)).reshape(h.shape)
    inner = (F > 0.05) & (F < 0.95)
    ok = inner.copy()
    for dr_, dc in ((1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1), (-1, -1)):
        ok &= np.roll(np.roll(inner, dr_, 0), dc, 1)
    r, c = (int(i[0]) for i in np.nonzero(ok))
    ch = 0
    eps = 1e-3
    up, down = base.copy(), base.copy()
    up[r, c, ch] += eps
    down[r, c, ch] -= eps
    numeric = (loss_of(up)[0] - loss_of(down)[0]) / (2 * eps)
    assert grad[r, c, ch] == pytest.approx(numeric, rel=0.05, abs=1e-3)


# --------------------------------------------------------------------------
# The fit
# --------------------------------------------------------------------------


def _oracle(scene, h, b, name, lights):
    """The per-texel optimum, found independently of the fit: the technique rendered with its AO map
    uniform at each of the 256 u8 levels, each pixel's error over the lights (facing pixels, each light
    weighted by its facing count, the fit's criterion) kept at its best level."""
    cls = technique.get(name)
    fs = fitted_training.fit_scene(scene)
    V, _ = fit.truths(fs, fs, h, lights, (), False)
    masks = [hzfacing.facing_mask(b.normal, cv.light_direction(az, e)) for e, az in lights]
    best = np.full(h.shape, np.inf)
    for level in range(256):
        uniform = dataclasses.replace(b, mean_cos2=np.full_like(b.mean_cos2, level / 255.0))
        t = cls(fs, uniform, None)
        cost = sum(
            np.abs(t.render(az, elevation_deg=e).layers["factor"] - v) * m / max(m.sum(), 1)
            for (e, az), v, m in zip(lights, V, masks)
        )
        best = np.minimum(best, cost)
    return float(best.sum() / len(lights))


@pytest.mark.parametrize("name", ["microshadow-filament", "microshadow-hdrp"])
def test_micro_shadowing_floor_is_the_per_texel_optimum(variant, name):
    scene, h, b = _setup(20)
    lights = fitted_training.parse_lights(FEW)
    oracle = _oracle(scene, h, b, name, lights)
    r = textures.fit_textures(h, b, scene, name, settings={"storage": {"ao": "u8"}}, lights=FEW, held_out="")
    got = r.mae["training"]["fitted"]
    assert got <= max(1.1 * oracle, oracle + 0.003), (got, oracle)
    assert got <= r.mae["training"]["baked"]


@pytest.mark.parametrize("name", FITTABLE)
def test_a_fit_is_never_worse_than_the_bake_on_its_training_lights(variant, name):
    scene, h, b = _setup(24, material="gravel")
    r = textures.fit_textures(h, b, scene, name, lights=FEW, held_out=HELD, progress=False)
    assert r.mae["training"]["fitted"] <= r.mae["training"]["baked"]
    assert set(r.planes) == set(technique.get(name).textures)
    for t, plane in r.planes.items():
        assert plane.shape == technique.get(name)(scene, b, None).plane(t).shape
        if technique.get(name).texture(t).signed:
            assert np.allclose(np.linalg.norm(plane, axis=-1), 1.0, atol=1e-4)
        else:
            assert plane.min() >= 0.0 and plane.max() <= 1.0
    assert [p["elevation_deg"] for p in r.mae["held_out"]["per_light"]] == [30.0, 30.0]


def test_a_flat_surface_has_nothing_to_fit(variant):
    scene, _, _ = _setup(16)
    h = np.zeros((16, 16), np.float32)
    b = bake.bake(h, bake.BakeParams(depth=0.1))
    for name in ("microshadow-hdrp", "ssbump"):
        r = textures.fit_textures(h, b, scene, name, lights=FEW, held_out="", progress=False)
        assert r.mae["training"]["baked"] == 0.0 and r.mae["training"]["fitted"] == 0.0


def test_a_technique_without_textures_cannot_be_fitted():
    from hzval.core.errors import InputError

    assert set(FITTABLE) == set(textures.fittable())
    with pytest.raises(InputError, match="--technique"):
        textures.check_fittable("terrain")


def test_written_fit_reads_back_and_a_cache_is_reused(variant, tmp_path):
    scene, h, b = _setup(16)
    kw = {"settings": {"storage": {"bent-normal": "bc5", "ao": "u8"}}, "lights": FEW, "held_out": ""}
    planes, record, cached = fitted_store.cached_texture_fit(h, b, scene, tmp_path / "c", "bent-cone", **kw)
    assert not cached and record["technique"] == "bent-cone"
    again, _, cached = fitted_store.cached_texture_fit(h, b, scene, tmp_path / "c", "bent-cone", **kw)
    assert cached and all(np.array_equal(planes[t], again[t]) for t in planes)
    read, rec = fitted_store.read_texture_fit(tmp_path / "c")
    assert rec["storage"] == {"bent-normal": "bc5", "ao": "u8"}
    assert all(np.array_equal(read[t], planes[t]) for t in planes)


# --------------------------------------------------------------------------
# The command, the sweep and the rankings
# --------------------------------------------------------------------------


def test_cli_fits_a_technique_and_refuses_the_horizon_flags(variant, tmp_path, capsys):
    out = tmp_path / "f"
    argv = ["fit", "--size", "16", "--technique", "microshadow-hdrp", "--ao-storage", "bc4"]
    assert cli.main([*argv, "--lights", FEW, "--held-out", HELD, "--out", str(out), "--quiet"]) == 0
    record = json.loads((out / "fit.json").read_text())
    assert record["storage"] == {"ao": "bc4"} and record["settings"] == {"opacity": 1.0}
    assert len(record["mae"]["held_out"]["per_light"]) == 2
    assert (out / "ao.exr").is_file() and "microshadow-hdrp" in capsys.readouterr().out
    code = cli.main(
        ["fit", "--size", "16", "--technique", "ssbump", "--k", "4", "--out", str(tmp_path / "g")]
    )
    assert code == 2 and "--k" in capsys.readouterr().err and not (tmp_path / "g").exists()


def test_a_sweep_with_a_fit_shows_the_floor(variant, tmp_path):
    from hzval.pipeline import sweep
    from hzval.report import pages as report

    scene = sc.override(sc.Scene(), size=20, depth=0.1, effects="shadow", azimuths="0,90", elevation="30,50")
    opts = sweep.Options(
        techniques=("microshadow-filament", "microshadow-filament-fit"),
        settings={"microshadow-filament-fit": {"lights": FEW, "held_out": ""}},
    )
    result = sweep.run(scene, tmp_path / "run", options=opts, progress=False)
    assert result["techniques"]["microshadow-filament-fit"]["fit_of"] == "microshadow-filament"
    rows = ranking.floors(result)["microshadow-filament"]
    assert [r["elevation_deg"] for r in rows] == [30.0, 50.0]
    for r in rows:
        assert r["bake_loss"] == pytest.approx(r["shipped"] - r["floor"])
    table = records.summary_table(result)
    assert "floor" in table.splitlines()[0] and "bake loss" in table
    assert (tmp_path / "run" / "fit" / "microshadow_filament_fit" / "fit.json").is_file()
    report.write_report(tmp_path / "run", result, command="hzval sweep")
    html = (tmp_path / "run" / "index.html").read_text()
    assert "bake loses" in html and (tmp_path / "run" / "plots" / "error_per_byte.png").is_file()


def _metrics(shipped: dict, fitted: dict, none: dict) -> dict:
    frames = [
        {
            "elevation_deg": e,
            "techniques": {
                "a": {"visibility_mae_facing": shipped[e]},
                "a-fit": {"visibility_mae_facing": fitted[e]},
            },
            "no_shadows": {"visibility_mae_facing": none[e]},
        }
        for e in shipped
    ]
    return {
        "techniques": {"a": {"label": "A", "texture_bytes_per_texel": 1.0}, "a-fit": {"fit_of": "a"}},
        "frames": frames,
    }


def test_floors_split_the_error_and_say_where_the_formula_does_harm():
    m = _metrics({30.0: 0.05, 60.0: 0.04}, {30.0: 0.01, 60.0: 0.03}, {30.0: 0.02, 60.0: 0.0})
    rows = ranking.floors(m)["a"]
    assert [r["bake_loss"] for r in rows] == pytest.approx([0.04, 0.01])
    assert [r["harms"] for r in rows] == [False, True]
    assert ranking.formula_harms(m) == {"a": [60.0]}
    # a floor a hair above no shadows' 0 is not harm
    m = _metrics({60.0: 0.001}, {60.0: 0.0002}, {60.0: 0.0})
    assert ranking.formula_harms(m) == {}
    r = next(r for r in ranking.ranking(m) if r["name"] == "a")
    assert r["floor"] == pytest.approx(0.0002) and r["bake_loss"] == pytest.approx(0.0008)


def test_error_per_byte_marks_the_pareto_front():
    m = _metrics({30.0: 0.05}, {30.0: 0.01}, {30.0: 0.02})
    m["techniques"]["a-fit"]["texture_bytes_per_texel"] = 1.0
    points = {p["name"]: p for p in ranking.error_per_byte(m)[30.0]}
    assert points["no shadows"]["bytes_per_texel"] == 0.0 and points["no shadows"]["pareto"]
    assert points["a-fit"]["pareto"] and points["a-fit"]["fitted"] and not points["a"]["pareto"]
