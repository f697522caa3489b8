"""Ridges: a ridged multifractal terrain with nothing outside it (``open``).

Musgrave's ridged multifractal (Ebert et al., *Texturing and Modeling*, 3rd
ed., ch. 16): each octave is ``(1 - a|n|)^2`` of a band-limited noise ``n``
(sharp crests where ``n`` crosses 0), weighted by the octave above it so
that detail gathers on the ridges, amplitudes halving per octave; a broad
swell lifts some massifs and sinks others. The
noise is periodic, but a terrain ends at its border: the material's
boundary is ``open``. The albedo follows height and slope: vegetation low,
rock on steep flanks, snow on high gentle ground.
"""

from __future__ import annotations

import numpy as np

from hzval.core import conventions as cv
from hzval.materials import Material
from hzval.materials.noise import finish, periodic_noise, shape_of, smoothstep, tint

MIN_SIZE = 8
DEPTH = 0.08
_OCTAVES = 5
_GAIN = 1.6  # how strongly an octave's ridges gate the next one
_SHARPNESS = 0.5  # |n| that takes a crest down to its valley floor, inverted
_GRASS_SRGB = (0.33, 0.42, 0.22)
_ROCK_SRGB = (0.48, 0.45, 0.41)
_SNOW_SRGB = (0.90, 0.91, 0.93)


def ridges(size=512, *, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Height ``(rows, cols)`` in [0, 1] and linear albedo ``(rows, cols, 3)``."""
    rows, cols = shape_of(size, "ridges", MIN_SIZE)
    rng = np.random.default_rng(seed)
    height = np.zeros((rows, cols), np.float32)
    weight = np.ones((rows, cols), np.float32)
    for o in range(_OCTAVES):
        sigma = max(0.7, cols / 12.0 / 2**o)
        n = periodic_noise(rng, (rows, cols), (sigma,), (1.0,))
        signal = np.clip(1.0 - _SHARPNESS * np.abs(n), 0.0, 1.0) ** 2
        height += 0.5**o * signal * weight
        weight = np.clip(signal * _GAIN, 0.0, 1.0)
    # the massifs: a broad, smooth swell that lifts some ridge systems and sinks others
    height *= 0.8 + 0.2 * np.tanh(periodic_noise(rng, (rows, cols), (cols / 6.0,), (1.0,)))
    lo, hi = float(height.min()), float(height.max())
    height = (height - lo) / (hi - lo if hi > lo else 1.0)
    gy, gx = np.gradient(cv.heights_in_texels(height, DEPTH))  # slope, texel units
    slope = np.hypot(gx, gy)
    rock = smoothstep(0.35, 0.9, slope)[..., None]
    snow = (smoothstep(0.62, 0.75, height) * (1.0 - smoothstep(0.5, 1.2, slope)))[..., None]
    albedo = tint(_GRASS_SRGB) * (1.0 - rock) + tint(_ROCK_SRGB) * rock
    albedo = albedo * (1.0 - snow) + tint(_SNOW_SRGB) * snow
    return finish(height, albedo)


MATERIAL = Material(
    name="ridges",
    label="ridged terrain",
    summary="ridged multifractal mountains, open boundary: sharp crests, long shadows into valleys",
    depth=DEPTH,
    boundary="open",
    make=lambda shape, seed: ridges(shape, seed=seed),
    min_size=MIN_SIZE,
)
