"""The palette PNGs of hzval.report.images: a FLIP map and a visibility difference decode to exactly
the RGB image the colour code paints."""

from __future__ import annotations

import numpy as np
import pytest

from hzval.io import codecs
from hzval.report import images
from tests.helpers import magma_as_before, png_mode_and_rgb, visdiff_as_before

RNG = np.random.default_rng(7)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_the_flip_palette_png_decodes_to_the_rgb_map(tmp_path, dtype):
    edges = np.concatenate([np.arange(257) / 256, np.nextafter(np.arange(257) / 256, 0), [-1, 2, np.inf]])
    error = np.concatenate([edges, RNG.random(64 * 64 - edges.size)]).astype(dtype).reshape(64, 64)
    expected = magma_as_before(error)
    assert np.array_equal(images.flip_image(error), expected)
    codecs.write_png(tmp_path / "flip.png", images.flip_indexed(error))
    mode, back = png_mode_and_rgb(tmp_path / "flip.png")
    assert mode == "P" and np.array_equal(back, expected)


def test_a_flip_map_with_nan_is_rgb_with_nan_black_as_before(tmp_path):
    error = RNG.random((8, 8)).astype(np.float32)
    error[2, 3] = np.nan
    made = images.flip_indexed(error)
    assert isinstance(made, np.ndarray) and np.array_equal(made, magma_as_before(error))
    assert made[2, 3].tolist() == [0, 0, 0]


@pytest.mark.parametrize("levels", [4, None])  # V = k/4 as spp 4 gives it; any value in [0, 1]
def test_the_visibility_difference_palette_png_decodes_to_the_rgb_map(tmp_path, levels):
    V = RNG.random((40, 50))
    V = (np.round(V * levels) / levels if levels else V).astype(np.float32)
    F = np.clip(V + RNG.normal(0, 0.3, V.shape), 0, 1).astype(np.float32)
    expected = visdiff_as_before(V, F)
    assert {tuple(images.LEAK_RGB), tuple(images.FALSE_SHADOW_RGB)} <= {
        tuple(p) for p in expected.reshape(-1, 3)
    }
    assert np.array_equal(images.visibility_diff_image(V, F), expected)
    made = images.visibility_diff_indexed(V, F)
    assert isinstance(made, codecs.Indexed) and len(made.palette) <= (levels or 128) + 3
    codecs.write_png(tmp_path / "vd.png", made)
    mode, back = png_mode_and_rgb(tmp_path / "vd.png")
    assert mode == "P" and np.array_equal(back, expected)


def test_one_truth_half_serves_every_factor_of_a_frame():
    """A frame's :class:`images.VisibilityDiff`, made once, paints each technique's map as a map made
    for that technique alone: the same pixels, and only the grey levels left unpainted in its palette
    (a level every pixel of which is a leak drops out)."""
    V = (np.round(RNG.random((30, 40)) * 4) / 4).astype(np.float32)
    V[:, :10] = 0.125  # a level no other pixel has, shadowed by the truth ...
    truth = images.VisibilityDiff(V)
    for spread in (0.0, 0.2, 0.6):
        F = np.clip(V + RNG.normal(0, spread, V.shape), 0, 1).astype(np.float32)
        F[:, :10] = 1.0  # ... and wholly lit by the technique: all leaks
        made = truth.indexed(F)
        expected = visdiff_as_before(V, F)
        assert np.array_equal(made.rgb(), expected)
        grey_levels = {int(p[0]) for p in made.palette[:-2]}
        assert grey_levels == {
            int(g) for g in np.unique(expected[(expected == expected[..., :1]).all(-1)][:, 0])
        }
        assert 80 not in grey_levels  # unit_to_u8(0.25 + 0.5 * 0.125)
        assert np.array_equal(truth.image(F), expected)


@pytest.mark.parametrize("dtype", [np.float16, np.float32, np.float64])
def test_magma_index_is_matplotlibs_floor_of_256_x_with_nan_as_zero(dtype):
    big = np.finfo(dtype).max  # beyond max / 256: 256 x is infinite, and no overflow to report
    values = np.array(
        [np.nan, -np.inf, -big, -1.0, -0.0, 0.0, 1 / 256, 0.5, 255 / 256, 1.0, big, np.inf], dtype
    )
    with np.errstate(all="raise"):
        index = images.magma_index(values)
    assert index.dtype == np.uint8
    assert index.tolist() == [0, 0, 0, 0, 0, 0, 1, 128, 255, 255, 255, 255]
    assert images.magma_index(np.finfo(dtype).max).tolist() == 255  # a scalar too
    assert images.magma_index(dtype(0.25)).tolist() == 64
