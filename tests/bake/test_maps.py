"""The baker against answers known in advance (docs/ARCHITECTURE.md, issue 2).

The seed peer (tests/bake/test_horizon_peer.py) checks that the bake reproduces the
seed loop; these tests check that what it computes means what we say it does.
"""

import math

import numpy as np
import pytest

import hzval.bake as B
from hzval.core import conventions as cv
from hzval.core import cube as cube_layout

DEFAULT = B.BakeParams()


def bake(h, **kw):
    return B.bake(np.asarray(h, np.float32), B.BakeParams(**kw))


def test_flat_map_has_no_horizon_and_straight_normals(variant):
    r = bake(np.full((9, 13), 0.3))
    assert r.horizon.shape == (9, 13, 8) and r.horizon.dtype == np.float32
    assert np.all(r.horizon == 0.0)
    assert np.allclose(r.normal, [0.0, 0.0, 1.0])
    assert np.all(r.mean_cos == 1.0) and np.all(r.mean_cos2 == 1.0)


@pytest.mark.parametrize("d", [1, 2, 3])
def test_wall_gives_its_sine_toward_it_and_none_away(variant, d):
    # A wall 4 texels high (H = 1, depth 0.125, 32 columns) at column 20.
    # From d texels to its left, the nearest wall texel covers all five bins
    # of channel 0 (its angular extent atan(0.7071/d) >= 13 degrees), so the
    # channel holds exactly the sine of atan(4 / d).
    h = np.zeros((8, 32), np.float32)
    h[:, 20] = 1.0
    r = bake(h, depth=0.125, boundary="open")
    expect = 4.0 / math.hypot(4.0, d)
    left, right = r.horizon[4, 20 - d], r.horizon[4, 20 + d]
    assert left[0] == pytest.approx(expect, abs=1e-6)  # facing the wall (0 deg)
    assert left[4] == 0.0  # away from it (180 deg)
    assert right[4] == pytest.approx(expect, abs=1e-6)
    assert right[0] == 0.0


def test_pit_sees_the_same_horizon_in_every_direction(variant):
    # A one-texel pit 3 texels deep: the four edge neighbours (r = 1) cover
    # every bin, so all channels hold sin(atan 3) and the ambient terms are
    # cos(atan 3) and its square, exactly.
    h = np.ones((7, 7), np.float32)
    h[3, 3] = 0.0
    r = bake(h, depth=3 / 7, boundary="open")
    sin_a, cos_a = 3 / math.sqrt(10), 1 / math.sqrt(10)
    assert r.horizon[3, 3] == pytest.approx([sin_a] * 8, abs=1e-6)
    assert r.mean_cos[3, 3] == pytest.approx(cos_a, abs=1e-6)
    assert r.mean_cos2[3, 3] == pytest.approx(cos_a**2, abs=1e-6)


def test_rotating_the_map_by_90_degrees_permutes_channels_by_two(variant):
    rng = np.random.default_rng(7)
    h = rng.random((24, 24)).astype(np.float32)
    a = bake(h, depth=0.2)
    b = bake(np.rot90(h), depth=0.2)  # content turns 90 deg counterclockwise
    for k in range(8):
        assert np.allclose(b.horizon[..., (k + 2) % 8], np.rot90(a.horizon[..., k]), atol=1e-6), k
    # the normals turn with it: (nx, ny) -> (-ny, nx)
    na = np.rot90(a.normal)
    assert np.allclose(b.normal[..., 0], -na[..., 1], atol=1e-6)
    assert np.allclose(b.normal[..., 1], na[..., 0], atol=1e-6)


def test_wrap_finds_an_occluder_across_the_edge_and_open_does_not(variant):
    h = np.zeros((8, 16), np.float32)
    h[:, 0] = 1.0  # wall 4 texels high on the left edge
    wrap = bake(h, depth=0.25, boundary="wrap")
    open_ = bake(h, depth=0.25, boundary="open")
    assert wrap.horizon[3, 15, 0] == pytest.approx(4 / math.sqrt(17), abs=1e-6)
    assert open_.horizon[3, 15, 0] == 0.0
    # and the same across the top/bottom edge (channel 2 looks up = row - 1)
    v = np.zeros((16, 8), np.float32)
    v[0, :] = 1.0
    assert bake(v, depth=0.5, boundary="wrap").horizon[15, 3, 6] == pytest.approx(4 / math.sqrt(17), abs=1e-6)
    assert bake(v, depth=0.5, boundary="open").horizon[15, 3, 6] == 0.0


