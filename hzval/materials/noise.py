"""Exactly periodic building blocks of the built-in materials: noise, cells, palettes.

Everything here tiles with the map's period ``(rows, cols)`` by construction,
so a material made only of these (and of integer counts of features per
period) has no seam under ``boundary = "wrap"``. Lengths are in texels;
heights are dimensionless fractions of the [0, 1] range.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hzval.core import srgb

__all__ = ["periodic_noise", "smoothstep", "Cells", "cells", "count", "grid", "finish", "tint", "shape_of"]


def shape_of(size, name: str, min_size: int) -> tuple[int, int]:
    """``n`` or ``(rows, cols)`` as ``(rows, cols)``, each at least ``min_size`` (else ValueError)."""
    if np.ndim(size) == 0:
        rows = cols = int(size)
    else:
        rows, cols = (int(s) for s in size)
    if rows < min_size or cols < min_size:
        raise ValueError(f"{name}: size must be at least {min_size}x{min_size} texels, got {rows}x{cols}")
    return rows, cols


def grid(shape: tuple[int, int], across: int, min_px: float) -> tuple[int, int]:
    """Return ``(gy, gx)`` cells per period for ``across`` features across the width.

    As many go down as keep them about square (:func:`count` on each axis).
    """
    rows, cols = shape
    gx = count(cols, across, min_px)
    return count(rows, max(1, round(gx * rows / cols)), min_px), gx


def finish(height: np.ndarray, albedo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return a material's result: height clipped to [0, 1], albedo to [0.02, 0.9], both float32.

    The albedo's range leaves no perfect black or white.
    """
    return np.clip(height, 0.0, 1.0).astype(np.float32), np.clip(albedo, 0.02, 0.9).astype(np.float32)


