"""Spikes: a field of thin, tall cones on a low ground - a hard case.

One cone per cell of a jittered grid (about 12 across), its radius 14% of a
cell (6 texels at 512) and its height up to the full range: at the default
depth a spike is up to five times as tall as it is wide (60 texels over a
12-texel base at 512), and at a 30-degree light its shadow runs about 100
texels, far beyond the horizon bake's default radius of 16. Jittered within
the middle 60% of their cells, cone centres are at least 0.4 cells apart,
so no two cones overlap while the radius (at least 1.5 texels) stays below
0.2 cells, i.e. from 7.5-texel cells (90 texels across) up; each texel then
belongs to its nearest cell's cone.
"""

from __future__ import annotations

import numpy as np

from hzval.materials import Material
from hzval.materials.noise import cells, finish, grid, periodic_noise, shape_of, tint

MIN_SIZE = 8
_ACROSS = 12
_MIN_PX = 6
_RADIUS = 0.14  # cone radius, fraction of a cell
_GROUND = 0.03
_GROUND_SRGB = (0.24, 0.20, 0.16)
_SPIKE_SRGB = (0.82, 0.80, 0.72)


def spikes(size=512, *, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Height ``(rows, cols)`` in [0, 1] and linear albedo ``(rows, cols, 3)``, exactly periodic."""
    rows, cols = shape_of(size, "spikes", MIN_SIZE)
    rng = np.random.default_rng(seed)
    gy, gx = grid((rows, cols), _ACROSS, _MIN_PX)
    c = cells(rng, (rows, cols), (gy, gx), jitter=0.6)
    top = (0.6 + 0.4 * rng.random(gx * gy)).astype(np.float32)
    ground = periodic_noise(rng, (rows, cols), (2.0,), (1.0,))
    r = max(1.5, _RADIUS * min(c.cell_w, c.cell_h))
    cone = np.clip(1.0 - c.dist / r, 0.0, None) ** 1.3
    height = _GROUND + 0.01 * ground + cone * (top[c.index] - _GROUND)
    m = np.clip(cone * 3.0, 0.0, 1.0)[..., None]
    albedo = (
        tint(_GROUND_SRGB, 0.15 * ground) * (1.0 - m) + tint(_SPIKE_SRGB) * (0.6 + 0.4 * cone[..., None]) * m
    )
    return finish(height, albedo)


MATERIAL = Material(
    name="spikes",
    label="spike field",
    summary="thin cones up to five times as tall as wide: shadows far beyond the bake radius (a hard case)",
    depth=0.12,
    make=lambda shape, seed: spikes(shape, seed=seed),
    min_size=MIN_SIZE,
)
