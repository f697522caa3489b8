"""How the plane truth holds its samples.

That is which are kept between frames, the bands of whole pixel rows they are traced in, and the samples that
fall on a cell's edge.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from hzval.core.backend import dr, mi  # Dr.Jit loads at first use, once the LLVM is chosen

__all__ = [
    "KEEP_SAMPLES",
    "BAND_SAMPLES",
    "KEPT_BAND_SAMPLES",
    "bands",
    "keeps_samples",
    "band_ranges",
    "Samples",
    "off_edge_lines",
]

#: Up to this many samples (2048 x 2048 at 32 spp) the truth keeps every sample's camera hit
#: between frames (module docstring, "Memory"); a larger image traces them again in each frame.
KEEP_SAMPLES = 1 << 27
#: Samples per band of a larger image: about 1 GB of per-sample state at a time.
BAND_SAMPLES = 1 << 24
#: Samples per band of an image whose samples are kept: the rays' own buffers (Embree's inputs
#: and outputs, the shading's terms) stay this small, and are reused from band to band.
KEPT_BAND_SAMPLES = 1 << 22


def bands(rows: int, cols: int, spp: int) -> list[tuple[int, int]]:
    """Return the bands of pixels in which a truth of a ``rows x cols`` image at ``spp`` works.

    See :func:`band_ranges`.
    """
    return band_ranges((rows, cols), spp)


def keeps_samples(rows: int, cols: int, spp: int) -> bool:
    """Return whether a truth of a ``rows x cols`` image at ``spp`` keeps every sample's camera hit.

    The hits are kept between frames, up to :data:`KEEP_SAMPLES` (module docstring, "Memory").
    """
    return rows * cols * spp <= KEEP_SAMPLES


def band_ranges(shape: tuple[int, int], spp: int, band_samples: int | None = None) -> list[tuple[int, int]]:
    """Return bands of whole pixel rows as ``[(first, stop), ...]`` pixel indices.

    Each band has at most ``band_samples`` samples (at least one row); default: bands of
    :data:`KEPT_BAND_SAMPLES` where the samples are kept (:func:`keeps_samples`), else of
    :data:`BAND_SAMPLES`.
    """
    H, W = shape
    if band_samples is None:
        band_samples = KEPT_BAND_SAMPLES if keeps_samples(H, W, spp) else BAND_SAMPLES
    rows = max(1, int(band_samples) // (W * spp))
    return [(r * W, min(H, r + rows) * W) for r in range(0, H, rows)]


@dataclasses.dataclass
class Samples:
    """The camera samples of a band of pixels ``first <= p < stop``.

    They are samples ``start`` to ``start + count``: lifted origin ``o``, geometric normal ``n``, shading
    normal ``ns``, ``albedo`` (or None), ``A`` (``ambient``, when declared), and how many were ``moved`` off a
    line of edges.
    """

    first: int
    stop: int
    start: int
    count: int
    o: object
    n: object
    ns: object
    albedo: object
    moved: int
    ambient: object = None
    seen: object = None


def off_edge_lines(
    xs: np.ndarray, ys: np.ndarray, rows: int, cols: int, level: int = 1
) -> tuple[np.ndarray, np.ndarray, int]:
    """Move samples that lie exactly on a line of mesh edges a few ulps off it.

    The mesh's edges (:func:`hzval.geometry.tile.tessellate`) run along the lines of
    the sub-cell grid of its finest ``level`` ``n`` (a power of two):
    ``(x - 1/2) n`` or ``(y - 1/2) n`` an integer (the columns and rows of
    texel centres among them), and along that grid's diagonals, where the
    two fractions ``u``, ``v`` of those coordinates are equal or sum to 1
    (a coarser cell's diagonals and sub-cells lie on the same lines). A
    sample on such a line has no single triangle, and a ray toward an
    azimuth along the line (0, 90, 180, 270 or 45, 135, 225, 315 degrees,
    all in common sweeps) runs inside the edge and can slip between its two
    triangles: Embree's traversal is not watertight there (embree/embree#387).
    With float32 positions this is not rare: on a 512x512 map at 16 spp
    about 230 samples per frame sat on the lines of the old diagonal mesh.
    They move by 8 ulps of the map's largest coordinate (1/2048 texel at
    512) toward the tile's interior, to a point of one triangle; a few on
    lines of a finer grid than their cell's move for nothing.
    """
    step = 2.0 ** (math.ceil(math.log2(max(rows, cols, 2))) - 20)

    def on_lines(x, y):
        # (x - 1/2) n and its fraction are exact in float32 (n a power of two), and two fractions
        # sum to exactly 1 only if 1 - fu, which is then a float32, equals fv
        u, v = (x - np.float32(0.5)) * np.float32(level), (y - np.float32(0.5)) * np.float32(level)
        fu, fv = u - np.floor(u), v - np.floor(v)
        return (fu == 0) | (fv == 0) | (fu == fv) | (fv == 1 - fu)

    # only the few samples found on a line are moved and checked again; they are found in one
    # Dr.Jit kernel (the same float32 test: 0.1 s against 0.8 s in NumPy at 2048 x 2048 x 16)
    idx = _on_edge_lines_index(xs, ys, level)
    moved = int(idx.size)
    if not moved:
        return xs, ys, 0  # as they are (the shared positions are read-only: no copy)
    xs, ys = np.array(xs, dtype=np.float32), np.array(ys, dtype=np.float32)
    for _ in range(3):
        if not idx.size:
            break
        x, y = xs[idx].astype(np.float64), ys[idx].astype(np.float64)
        xs[idx] = x + np.where(x < cols / 2, step, -step)
        ys[idx] = y + np.where(y < rows / 2, step / 2, -step / 2)
        idx = idx[on_lines(xs[idx], ys[idx])]
    return xs, ys, moved


def _on_edge_lines_index(xs: np.ndarray, ys: np.ndarray, level: int = 1) -> np.ndarray:
    """Return the indices (int64) of the samples exactly on a line of mesh edges (:func:`off_edge_lines`)."""
    i = dr.arange(mi.UInt32, xs.size)
    n = dr.opaque(mi.Float, float(level))
    x = dr.gather(mi.Float, mi.Float(np.ascontiguousarray(xs, np.float32)), i)
    y = dr.gather(mi.Float, mi.Float(np.ascontiguousarray(ys, np.float32)), i)
    u, v = (x - 0.5) * n, (y - 0.5) * n
    fu, fv = u - dr.floor(u), v - dr.floor(v)
    return np.asarray(dr.compress((fu == 0.0) | (fv == 0.0) | (fu == fv) | (fv == 1.0 - fu)), dtype=np.int64)
