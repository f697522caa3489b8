"""8 vs 16 stored horizon directions (``BakeParams.directions``), against known answers.

With ``D`` directions channel ``c`` looks toward azimuth ``360 c / D``
(:func:`hzval.core.conventions.channel_azimuth_deg`) and averages the
``angles / D + 1`` bins centred on it: with 32 bins, channel ``2c`` of a
16-direction map is the mean of the 3 central bins of the 5 that channel
``c`` of the 8-direction map averages. So the two are equal where those 5
bins hold the same sine (a wall close enough that its nearest texel covers
them all), and in general ``5 ch8[c] - 3 ch16[2c]`` is the sum of the two
outer bins' sines, in ``[0, 2 max sine]``.
"""

import dataclasses
import json
import math

import numpy as np
import pytest

import hzval.bake as B
from hzval.core import conventions as cv
from hzval.core.errors import InputError
from hzval.materials.bricks import bricks
from hzval.scene.spec import MaterialSpec, Scene
from hzval.techniques import horizon
from tests.hard._ref import horizon_f64


def bake(h, **kw):
    return B.bake(np.asarray(h, np.float32), B.BakeParams(**kw))


def test_direction_geometry_lives_in_conventions():
    assert cv.channel_azimuths_deg(8) == cv.CHANNEL_AZIMUTHS_DEG
    assert cv.channel_azimuths_deg(16) == tuple(22.5 * c for c in range(16))
    assert cv.layer_count(8) == 2 and cv.layer_count(16) == 4
    assert cv.channels_per_radian(8) == 4.0 / math.pi  # the 8-channel kernels' constant, exactly


def test_validation():
    B.BakeParams(directions=16).validate()
    B.BakeParams(directions=16, angles=64).validate()
    for bad in (4, 12, 32, 16.5, 16.0, True, "16"):
        with pytest.raises(InputError, match="--directions"):
            B.BakeParams(directions=bad).validate()
    with pytest.raises(InputError, match="multiple of 32"):
        B.BakeParams(directions=16, angles=48).validate()
    with pytest.raises(InputError, match="--directions.*exact"):
        B.BakeParams(directions=16, method="exact").validate()


def test_flat_map_has_no_horizon_in_any_of_16_channels(variant):
    r = bake(np.full((9, 13), 0.3), directions=16)
    assert r.horizon.shape == (9, 13, 16) and r.horizon.dtype == np.float32
    assert np.all(r.horizon == 0.0)
    assert len(r.layers) == 4 and all(layer.shape == (9, 13, 4) for layer in r.layers)


@pytest.mark.parametrize("d", [1, 2, 3])
def test_wall_channel_2c_of_16_equals_channel_c_of_8_where_their_bins_agree(variant, d):
    """A wall 4 texels high (as in tests/bake/test_maps.py) d <= 3 texels to the right: its nearest
    texel covers bins -2..2, so channel 0 is sin(atan(4/d)) with 8 and with 16 directions."""
    h = np.zeros((9, 32), np.float32)
    h[:, 20] = 1.0
    r8 = bake(h, depth=0.125, boundary="open")
    r16 = bake(h, depth=0.125, boundary="open", directions=16)
    expect = 4.0 / math.hypot(4.0, d)
    left16 = r16.horizon[4, 20 - d]
    assert r8.horizon[4, 20 - d, 0] == pytest.approx(expect, rel=1e-6)
    assert left16[0] == pytest.approx(expect, rel=1e-6)
    # facing the wall: 22.5 degrees either side see it, symmetrically (row 4 is the middle row)
    assert left16[1] > 0 and left16[15] > 0 and left16[1] == left16[15]
    assert left16[1] <= left16[0]  # equal at d = 1: the nearest texel covers +-35 degrees
    # facing away (112.5 .. 247.5 degrees): nothing
    assert np.all(left16[5:12] == 0.0)
    # the relation in the module docstring, on every texel and channel
    s8, s16 = r8.horizon.astype(np.float64), r16.horizon.astype(np.float64)
    outer = 5 * s8 - 3 * s16[..., ::2]
    assert np.all(outer >= -1e-5) and np.all(outer <= 2 * s16.max() + 1e-5)


@pytest.mark.parametrize("angles", [32, 64])
def test_16_directions_match_the_float64_reference(variant, angles):
    rng = np.random.default_rng(angles)
    h = cv.heights_in_texels(rng.random((12, 15)).astype(np.float32), 0.1)
    got = B.horizon_map(h, 6, angles, "wrap", directions=16)
    ref, mean_cos, mean_cos2 = horizon_f64(h, 6, angles, "wrap", directions=16)
    assert np.allclose(got[0].reshape(-1, 16), ref, atol=2e-6, rtol=0)
    # the bins, and so the ambient terms, do not depend on the directions stored
    eight = B.horizon_map(h, 6, angles, "wrap")
    assert got[1].tobytes() == eight[1].tobytes() and got[2].tobytes() == eight[2].tobytes()


