"""Riveted metal panels: flat plates with seams between them and rows of rivets along their edges.

Panels (2 x 2 per period) bulge very slightly and carry shallow dents; a
narrow flat-bottomed seam with smoothstep walls separates them; rivets,
small half spheres, run along each panel's edges inset from the seam. Mostly flat: the shadows are those of
small isolated domes and of the seams' walls - little for a technique to
get right, and much it can get wrong (light leaking past a rivet).
"""

from __future__ import annotations

import numpy as np

from hzval.materials import Material
from hzval.materials.noise import count, finish, periodic_noise, shape_of, smoothstep, tint

MIN_SIZE = 8
_ACROSS = 2  # panels per period across
_MIN_PX = 16  # narrowest panel, texels
_RIVETS = 8  # rivet spacings per panel edge: 9 rivets on it, 32 per panel (corners shared)
_SEAM = 0.2  # seam floor
_PLATE = 0.45  # plate level
_RIVET_HEIGHT = 0.25  # above the plate
_METAL_SRGB = (0.58, 0.59, 0.61)
_RIVET_SRGB = (0.46, 0.45, 0.43)
_SEAM_SRGB = (0.18, 0.18, 0.19)


def _rivet_distance(lx, ly, w, h, inset, step_x, step_y):
    """Distance (texels) from panel-local ``(lx, ly)`` to the nearest rivet on the inset rectangle."""
    best = np.full(np.broadcast(lx, ly).shape, np.inf)
    for fixed, along, length, step, horizontal in (
        (inset, lx, w, step_x, True),
        (h - inset, lx, w, step_x, True),
        (inset, ly, h, step_y, False),
        (w - inset, ly, h, step_y, False),
    ):
        k = np.clip(np.round((along - inset) / step), 0, round((length - 2 * inset) / step))
        nearest = inset + k * step
        d = np.hypot(lx - nearest, ly - fixed) if horizontal else np.hypot(lx - fixed, ly - nearest)
        best = np.minimum(best, d)
    return best


def panels(size=512, *, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Height ``(rows, cols)`` in [0, 1] and linear albedo ``(rows, cols, 3)``, exactly periodic."""
    rows, cols = shape_of(size, "panels", MIN_SIZE)
    rng = np.random.default_rng(seed)
    gx, gy = count(cols, _ACROSS, _MIN_PX), count(rows, _ACROSS, _MIN_PX)
    pw, ph = cols / gx, rows / gy
    side = min(pw, ph)
    n = gx * gy
    level = (_PLATE + 0.03 * rng.uniform(-1, 1, n)).astype(np.float32)
    shade = (0.08 * rng.uniform(-1, 1, n)).astype(np.float32)
    dents = periodic_noise(rng, (rows, cols), (0.08 * side,), (1.0,))
    streaks = periodic_noise(rng, (rows, cols), (1.0,), (1.0,), stretch=12.0)
    y = (np.arange(rows) + 0.5)[:, None]
    x = (np.arange(cols) + 0.5)[None, :]
    py, px = np.floor(y / ph), np.floor(x / pw)
    ly, lx = y - py * ph, x - px * pw  # texels within the panel
    ids = ((py % gy) * gx + px % gx).astype(np.int64)
    border = np.minimum(np.minimum(lx, pw - lx), np.minimum(ly, ph - ly))
    half_seam, bevel = max(1.0, 0.012 * side), max(1.0, 0.02 * side)
    plate = smoothstep(half_seam, half_seam + bevel, border)
    bulge = 0.04 * np.sin(np.pi * lx / pw) * np.sin(np.pi * ly / ph)
    surface = level[ids] + bulge + 0.008 * dents
    inset = 0.06 * side
    d = _rivet_distance(lx, ly, pw, ph, inset, (pw - 2 * inset) / _RIVETS, (ph - 2 * inset) / _RIVETS)
    r = max(1.0, 0.018 * side)
    rivet = _RIVET_HEIGHT * np.sqrt(np.clip(1.0 - (d / r) ** 2, 0.0, None))
    height = _SEAM + plate * (surface - _SEAM) + rivet
    metal = tint(_METAL_SRGB, shade[ids] + 0.04 * streaks)
    albedo = np.where((rivet > 0)[..., None], tint(_RIVET_SRGB), metal)
    albedo = albedo * plate[..., None] + tint(_SEAM_SRGB) * (1.0 - plate[..., None])
    return finish(height, albedo)


MATERIAL = Material(
    name="panels",
    label="riveted metal panels",
    summary="flat plates, narrow seams and rows of small rivet domes: small isolated occluders",
    depth=0.02,
    make=lambda shape, seed: panels(shape, seed=seed),
    min_size=MIN_SIZE,
)
