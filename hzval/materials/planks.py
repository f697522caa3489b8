"""Wood planks: boards in rows with V grooves between them, grain along their length.

Rows of boards (6 per period) run across the image, 2 boards per row with
staggered butt joints; a V groove separates rows and a narrower one the
boards' ends. Each board has its own height, a slight crown across its
width, and a grain of fine ridges along it (noise stretched 20:1 along x).
Long straight grooves, like the bricks' joints, but V-shaped: a horizon map
sees the same wall in every direction along them.
"""

from __future__ import annotations

import numpy as np

from hzval.materials import Material
from hzval.materials.noise import count, finish, periodic_noise, shape_of, tint

MIN_SIZE = 8
_ROWS = 6  # rows of boards per period
_MIN_ROW_PX = 8
_BOARDS = 2  # boards per row
_MIN_BOARD_PX = 16
_GROOVE = 0.15  # groove floor
_BOARD = 0.75  # board level
_WOOD_SRGB = (0.58, 0.40, 0.24)
_GROOVE_SRGB = (0.16, 0.11, 0.07)


def planks(size=512, *, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Height ``(rows, cols)`` in [0, 1] and linear albedo ``(rows, cols, 3)``, exactly periodic."""
    rows, cols = shape_of(size, "planks", MIN_SIZE)
    rng = np.random.default_rng(seed)
    nr, nb = count(rows, _ROWS, _MIN_ROW_PX), count(cols, _BOARDS, _MIN_BOARD_PX)
    bh, bl = rows / nr, cols / nb
    offset = rng.random(nr) * bl
    level = (_BOARD + 0.05 * rng.uniform(-1, 1, nr * nb)).astype(np.float32)
    shade = (0.15 * rng.uniform(-1, 1, nr * nb)).astype(np.float32)
    grain = periodic_noise(rng, (rows, cols), (1.2, 0.5), (1.0, 0.4), stretch=20.0)
    figure = periodic_noise(rng, (rows, cols), (0.25 * bh,), (1.0,), stretch=4.0)
    y = (np.arange(rows) + 0.5)[:, None]
    x = (np.arange(cols) + 0.5)[None, :]
    row = np.floor(y / bh).astype(np.int64)
    fv = y / bh - row
    along = (x + offset[row % nr]) / bl
    board = np.floor(along).astype(np.int64)
    fu = along - board
    ids = (row % nr) * nb + board % nb
    across_groove = np.clip(np.minimum(fv, 1.0 - fv) * bh / max(1.5, 0.06 * bh), 0.0, 1.0)
    end_groove = np.clip(np.minimum(fu, 1.0 - fu) * bl / max(1.0, 0.03 * bh), 0.0, 1.0)
    profile = np.minimum(across_groove, end_groove)  # V: linear walls
    rings = 0.012 * np.sin(2 * np.pi * (fv * bh / max(3.0, 0.08 * bh) + 1.5 * figure))
    surface = level[ids] - 0.04 * (2.0 * fv - 1.0) ** 2 + 0.012 * grain + rings
    height = _GROOVE + profile * (surface - _GROOVE)
    wood = tint(_WOOD_SRGB, shade[ids] + 0.12 * grain + 4.0 * rings)
    m = profile[..., None]
    albedo = wood * m + tint(_GROOVE_SRGB) * (1.0 - m)
    return finish(height, albedo)


MATERIAL = Material(
    name="planks",
    label="wood planks",
    summary="boards with V grooves and staggered ends, grain along them: long straight grooves",
    depth=0.03,
    make=lambda shape, seed: planks(shape, seed=seed),
    min_size=MIN_SIZE,
)