def test_rotating_the_map_90_degrees_permutes_16_channels_by_4(variant):
    rng = np.random.default_rng(5)
    h = rng.random((24, 24)).astype(np.float32)
    r = bake(h, depth=0.1, directions=16).horizon
    rot = bake(np.rot90(h), depth=0.1, directions=16).horizon  # counterclockwise on screen
    expect = np.roll(np.rot90(r, axes=(0, 1)), 4, axis=-1)  # azimuth + 90 = channel + 4
    # exact: the radius-16, 32-bin float32 offset table maps (i, j) -> (-j, i) onto bins + 8, and
    # each channel sums the same bins' sines in the same order
    assert np.array_equal(rot, expect)


def test_bake_files_round_trip_with_16_directions(variant, tmp_path):
    rng = np.random.default_rng(2)
    r = bake(rng.random((10, 12)), directions=16)
    B.write_bake(r, tmp_path, input_info={"digest": "x"})
    names = {p.name for p in tmp_path.iterdir()}
    assert {f"horizon{i}.{e}" for i in range(4) for e in ("exr", "png")} <= names
    assert "cube" not in names
    record = json.loads((tmp_path / "bake.json").read_text())
    assert record["parameters"]["directions"] == 16
    assert "22.5" in record["outputs"]["horizon0"]
    back = B.read_bake(tmp_path)
    assert back.params.directions == 16 and back.horizon.tobytes() == r.horizon.tobytes()
    # an 8-direction bake written over it leaves no stale layers behind
    B.write_bake(bake(rng.random((10, 12))), tmp_path, input_info={"digest": "y"})
    assert not (tmp_path / "horizon2.exr").exists() and (tmp_path / "cube").is_dir()
    assert B.read_bake(tmp_path).horizon.shape[-1] == 8
    # and a 16-direction bake over that leaves no cube, not even an empty folder
    B.write_bake(r, tmp_path, input_info={"digest": "x"})
    assert not (tmp_path / "cube").exists()


def test_old_bake_json_without_directions_reads_as_8_and_stays_cached(variant, tmp_path):
    h = np.random.default_rng(4).random((8, 8)).astype(np.float32)
    params = B.BakeParams()
    first, cached = B.cached_bake(h, "d", params, tmp_path, {"digest": "d"})
    assert not cached
    record = json.loads((tmp_path / "bake.json").read_text())
    del record["parameters"]["directions"]  # as written before it existed
    (tmp_path / "bake.json").write_text(json.dumps(record))
    again, cached = B.cached_bake(h, "d", params, tmp_path, {"digest": "d"})
    assert cached and again.params.directions == 8
    _, cached = B.cached_bake(h, "d", dataclasses.replace(params, directions=16), tmp_path, {"digest": "d"})
    assert not cached


def test_cube_weights_and_the_gpu_path_need_8_directions(variant):
    r = bake(np.zeros((8, 8)), directions=16)
    scene = Scene(material=MaterialSpec(size=8), spp=1)
    for kw in ({"path": "gpu"}, {"weights": "cube"}):
        with pytest.raises(InputError, match="8"):
            horizon.Horizon(scene, r, **kw)
    horizon.Horizon(scene, r, storage="u8")  # 8-bit storage works for any D


@pytest.mark.parametrize("c", [0, 1, 3, 5, 10, 15])
def test_light_on_a_channel_reads_that_channel(variant, c):
    rng = np.random.default_rng(c)
    r = bake(rng.random((8, 8)), depth=0.2, directions=16)
    scene = Scene(material=MaterialSpec(size=8), spp=1)
    a = horizon.Horizon(scene, r)
    rows, cols = 8, 8
    x, y = cv.texel_centres(rows, cols)
    az, el = cv.channel_azimuth_deg(c, 16), 20.0
    out = a.sample(x, y, az, el)
    channel = r.horizon[..., c].ravel()
    assert np.allclose(out["horizon_sine"], channel, atol=1e-6)
    lz = math.sin(math.radians(el))
    assert np.allclose(out["factor"], np.clip(horizon.DEFAULT_K * (lz - channel) + 1, 0, 1), atol=1e-5)


def test_bricks_16_directions_against_the_truth(variant, capsys):
    """|F - V| over the default sweep on the built-in bricks at 64 px: measured and printed."""
    from hzval.scene.spec import load_albedo
    from hzval.truth import plane as truth

    scene = Scene(material=MaterialSpec(size=64), spp=4)
    h = bricks(64)
    albedo = load_albedo(scene.material, 64, 64)
    V = [f.layers["visibility"] for f in map(truth.Truth(scene, h).render, scene.light.azimuths_deg)]
    mae = {}
    for d in (8, 16):
        ap = horizon.Horizon(scene, B.bake(h, B.BakeParams(directions=d)), albedo)
        F = [ap.render(az).layers["factor"] for az in scene.light.azimuths_deg]
        assert all(np.isfinite(f).all() and (f >= 0).all() and (f <= 1).all() for f in F)
        mae[d] = float(np.mean([np.mean(np.abs(f.astype(np.float64) - v)) for f, v in zip(F, V)]))
    with capsys.disabled():
        print(
            f"\nbricks 64 px, default sweep: mean |F - V| 8 directions {mae[8]:.5f}, "
            f"16 directions {mae[16]:.5f}"
        )
    assert 0 < mae[16] < 1
    assert mae[16] <= mae[8] + 0.005
