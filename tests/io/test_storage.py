"""Storage of the horizon map (hzval.io.storage): bytes, round trips through real block codecs, and
what the approximation reads from them."""

from __future__ import annotations

import numpy as np
import pytest

from hzval.bake import maps as bake
from hzval.io import storage as hz_storage
from hzval.io.codecs import unit_to_u8
from hzval.techniques import horizon
from tests.helpers import make_scene


def smooth_sines(rows=64, cols=64, D=8, seed=3):
    from scipy.ndimage import gaussian_filter

    g = gaussian_filter(np.random.default_rng(seed).random((rows, cols, D)), (3, 3, 0), mode="wrap")
    g = (g - g.min()) / (g.max() - g.min())
    return (0.6 * g * g).astype(
        np.float32
    )  # sines up to 0.6 (37 degrees), most of them low, as in baked maps


def test_bytes_of_each_format():
    """8 channels at 64 x 64: float 4 bytes a channel, u8 1; BC7/BC3 two RGBA textures of 16-byte
    blocks; BC1 three RGB textures of 8-byte blocks; BC4 eight one-channel textures of 8-byte blocks."""
    b = {n: hz_storage.get(n).bytes(64, 64, 8) for n in hz_storage.names()}
    blocks = 16 * 16
    assert b["float"] == 64 * 64 * 8 * 4 and b["u8"] == 64 * 64 * 8
    assert b["bc7"] == b["bc3"] == 2 * blocks * 16 == b["u8"] // 4
    assert b["bc1"] == 3 * blocks * 8 and b["bc4"] == 8 * blocks * 8
    assert b["bc7-sqrt"] == b["bc7"]
    assert hz_storage.get("bc7").bytes(10, 7, 8) == 2 * 3 * 2 * 16  # partial blocks count whole


def test_float_is_exact_and_u8_is_the_engines_quantisation():
    s = smooth_sines()
    np.testing.assert_array_equal(hz_storage.get("float").roundtrip(s), s)
    np.testing.assert_array_equal(hz_storage.get("u8").roundtrip(s), unit_to_u8(s).astype(np.float32) / 255)


@pytest.mark.parametrize("name", ["bc7", "bc3", "bc1", "bc4"])
def test_block_formats_round_trip_through_real_codecs(name):
    """Black and white survive every format exactly (block end points); a smooth map of eight
    independent channels comes back within a few 8-bit steps (measured: BC4 1.2, BC7 2.7, BC3 4.9,
    BC1 5.9 steps on average); odd sizes are padded and cropped."""
    fmt = hz_storage.get(name)
    for v in (0.0, 1.0):
        np.testing.assert_array_equal(fmt.roundtrip(np.full((8, 12, 8), v, np.float32)), v)
    s = smooth_sines(37, 22)
    back = fmt.roundtrip(s)
    assert back.shape == s.shape and back.dtype == np.float32
    err = np.abs(back - s).mean()
    assert err < {"bc7": 4.0, "bc3": 6.5, "bc1": 7.5, "bc4": 2.0}[name] / 255, err
    assert err > 0  # it is lossy: the codec really ran


def test_bc7_beats_bc1_and_square_roots_help_low_horizons():
    s = smooth_sines()
    e = {n: np.abs(hz_storage.get(n).roundtrip(s) - s) for n in ("bc7", "bc1", "u8", "u8-sqrt", "bc7-sqrt")}
    assert e["bc7"].mean() < e["bc1"].mean()
    low = s < 0.05
    assert low.mean() > 0.01
    # relative error of low horizons: sqrt encoding gives them more of the 8-bit steps
    rel = {n: (e[n][low] / np.maximum(s[low], 1e-3)).mean() for n in e}
    assert rel["u8-sqrt"] < rel["u8"] and rel["bc7-sqrt"] < rel["bc7"]


def test_approximation_reads_the_stored_map(variant):
    """The horizon technique samples the decoded textures: storage_bytes follows the format, and a
    BC7 map shadows almost exactly where the float map does."""
    from hzval.materials.bricks import bricks

    h = bricks(64)
    sc = make_scene(h.shape, 0.1, "wrap", effects=("shadow", "diffuse"), spp=4)
    bk = bake.bake(h, bake.BakeParams(depth=0.1))
    F = {n: horizon.Horizon(sc, bk, storage=n) for n in ("float", "bc7", "bc1")}
    f = {n: a.render(30.0).layers["factor"] for n, a in F.items()}
    assert (
        F["bc7"].storage_bytes()
        == hz_storage.get("bc7").bytes(64, 64, 8)
        < F["float"].storage_bytes() // 4 + 1
    )
    assert 0 < np.abs(f["bc7"] - f["float"]).mean() < 0.02
    assert F["bc7"].parameters["storage"] == "bc7"
    with pytest.raises(Exception, match="storage"):
        horizon.Horizon(sc, bk, storage="dxt9")
