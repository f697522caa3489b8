"""The built-in brick material: deterministic, in range, seamless, with mortar."""

from __future__ import annotations

import numpy as np
import pytest

from hzval.materials.bricks import DEFAULT_DEPTH, DEFAULT_SIZE, bricks

SHAPES = [(32, 32), (64, 64), (128, 128), (96, 160), (128, 48)]


def _wrap_and_interior_jumps(h: np.ndarray) -> tuple[float, np.ndarray]:
    """Largest jump across the wrap edges, and all interior neighbour jumps."""
    wrap = max(np.abs(h[-1, :] - h[0, :]).max(), np.abs(h[:, -1] - h[:, 0]).max())
    interior = np.concatenate([np.abs(np.diff(h, axis=0)).ravel(), np.abs(np.diff(h, axis=1)).ravel()])
    return float(wrap), interior


def test_defaults():
    assert DEFAULT_SIZE == 512
    assert DEFAULT_DEPTH == pytest.approx(0.05)


def test_deterministic():
    a = bricks(64, seed=3)
    b = bricks(64, seed=3)
    np.testing.assert_array_equal(a, b)
    c = bricks(64, seed=4)
    assert not np.array_equal(a, c)
    assert np.abs(a - c).mean() > 0.01


@pytest.mark.parametrize("shape", SHAPES)
def test_dtype_shape_range(shape):
    h = bricks(shape, seed=1)
    assert h.dtype == np.float32
    assert h.shape == shape
    assert np.isfinite(h).all()
    assert h.min() >= 0.0 and h.max() <= 1.0
    assert h.min() <= 0.2 and h.max() >= 0.8


def test_int_size_is_square():
    assert bricks(48).shape == (48, 48)


@pytest.mark.parametrize("shape", [(8, 8), (9, 13), (8, 200), (200, 8)])
def test_tiny_and_extreme_sizes(shape):
    h = bricks(shape)
    assert h.shape == shape and np.isfinite(h).all()
    assert 0.0 <= h.min() and h.max() <= 1.0


def test_rejects_bad_arguments():
    with pytest.raises(ValueError):
        bricks(7)
    with pytest.raises(ValueError):
        bricks((64, 4))
    with pytest.raises(ValueError):
        bricks(64, bricks_across=0)


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_tiles_without_seam(shape, seed):
    h = bricks(shape, seed=seed)
    wrap, interior = _wrap_and_interior_jumps(h)
    assert wrap <= np.percentile(interior, 99.9)


def test_seam_test_detects_a_seam():
    # The same statistic on a map that does not tile (a brick wall with a
    # shifted half glued on) must fail, or the test above proves nothing.
    h = bricks(128, seed=1)
    broken = np.concatenate([h[:, :64], np.roll(h, 37, axis=0)[:, 64:]], axis=1)
    broken = np.roll(broken, -64, axis=1)  # move the glued edge onto the wrap
    wrap, interior = _wrap_and_interior_jumps(broken)
    assert wrap > np.percentile(interior, 99.9)


@pytest.mark.parametrize("shape", [(64, 64), (128, 128), (96, 160)])
def test_has_mortar(shape):
    h = bricks(shape, seed=1)
    well_below = np.mean(h < np.median(h) - 0.5)
    assert 0.02 <= well_below <= 0.20


def test_bricks_stand_proud():
    # Mortar near 0.1-0.2, brick faces near 0.7-1.0.
    h = bricks(128, seed=1)
    assert 0.05 <= np.percentile(h, 2) <= 0.25
    assert 0.7 <= np.median(h) <= 0.95