def count(length: int, wanted: int, min_px: float, *, even: bool = False) -> int:
    """Return the features per period along an axis of ``length`` texels.

    It is ``wanted``, fewer where a feature would be narrower than ``min_px`` texels, at least 1 (2 and even
    with ``even``).
    """
    n = max(1, min(int(wanted), int(length // min_px)))
    if even:
        n = max(2, n - n % 2)
    return n


def periodic_noise(
    rng: np.random.Generator,
    shape: tuple[int, int],
    sigmas: tuple[float, ...],
    weights: tuple[float, ...],
    *,
    stretch: float = 1.0,
) -> np.ndarray:
    """Exactly periodic noise of zero mean and unit variance, float32 ``shape``.

    White Gaussian noise is drawn directly as Fourier coefficients and
    shaped by a sum of Gaussian low-pass kernels of standard deviations
    ``sigmas`` (texels, along y; ``stretch`` times longer along x, for
    grain) with ``weights``; the inverse real FFT of a discrete spectrum is
    periodic with the image. Coefficients where every kernel is below
    ``exp(-8)`` are zero and not drawn, so smooth fields are cheap.
    """
    rows, cols = shape
    # Band limit: |f| <= 4 / (2 pi sigma_min) cycles per texel, per axis.
    f_max_y = 4.0 / (2.0 * np.pi * min(sigmas))
    f_max_x = f_max_y / stretch
    ky = min(rows // 2, int(np.ceil(f_max_y * rows)))
    kx = min(cols // 2, int(np.ceil(f_max_x * cols)))
    iy = np.r_[0 : ky + 1, rows - ky : rows] if 2 * ky + 1 < rows else np.arange(rows)
    fy = np.where(iy <= rows // 2, iy, iy - rows) / rows
    fx = np.arange(kx + 1) / cols
    kernel = np.zeros((fy.size, fx.size))
    for sigma, weight in zip(sigmas, weights):
        c = 2.0 * np.pi**2 * sigma**2  # the Gaussian is separable
        kernel += weight * np.outer(np.exp(-c * fy * fy), np.exp(-c * stretch**2 * fx * fx))
    kernel[0, 0] = 0.0  # zero mean
    white = rng.standard_normal((fy.size, fx.size, 2), dtype=np.float32)
    band = (white[..., 0] + 1j * white[..., 1]) * kernel.astype(np.float32)
    spectrum = np.zeros((rows, cols // 2 + 1), dtype=np.complex64)
    spectrum[iy, : kx + 1] = band
    field = np.fft.irfft2(spectrum, s=shape).astype(np.float32)
    std = field.std()
    return field / std if std > 0 else field


def smoothstep(e0: float, e1: float, x: np.ndarray) -> np.ndarray:
    """Return the smoothstep of ``x`` between the edges ``e0`` and ``e1`` (0 below, 1 above)."""
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


@dataclass(frozen=True)
class Cells:
    """A periodic jittered-grid Voronoi diagram evaluated at every texel centre.

    ``index``: the nearest feature point's cell, ``(rows, cols)`` ints in
    ``[0, gy * gx)``; ``dx``, ``dy``: texel minus that point, in texels (+x
    right, +y down the rows); ``dist``: their length; ``edge``: distance to
    the cell's boundary (the nearest bisector with a neighbour), in texels.
    """

    index: np.ndarray
    dx: np.ndarray
    dy: np.ndarray
    dist: np.ndarray
    edge: np.ndarray
    cell_w: float
    cell_h: float


def cells(
    rng: np.random.Generator, shape: tuple[int, int], counts: tuple[int, int], jitter: float = 0.8
) -> Cells:
    """Return one feature point per cell of a ``counts = (gy, gx)`` grid over the period.

    Each is placed uniformly in the middle ``jitter`` of its cell; distances wrap, so the diagram tiles. The
    edge distance is exact for the 3 x 3 neighbourhood searched (Worley 1996's cellular texture basis, with
    the bisector distance ``(|x - b|^2 - |x - a|^2) / (2 |b - a|)`` of Quilez's Voronoi edges).
    """
    rows, cols = shape
    gy, gx = counts
    cw, ch = cols / gx, rows / gy
    pts = (0.5 - jitter / 2 + jitter * rng.random((gy, gx, 2))).astype(np.float32)  # (y, x) in the cell
    y = ((np.arange(rows) + 0.5) / ch).astype(np.float32)[:, None]  # texel centres in cell units
    x = ((np.arange(cols) + 0.5) / cw).astype(np.float32)[None, :]
    cy, cx = np.floor(y).astype(np.int64), np.floor(x).astype(np.int64)

    def neighbour(oy, ox):
        ny, nx = cy + oy, cx + ox
        p = pts[ny % gy, nx % gx]  # (rows, cols, 2)
        return ((x - (nx + p[..., 1])) * cw, (y - (ny + p[..., 0])) * ch, (ny % gy) * gx + nx % gx)

    offsets = [(oy, ox) for oy in (-1, 0, 1) for ox in (-1, 0, 1)]
    best = np.full((rows, cols), np.inf, np.float32)
    dx1 = np.zeros((rows, cols), np.float32)
    dy1 = np.zeros((rows, cols), np.float32)
    idx = np.zeros((rows, cols), np.int64)
    which = np.zeros((rows, cols), np.int64)  # the nearest point's offset, 0..8
    for k, (oy, ox) in enumerate(offsets):
        dx, dy, i = neighbour(oy, ox)
        d2 = dx * dx + dy * dy
        closer = d2 < best
        best = np.where(closer, d2, best)
        dx1, dy1, idx = np.where(closer, dx, dx1), np.where(closer, dy, dy1), np.where(closer, i, idx)
        which = np.where(closer, k, which)
    edge = np.full((rows, cols), np.inf, np.float32)
    for k, (oy, ox) in enumerate(offsets):
        # every other point bounds the cell, a periodic copy of the nearest one too (1 or 2 cells
        # per period along an axis): skip the nearest point itself by its offset, not by its index
        dx, dy, _ = neighbour(oy, ox)
        bx, by = dx1 - dx, dy1 - dy  # b - a, in texels
        sep = np.sqrt(bx * bx + by * by)
        e = (dx * dx + dy * dy - best) / np.maximum(2.0 * sep, 1e-6)
        edge = np.where(which != k, np.minimum(edge, e), edge)
    return Cells(idx, dx1, dy1, np.sqrt(best), edge.astype(np.float32), cw, ch)


def tint(encoded: tuple[float, float, float], variation: np.ndarray | float = 0.0) -> np.ndarray:
    """Return a linear albedo ``(..., 3)`` float32 from an sRGB colour scaled by ``1 + variation``.

    ``variation`` is per texel or per feature; the result is clipped to [0.02, 0.9] (no perfect black or
    white).
    """
    base = np.asarray(srgb.decode(np.asarray(encoded, np.float64)), np.float32)
    v = np.asarray(variation, np.float32)[..., None]
    return np.clip(base * (1.0 + v), 0.02, 0.9).astype(np.float32)
