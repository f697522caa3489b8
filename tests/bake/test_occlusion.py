"""The bent normal and the self-shadowed bump map from the horizon map, against integrals evaluated
independently by dense quadrature over the open directions (hzval.bake.occlusion)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hzval.bake import maps as bake
from hzval.bake import occlusion
from hzval.core import conventions as cv
from hzval.core.errors import InputError
from hzval.materials import generate
from tests.helpers import dense_bent_normal, hemisphere_directions


def _dense_ssbump(s: np.ndarray, n: np.ndarray) -> np.ndarray:
    t, dirs = hemisphere_directions(len(s))
    out = []
    for b in occlusion.HL2_BASIS:
        seen = whole = 0.0
        for (w, dw), sk in zip(dirs, s):
            weight = np.maximum(w @ b, 0.0) * dw
            whole += weight.sum()
            seen += weight[t > math.asin(min(max(sk, 0.0), 1.0))].sum()
        out.append(max(float(n @ b), 0.0) * seen / whole)
    return np.array(out)


@pytest.mark.parametrize("D", [8, 16])
def test_bent_normal_is_the_cosine_weighted_mean_open_direction(D):
    rng = np.random.default_rng(D)
    sines = rng.uniform(0.0, 0.95, size=(5, 1, D)).astype(np.float32)
    got = occlusion.bent_normal(sines)
    for i in range(5):
        np.testing.assert_allclose(got[i, 0], dense_bent_normal(sines[i, 0]), atol=2e-3)


def test_an_open_texel_bends_nothing_and_a_wall_bends_away_from_it():
    assert np.allclose(occlusion.bent_normal(np.zeros((1, 1, 8)))[0, 0], [0, 0, 1])
    wall = np.zeros((1, 1, 8))
    wall[..., 2] = 0.9  # channel 2 looks toward +y (90 degrees)
    b = occlusion.bent_normal(wall)[0, 0]
    assert b[1] < -0.05 and abs(b[0]) < 1e-6


@pytest.mark.parametrize("seed", [0, 1])
def test_ssbump_is_the_facing_times_the_open_share_about_each_basis_vector(seed):
    rng = np.random.default_rng(seed)
    D = 8
    sines = rng.uniform(0.0, 0.9, size=(4, 1, D)).astype(np.float32)
    n = rng.normal(size=(4, 1, 3)) * [0.3, 0.3, 0.0] + [0, 0, 1]
    n = (n / np.linalg.norm(n, axis=-1, keepdims=True)).astype(np.float32)
    got = occlusion.self_shadowed_bump(sines, n)
    for i in range(4):
        np.testing.assert_allclose(got[i, 0], _dense_ssbump(sines[i, 0], n[i, 0]), atol=2e-3)


def test_ssbump_of_an_open_flat_texel_is_one_over_root_three_and_a_closed_one_zero():
    flat = np.array([[[0.0, 0.0, 1.0]]], np.float32)
    assert np.allclose(occlusion.self_shadowed_bump(np.zeros((1, 1, 8)), flat), 1 / math.sqrt(3), atol=1e-6)
    assert np.allclose(occlusion.self_shadowed_bump(np.ones((1, 1, 8)), flat), 0.0, atol=1e-6)


def test_the_basis_is_orthonormal_and_mirrors_onto_itself_in_y():
    B = occlusion.HL2_BASIS
    np.testing.assert_allclose(B @ B.T, np.eye(3), atol=1e-12)
    mirrored = B * [1, -1, 1]
    np.testing.assert_allclose(mirrored[[0, 2, 1]], B, atol=1e-12)


def test_the_channels_made_side_by_side_are_the_channels_made_in_turn():
    """The bake makes ssbump's three channels on the host pool, beside the bent normals: each channel
    is the same float32 operations either way, so the maps agree bit for bit (and the bake's, which
    makes both at once, with them)."""
    from concurrent.futures import ThreadPoolExecutor

    rng = np.random.default_rng(3)
    sines = rng.uniform(-0.2, 1.0, size=(37, 23, 8)).astype(np.float32)
    n = rng.normal(size=(37, 23, 3)) * [0.4, 0.4, 0.0] + [0, 0, 1]
    n = (n / np.linalg.norm(n, axis=-1, keepdims=True)).astype(np.float32)
    alone = occlusion.self_shadowed_bump(sines, n)
    with ThreadPoolExecutor(3) as pool:
        assert np.array_equal(
            occlusion.self_shadowed_bump(sines, n, pool=pool).view(np.uint32), alone.view(np.uint32)
        )
    h = generate("bricks", 32, seed=2).height
    baked = bake.bake(h, bake.BakeParams(depth=0.1, ssbump_lift=0.0))
    assert np.array_equal(baked.ssbump, occlusion.self_shadowed_bump(baked.horizon, baked.normal))
    assert np.array_equal(baked.bent_normal, occlusion.bent_normal(baked.horizon))


# --------------------------------------------------------------------------
# Valve's ray lift (height2ssbump's surf_pnt.z += 0.55)
# --------------------------------------------------------------------------


def test_a_rise_under_the_lift_does_not_occlude_and_one_over_it_does(variant):
    """A single step of 0.5 texel next to flat ground: lifted by 0.55 texel the ground sees an
    open sky (Valve's flat ssbump value 1/sqrt(3) in every channel); a 0.6-texel step still
    occludes toward it."""
    for step, occluded in ((0.5, False), (0.6, True)):
        h = np.zeros((32, 32), np.float32)
        h[:, 20:24] = step  # texels, as heights_in_texels gives them
        depth = 1.0 / 32  # H = 1 is 1 texel high at 32 columns
        height = h  # normalised heights: one unit a texel at this depth
        baked = bake.bake(height, bake.BakeParams(depth=depth, boundary="open", ssbump_lift=0.55))
        ground = baked.ssbump[16, 18]  # two texels west of the step, facing it along +x
        assert np.allclose(cv.heights_in_texels(height, depth), h)
        if occluded:
            assert ground[0] < 1 / np.sqrt(3) - 1e-3
        else:
            assert np.allclose(ground, 1 / np.sqrt(3), atol=1e-6)


def test_the_lifted_horizons_are_lower_and_both_kernels_agree(variant):
    from hzval.bake import horizon as bake_horizon

    h = generate("gravel", 48, seed=4).height * 6.0
    plain = bake_horizon.horizon_map(h, 8, 32, "wrap")[0]
    unrolled = bake_horizon.horizon_map(h, 8, 32, "wrap", kernel="unrolled", lift=0.55)[0]
    loop = bake_horizon.horizon_map(h, 8, 32, "wrap", kernel="loop", lift=0.55)[0]
    assert np.array_equal(unrolled.view(np.uint32), loop.view(np.uint32))
    assert (unrolled <= plain).all() and (unrolled < plain).any()
    assert np.array_equal(bake_horizon.horizon_map(h, 8, 32, "wrap", lift=0.0)[0], plain)


def test_a_bake_record_without_the_lift_is_an_unlifted_bake():
    assert bake.BakeParams.normalise_record({"depth": 0.05})["ssbump_lift"] == 0.0
    with pytest.raises(InputError, match="--ssbump-lift"):
        bake.BakeParams(ssbump_lift=-0.1).validate()