def test_outputs_are_finite_and_in_range(variant):
    rng = np.random.default_rng(3)
    r = bake(rng.random((31, 17)), depth=1.0)
    assert np.isfinite(r.horizon).all() and (r.horizon >= 0).all() and (r.horizon <= 1).all()
    assert (r.mean_cos2 <= r.mean_cos + 1e-7).all() and (r.mean_cos2 > 0).all()
    assert np.allclose(np.linalg.norm(r.normal, axis=-1), 1.0, atol=1e-6)


def test_deeper_relief_raises_every_horizon(variant):
    rng = np.random.default_rng(4)
    h = rng.random((20, 20)).astype(np.float32)
    lo, hi = bake(h, depth=0.1), bake(h, depth=0.3)
    assert (hi.horizon >= lo.horizon - 1e-7).all()
    assert (hi.horizon > lo.horizon).any()


def test_radius_and_angles_are_parameters(variant):
    # a wall 10 texels away is inside radius 16 and outside radius 5
    h = np.zeros((8, 32), np.float32)
    h[:, 20] = 1.0
    assert bake(h, depth=0.125, boundary="open").horizon[4, 10, 0] > 0
    assert bake(h, depth=0.125, boundary="open", radius=5, angles=16).horizon[4, 10, 0] == 0.0


def test_normal_map_of_a_ramp():
    # heights rising 0.5 texel per column: normal = normalize(-0.5, 0, 1)
    h = np.tile(np.arange(10, dtype=np.float32) * 0.5, (6, 1))
    n = B.normal_map(h, "open")
    assert n[3, 4] == pytest.approx(np.array([-0.5, 0.0, 1.0]) / math.sqrt(1.25), abs=1e-6)


def test_table_covers_the_seed_neighbourhood():
    groups = B.horizon_table(16, 32)
    offsets = [o for g in groups for o in g.offsets]
    assert len(offsets) == len(set(offsets))
    assert len(offsets) == sum(1 for j in range(-15, 16) for i in range(-15, 16) if 0 < i * i + j * j < 256)
    # the neighbour straight to the right (+x, azimuth 0) updates bin 0
    assert any((1, 0) in g.offsets and 0 in g.bins for g in groups)
    # straight up (+y, azimuth 90 deg) updates bin 8 of 32
    assert any((0, 1) in g.offsets and 8 in g.bins for g in groups)


def test_weight_cube_decodes_to_the_exact_weights():
    cube = B.weight_cube(16)
    assert cube.shape == (6, 16, 16, 4) and cube.dtype == np.uint8
    f = cube / 255.0
    w0 = np.clip(2 * f - 1, 0, 1)  # Lengyel eq. 5.3
    w1 = np.clip(1 - 2 * f, 0, 1)
    d = cube_layout.cube_texel_directions(16)
    exact = cv.channel_weights(d[..., 0], d[..., 1])
    decoded = np.concatenate([w0, w1], axis=-1)
    assert np.abs(decoded - exact).max() <= 1 / 255 + 1e-9
    assert np.allclose(decoded.sum(-1), 1.0, atol=3 / 255)


@pytest.mark.parametrize(
    "kw,what",
    [
        ({"depth": 0.0}, "--depth"),
        ({"depth": -1.0}, "--depth"),
        ({"depth": float("nan")}, "--depth"),
        ({"radius": 1}, "--radius"),
        ({"angles": 24}, "--angles"),
        ({"boundary": "mirror"}, "--boundary"),
    ],
)
def test_bad_parameters_are_input_errors(kw, what):
    from hzval.core.errors import InputError

    with pytest.raises(InputError) as e:
        B.BakeParams(**kw).validate()
    assert str(e.value).startswith(what)


def test_memory_estimate_refuses_a_map_that_cannot_fit():
    from hzval.core.errors import InputError

    with pytest.raises(InputError, match="GiB"):
        B.check_fits("huge.png", 1_000_000, 1_000_000, DEFAULT)
    B.check_fits("small.png", 64, 64, DEFAULT)


