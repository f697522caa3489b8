"""Cobblestones: rounded domes of stone set in sand.

Each stone is a cell of a periodic Voronoi diagram (:func:`hzval.materials.noise.cells`,
about 7 across); its height rises from the sand in the joint as a quarter
circle of the distance to the cell's edge, so a stone is a smooth dome with
no steps: shadows here are soft-edged and short, falling on the sand and on
the next stone's flank - the case horizon mapping was made for.
"""

from __future__ import annotations

import numpy as np

from hzval.materials import Material
from hzval.materials.noise import cells, finish, grid, periodic_noise, shape_of, smoothstep, tint

MIN_SIZE = 8
_ACROSS = 7  # stones per period across
_MIN_PX = 10  # narrowest stone, texels
_SAND = 0.12  # sand level
_GAP = 0.05  # half-width of the joint, fraction of a stone
_STONES_SRGB = ((0.55, 0.53, 0.50), (0.47, 0.45, 0.44), (0.60, 0.55, 0.47), (0.40, 0.40, 0.42))
_SAND_SRGB = (0.66, 0.58, 0.44)


def cobblestones(size=512, *, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Height ``(rows, cols)`` in [0, 1] and linear albedo ``(rows, cols, 3)``, exactly periodic."""
    rows, cols = shape_of(size, "cobblestones", MIN_SIZE)
    rng = np.random.default_rng(seed)
    gy, gx = grid((rows, cols), _ACROSS, _MIN_PX)
    c = cells(rng, (rows, cols), (gy, gx), jitter=0.7)
    stone = min(c.cell_w, c.cell_h)
    n = gx * gy
    top = (0.72 + 0.22 * rng.random(n)).astype(np.float32)
    bevel = (stone * (0.32 + 0.16 * rng.random(n))).astype(np.float32)
    shade = (0.15 * rng.uniform(-1, 1, n)).astype(np.float32)
    kind = rng.integers(0, len(_STONES_SRGB), n)
    bumps = periodic_noise(rng, (rows, cols), (0.12 * stone, 0.04 * stone), (1.0, 0.3))
    sand_noise = periodic_noise(rng, (rows, cols), (0.03 * stone + 0.5,), (1.0,))
    grain = periodic_noise(rng, (rows, cols), (0.6,), (1.0,))
    # a quarter circle of the inset distance: vertical where it meets the sand, flat on top
    t = np.clip((c.edge - _GAP * stone) / bevel[c.index], 0.0, 1.0)
    dome = np.sqrt(1.0 - (1.0 - t) ** 2)
    sand = _SAND + 0.015 * sand_noise
    height = sand + dome * (top[c.index] + 0.025 * bumps - sand) + 0.004 * grain
    palette = np.stack([tint(s) for s in _STONES_SRGB])
    stone_rgb = palette[kind][c.index] * (1.0 + shade[c.index] + 0.05 * bumps)[..., None]
    m = smoothstep(0.0, 0.25, t)[..., None]
    albedo = tint(_SAND_SRGB, 0.08 * sand_noise) * (1.0 - m) + stone_rgb * m
    return finish(height, albedo)


MATERIAL = Material(
    name="cobblestones",
    label="cobblestones",
    summary="rounded stone domes in sand: smooth curved relief, short soft-edged shadows",
    depth=0.04,
    make=lambda shape, seed: cobblestones(shape, seed=seed),
    min_size=MIN_SIZE,
)
