"""Fabric: a plain weave of round threads, warp over weft over warp.

Warp threads run down the image (along y), weft threads across; warp ``i``
passes over weft ``j`` where ``i + j`` is even and under it elsewhere, its
centre line a cosine between the two levels, so each thread undulates over
and under its neighbours (an even count of threads per period keeps the
pattern periodic). A thread's cross-section is round (a half ellipse: at
the default depth it stands about a fifth as tall as it is wide), and a faint
twist of its fibres rides on it. A regular grid of small saddles: shadows
repeat with the weave and flip between warp and weft as the light turns.
"""

from __future__ import annotations

import numpy as np

from hzval.materials import Material
from hzval.materials.noise import count, finish, periodic_noise, shape_of, tint

MIN_SIZE = 8
_ACROSS = 12  # threads per period across (even)
_MIN_PX = 6  # narrowest thread pitch, texels
_HALF_WIDTH = 0.42  # thread half-width, in pitches
_SWING = 0.22  # over/under swing of a thread's centre line
_RADIUS = 0.25  # thread height above its centre line
_WARP_SRGB = (0.20, 0.26, 0.48)
_WEFT_SRGB = (0.80, 0.64, 0.30)


def fabric(size=512, *, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Height ``(rows, cols)`` in [0, 1] and linear albedo ``(rows, cols, 3)``, exactly periodic."""
    rows, cols = shape_of(size, "fabric", MIN_SIZE)
    rng = np.random.default_rng(seed)
    n = count(cols, _ACROSS, _MIN_PX, even=True)
    m = count(rows, max(2, round(n * rows / cols)), _MIN_PX, even=True)
    fuzz = periodic_noise(rng, (rows, cols), (0.8,), (1.0,))
    t = ((np.arange(cols) + 0.5) / (cols / n) - 0.5)[None, :]  # warp i's centre at t = i
    s = ((np.arange(rows) + 0.5) / (rows / m) - 0.5)[:, None]  # weft j's centre at s = j
    i, j = np.round(t), np.round(s)
    across_warp, across_weft = t - i, s - j
    warp_profile = np.sqrt(np.clip(1.0 - (across_warp / _HALF_WIDTH) ** 2, 0.0, None))
    weft_profile = np.sqrt(np.clip(1.0 - (across_weft / _HALF_WIDTH) ** 2, 0.0, None))
    twist_warp = 0.03 * np.cos(2 * np.pi * (3.0 * s + 1.5 * across_warp))
    twist_weft = 0.03 * np.cos(2 * np.pi * (3.0 * t + 1.5 * across_weft))
    warp = 0.5 + _SWING * np.cos(np.pi * (s - i)) + (_RADIUS + twist_warp) * warp_profile
    weft = 0.5 - _SWING * np.cos(np.pi * (t - j)) + (_RADIUS + twist_weft) * weft_profile
    warp = np.where(warp_profile > 0, warp, 0.0)
    weft = np.where(weft_profile > 0, weft, 0.0)
    height = np.maximum(np.maximum(warp, weft), 0.04) + 0.006 * fuzz
    on_top = (warp >= weft)[..., None]
    albedo = np.where(on_top, tint(_WARP_SRGB), tint(_WEFT_SRGB)) * (0.55 + 0.45 * height)[..., None]
    return finish(height, albedo)


MATERIAL = Material(
    name="fabric",
    label="woven fabric",
    summary="a plain weave of round threads over and under: a regular grid of saddles and holes",
    depth=0.03,
    make=lambda shape, seed: fabric(shape, seed=seed),
    min_size=MIN_SIZE,
)
