"""Gravel: small pebbles, densely packed and overlapping.

One pebble per cell of a jittered grid (about 14 across), each a half
ellipsoid of its own size, elongation and orientation; where pebbles overlap
the higher one shows (the maximum over the 3 x 3 neighbouring cells, which
holds every pebble that can reach a texel since no radius exceeds a cell).
Many small occluders with near-vertical rims: shadows are short, numerous
and fragmented.
"""

from __future__ import annotations

import numpy as np

from hzval.materials import Material
from hzval.materials.noise import finish, grid, periodic_noise, shape_of, tint

MIN_SIZE = 8
_ACROSS = 14  # pebbles per period across
_MIN_PX = 6  # smallest cell, texels
_BASE = 0.05  # the grit between pebbles
_PEBBLES_SRGB = (
    (0.70, 0.66, 0.58),
    (0.52, 0.50, 0.48),
    (0.60, 0.48, 0.36),
    (0.34, 0.33, 0.32),
    (0.78, 0.76, 0.72),
)
_GRIT_SRGB = (0.30, 0.27, 0.23)


def gravel(size=512, *, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Height ``(rows, cols)`` in [0, 1] and linear albedo ``(rows, cols, 3)``, exactly periodic."""
    rows, cols = shape_of(size, "gravel", MIN_SIZE)
    rng = np.random.default_rng(seed)
    gy, gx = grid((rows, cols), _ACROSS, _MIN_PX)
    cw, ch = cols / gx, rows / gy
    n = gx * gy
    centre = 0.15 + 0.7 * rng.random((n, 2))  # (y, x) within the cell
    radius = min(cw, ch) * (0.5 + 0.35 * rng.random(n))  # semi-major axis, texels
    aspect = 0.55 + 0.45 * rng.random(n)
    angle = np.pi * rng.random(n)
    top = (0.45 + 0.5 * rng.random(n)) * radius / radius.max()  # small pebbles sit lower
    kind = rng.integers(0, len(_PEBBLES_SRGB), n)
    shade = 0.15 * rng.uniform(-1, 1, n)
    grit = periodic_noise(rng, (rows, cols), (1.0,), (1.0,))
    y = ((np.arange(rows) + 0.5) / ch)[:, None]
    x = ((np.arange(cols) + 0.5) / cw)[None, :]
    cy, cx = np.floor(y).astype(np.int64), np.floor(x).astype(np.int64)
    height = np.full((rows, cols), -1.0)
    owner = np.zeros((rows, cols), np.int64)
    for oy in (-1, 0, 1):
        for ox in (-1, 0, 1):
            ny, nx = cy + oy, cx + ox
            i = (ny % gy) * gx + nx % gx
            dy = (y - ny - centre[i, 0]) * ch
            dx = (x - nx - centre[i, 1]) * cw
            ca, sa = np.cos(angle[i]), np.sin(angle[i])
            u, v = (dx * ca + dy * sa) / radius[i], (-dx * sa + dy * ca) / (radius[i] * aspect[i])
            h = top[i] * np.sqrt(np.clip(1.0 - u * u - v * v, 0.0, None)) - (u * u + v * v >= 1.0)
            higher = h > height
            height, owner = np.where(higher, h, height), np.where(higher, i, owner)
    covered = height > 0
    height = np.where(covered, _BASE + (1.0 - _BASE) * height, _BASE + 0.02 * grit)
    palette = np.stack([tint(s) for s in _PEBBLES_SRGB])
    rgb = palette[kind][owner] * (1.0 + shade[owner])[..., None]
    albedo = np.where(covered[..., None], rgb, tint(_GRIT_SRGB, 0.2 * grit))
    return finish(height, albedo)


MATERIAL = Material(
    name="gravel",
    label="gravel",
    summary="small overlapping pebbles: many short fragmented shadows under near-vertical rims",
    depth=0.03,
    make=lambda shape, seed: gravel(shape, seed=seed),
    min_size=MIN_SIZE,
)