def test_cached_bake_reads_back_exactly_and_rebakes_on_change(variant, tmp_path):
    rng = np.random.default_rng(5)
    h = rng.random((12, 10)).astype(np.float32)
    p = B.BakeParams(radius=5, angles=16)
    info = {"digest": "sha256:abc"}
    first, cached = B.cached_bake(h, "sha256:abc", p, tmp_path, info)
    assert not cached
    again, cached = B.cached_bake(h, "sha256:abc", p, tmp_path, info)
    assert (
        cached and np.array_equal(again.horizon, first.horizon) and np.array_equal(again.normal, first.normal)
    )
    assert np.array_equal(again.mean_cos2, first.mean_cos2)
    _, cached = B.cached_bake(h, "sha256:abc", B.BakeParams(radius=5, angles=16, depth=0.1), tmp_path, info)
    assert not cached
    _, cached = B.cached_bake(h, "sha256:def", B.BakeParams(radius=5, angles=16, depth=0.1), tmp_path, info)
    assert not cached


def test_the_directional_occlusion_is_baked_only_for_the_techniques_that_read_it(variant, tmp_path):
    """occlusion=False: no bent normals or ssbump (nor their files); a cache without them serves such a
    run and is baked anew for one that reads them, whose cache then serves both; the maps it shares
    with the lighter bake are the same bits."""
    rng = np.random.default_rng(8)
    h = rng.random((12, 10)).astype(np.float32)
    p, info = B.BakeParams(radius=5, angles=16), {"digest": "sha256:abc"}
    light, cached = B.cached_bake(h, "sha256:abc", p, tmp_path, info, occlusion=False)
    assert not cached and light.bent_normal is None and light.ssbump is None
    assert light.contents == ("normal", "horizon_map", "ambient")
    assert not (tmp_path / "bent_normal.exr").exists() and not (tmp_path / "ssbump.exr").exists()
    again, cached = B.cached_bake(h, "sha256:abc", p, tmp_path, info, occlusion=False)
    assert cached and again.bent_normal is None
    full, cached = B.cached_bake(h, "sha256:abc", p, tmp_path, info)
    assert not cached and full.contents == B.CONTENTS and (tmp_path / "ssbump.exr").is_file()
    assert np.array_equal(full.horizon, light.horizon) and np.array_equal(full.mean_cos2, light.mean_cos2)
    for occlusion in (True, False):
        back, cached = B.cached_bake(h, "sha256:abc", p, tmp_path, info, occlusion=occlusion)
        assert cached and np.array_equal(back.ssbump, full.ssbump)
    assert B.needs_occlusion({"normal", "bent_normal"}) and not B.needs_occlusion({"horizon_map", "ambient"})


@pytest.mark.parametrize("damage", ["truncate", "flip a byte", "delete", "no digests"])
def test_a_damaged_bake_cache_is_baked_anew_with_a_notice(variant, tmp_path, damage):
    """A cache file that no longer has the digest bake.json recorded is never read: it is rebaked."""
    import json

    h = np.random.default_rng(6).random((12, 10)).astype(np.float32)
    p = B.BakeParams(radius=5, angles=16)
    first, _ = B.cached_bake(h, "sha256:abc", p, tmp_path, {"digest": "sha256:abc"})
    victim = tmp_path / "horizon0.exr"
    data = victim.read_bytes()
    if damage == "truncate":
        victim.write_bytes(data[: len(data) // 2])
    elif damage == "flip a byte":
        victim.write_bytes(data[:-9] + bytes([data[-9] ^ 0x01]) + data[-8:])
    elif damage == "delete":
        victim.unlink()
    else:
        record = json.loads((tmp_path / "bake.json").read_text())
        del record["files"]
        (tmp_path / "bake.json").write_text(json.dumps(record))
    notices: list[str] = []
    again, cached = B.cached_bake(h, "sha256:abc", p, tmp_path, {"digest": "sha256:abc"}, notices)
    assert not cached and len(notices) == 1 and "baked it anew" in notices[0]
    assert ("bake.json" if damage == "no digests" else "horizon0.exr") in notices[0]
    assert np.array_equal(again.horizon, first.horizon)
    # and the cache is whole again
    third, cached = B.cached_bake(h, "sha256:abc", p, tmp_path, {"digest": "sha256:abc"}, notices)
    assert cached and len(notices) == 1
