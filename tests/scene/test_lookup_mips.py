"""Mip levels quantised to the horizon map's storage (issue 31): a GPU's chain of an RGBA8 texture is
RGBA8."""

import numpy as np
import pytest

from hzval.bake.maps import BakeParams, bake
from hzval.io import storage as hz_storage
from hzval.scene import lookup
from hzval.scene import spec as sc
from hzval.techniques.horizon import Horizon


def test_each_level_is_made_from_the_stored_one_below_and_stored_again():
    rng = np.random.default_rng(1)
    data = rng.uniform(0, 1, (8, 8, 3)).astype(np.float32)
    u8 = hz_storage.get("u8").roundtrip
    chain = lookup.mip_chain(data, stored=slice(0, 2), quantise=u8)
    plain = lookup.mip_chain(data)
    assert [c.shape for c in chain] == [(8, 8, 3), (4, 4, 3), (2, 2, 3), (1, 1, 3)]
    for below, level, _p in zip(chain, chain[1:], plain[1:]):
        quads = below[0::2, 0::2] + below[0::2, 1::2] + below[1::2, 0::2] + below[1::2, 1::2]
        mean = quads[..., :2].astype(np.float64) / 4
        assert np.abs(level[..., :2] - mean).max() <= 0.5 / 255 + 1e-6  # rounded to the nearest 8-bit value
        assert np.array_equal(level[..., :2] * 255, np.rint(level[..., :2] * 255))
        assert np.allclose(level[..., 2], (quads[..., 2] / 4), atol=1e-6)  # other channels stay float
    assert np.array_equal(chain[0], data)  # level 0 as given
    assert np.abs(chain[-1][..., :2] - plain[-1][..., :2]).max() > 0  # and it differs from a float chain


@pytest.mark.parametrize("storage,quantised", [("u8", True), ("float", False)])
def test_the_gpu_paths_horizon_levels_are_the_storages(variant, storage, quantised):
    scene = sc.override(
        sc.Scene(),
        size=16,
        effects="shadow",
        spp=1,
        camera="orthographic",
        view_elevation=90.0,
        resolution=(8, 8),
        filter="trilinear",
    ).validate()
    hm = sc.load_material_height(scene.material)
    baked = bake(hm.height, BakeParams(depth=scene.material.depth).validate())
    ap = Horizon(scene, baked, path="gpu", storage=storage, height=hm.height)
    slot = ap._slots["horizon"]
    for level in ap._texture.levels[1:]:
        h = np.asarray(level.tensor())[..., slot]
        assert np.array_equal(h * 255, np.rint(h * 255)) == quantised
