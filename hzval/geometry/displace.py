"""The truth's displaced surface on a base mesh (docs/meshes.md, "The displaced surface").

On the plane the truth traces the bilinear height field tessellated to a tolerance
(:mod:`hzval.geometry.tile`, docs/truth-surface.md). On a model the analogue is the base mesh **cut along
the texel grid** in UV space, every piece of a triangle in a cell a fan about its centre
(:func:`refine`, :mod:`hzval.geometry.cells`), each vertex pushed along its interpolated normal by the
bilinear height there (:func:`displace`): ``p + n * H(uv) * depth * world_per_uv``, ``depth`` in
texture widths as on the plane.

Watertight
    A point on a base edge is computed from the edge's two ends alone, bit for bit alike on both
    of its triangles; where a UV seam cuts the two sides at different points, each side gets the
    other's (:func:`hzval.geometry.cells._stitch`), and the points at one place share one weld id.
    :func:`displace` gives every welded vertex one displaced position (the mean height along the
    mean of the normals, mitred at hard edges), so no light leaks through a crack.
The plane
    The unit quad whose UVs are its ``(x, y)`` has a vertex at every texel centre and a fan in
    every cell about its centre: the plane's surface (:func:`hzval.geometry.tile.tessellate`) at one ring,
    ``H * depth`` at the texel centres (tests/geometry/test_displace.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hzval.core import budget
from hzval.core import conventions as cv
from hzval.geometry import cells
from hzval.geometry import tangents as tg
from hzval.geometry.model import BaseMesh
from hzval.geometry.tile import DEFAULT_TOLERANCE

__all__ = [
    "Refined",
    "refine",
    "estimate",
    "bilinear",
    "sample_height",
    "shading_normals",
    "weld_means",
    "WELDS",
    "MAX_MITER",
    "displace",
]


@dataclass(frozen=True)
class Refined:
    """A base mesh cut to the texel scale.

    Per vertex: ``positions (V, 3)`` (on the base mesh), ``normals (V, 3)`` (interpolated, normalised),
    ``tangents (V, 4)`` (interpolated, re-orthonormalised against the normal, ``w`` kept), ``uvs (V, 2)``,
    ``weld (V,)`` (one id per position, equal across a seam); ``faces (F, 3)`` int64 counterclockwise as the
    base's, ``base_face (F,)`` the base triangle each came from.
    """

    positions: np.ndarray
    normals: np.ndarray
    tangents: np.ndarray
    uvs: np.ndarray
    faces: np.ndarray
    weld: np.ndarray
    base_face: np.ndarray


def refine(
    base: BaseMesh,
    texels: tuple[int, int],
    boundary: str = "wrap",
    *,
    height: np.ndarray | None = None,
    depth: float | None = None,
    tolerance: float | None = None,
) -> Refined:
    """Cut ``base`` in UV space along the texel grid of a ``texels = (rows, cols)`` image.

    Each piece is a fan, watertight across UV seams (:mod:`hzval.geometry.cells`). With ``height``
    (normalised, the map itself) and ``depth``, a twisted cell's fans are cut into rings until they are within
    ``tolerance`` texels of the bilinear patch (default :data:`hzval.geometry.tile.DEFAULT_TOLERANCE`).
    """
    h_tex = None
    if height is not None:
        h_tex = cv.heights_in_texels(np.asarray(height, np.float32), float(depth))
        tolerance = DEFAULT_TOLERANCE if tolerance is None else float(tolerance)
    m = cells.mesh(base, texels, boundary, height_texels=h_tex, tolerance=tolerance)
    return Refined(
        m["positions"], m["normals"], m["tangents"], m["uvs"], m["faces"], m["weld"], m["base_face"]
    )


def estimate(
    base: BaseMesh,
    texels: tuple[int, int],
    boundary: str = "wrap",
    *,
    height: np.ndarray | None = None,
    depth: float | None = None,
    tolerance: float | None = None,
) -> tuple[int, int]:
    """Return the ``(triangles, bytes)`` of :func:`refine` before it runs, one ring a cell.

    That is ``4 A + 2.2 P + 1.1 F`` triangles for ``A`` texels of UV area, ``P`` texels of the base triangles'
    edges (the cells they cross: ``|du| + |dv|``) and ``F`` base triangles, fitted within 5% to the shapes and
    a 20k-triangle torus at 64^2 to 256^2 (commit message),
    :data:`hzval.core.budget.REFINE_BYTES_PER_TRIANGLE` each. With the map (``height``, ``depth``,
    ``tolerance`` as :func:`refine` takes them) the cells' rings count too: a fan's edge of ``n`` rings is ``2
    n - 1`` triangles (the cells' mean).
    """
    rows, cols = texels
    uv = base.uvs[base.faces] * [cols, rows]
    area = 0.5 * np.abs(
        (uv[:, 1, 0] - uv[:, 0, 0]) * (uv[:, 2, 1] - uv[:, 0, 1])
        - (uv[:, 2, 0] - uv[:, 0, 0]) * (uv[:, 1, 1] - uv[:, 0, 1])
    )
    perimeter = np.abs(np.roll(uv, -1, axis=1) - uv).sum()
    rings = 1.0
    if height is not None:
        h_tex = cv.heights_in_texels(np.asarray(height, np.float32), float(depth))
        n = cells.ring_levels(h_tex, boundary, DEFAULT_TOLERANCE if tolerance is None else float(tolerance))
        rings = float(np.mean(2 * n - 1))
    triangles = int(rings * (4.0 * area.sum() + 2.2 * perimeter) + 1.1 * len(base.faces))
    return triangles, triangles * budget.REFINE_BYTES_PER_TRIANGLE


# ----------------------------------------------------------------------------------------------
# Displacement
# ----------------------------------------------------------------------------------------------


def bilinear(image: np.ndarray, uvs: np.ndarray, boundary: str) -> np.ndarray:
    """Read ``image`` bilinearly between texel centres at hzval UVs, as the plane reads it.

    ``image`` is ``(rows, cols)`` or ``(rows, cols, k)``; the UVs have u right, v up the image
    (:mod:`hzval.geometry.model`); the plane reads it with :func:`hzval.core.conventions.bilinear_at` at ``x =
    u cols``, ``y = v rows``. Returns ``(V,)`` or ``(V, k)`` float64.
    """
    if boundary not in cv.BOUNDARIES:
        raise ValueError(f"unknown boundary {boundary!r}")
    rows, cols = np.shape(image)[:2]
    uvs = np.asarray(uvs, np.float64)
    return cv.bilinear_at(image, uvs[:, 0] * cols, uvs[:, 1] * rows, boundary)


def sample_height(height: np.ndarray, uvs: np.ndarray, boundary: str) -> np.ndarray:
    """``(V,)`` float64: the height map ``H`` at ``uvs`` (:func:`bilinear`)."""
    return bilinear(height, uvs, boundary)


def shading_normals(refined: Refined, normal_map: np.ndarray, boundary: str) -> np.ndarray:
    """Return the refined vertices' unit world normals from the tangent-space normal map.

    They are ``(V, 3)`` float32. The map (``(rows, cols, 3)``, :func:`hzval.core.conventions.normal_map`: x
    along +u, y along +v, z out) is read at each vertex (:func:`bilinear`) and carried to the world by the
    vertex's frame (:func:`hzval.geometry.tangents.to_world`), as the techniques carry it at their hit points.
    """
    m = bilinear(normal_map, refined.uvs, boundary)
    n = tg.to_world(m, refined.normals, refined.tangents[:, :3], refined.tangents[:, 3])
    return tg.normalize(n).astype(np.float32)


def weld_means(weld: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Return the mean of ``values`` (``(V,)`` or ``(V, k)``) over each weld id, ``(W, ...)``."""
    count = np.bincount(weld).astype(np.float64)
    if values.ndim == 1:
        return np.bincount(weld, values) / count
    return np.stack([np.bincount(weld, values[:, j]) for j in range(values.shape[1])], -1) / count[:, None]


#: Welds :func:`displace` knows: ``miter`` (the default) or ``mean``.
WELDS: tuple[str, ...] = ("miter", "mean")
#: The miter's longest push, in heights: a cube's corner (three normals at right angles, ``|m| =
#: 1/sqrt(3)``); sharper corners are pushed no further.
MAX_MITER = math.sqrt(3.0)


def displace(
    refined: Refined,
    height: np.ndarray,
    depth: float,
    world_per_uv: float,
    boundary: str,
    *,
    weld: str = "miter",
) -> tuple[np.ndarray, np.ndarray]:
    """Return the truth's surface: ``(positions (V, 3) float32, faces (F, 3) uint32)``.

    There is one position per refined vertex, ``p + n H(uv) depth world_per_uv`` with ``H`` from
    :func:`sample_height` (``height`` ``(rows, cols)`` in [0, 1], ``depth`` in texture widths). The vertices
    of one weld id (a seam's sides, a hard edge's) share one position, bit for bit, pushed by their mean
    height ``h`` along the mean ``m`` of their unit normals (their first normal where those cancel): ``mean``
    by ``h m / |m|``; ``miter`` by ``h m / |m|^2`` (at most :data:`MAX_MITER` ``h``), which moves the point by
    ``h`` along each of two normals, or three at right angles, so that a hard edge's faces stay flat up to it
    (a constant height grows a cube into a cube). Along a smooth seam (equal normals) the two are the same.
    """
    if np.ndim(height) != 2 or not np.all(np.isfinite(height)):
        raise ValueError("height must be a finite (rows, cols) array")
    if weld not in WELDS:
        raise ValueError(f"unknown weld {weld!r}; known: {', '.join(WELDS)}")
    h = sample_height(height, refined.uvs, boundary) * (float(depth) * float(world_per_uv))
    w = refined.weld
    m = weld_means(w, refined.normals)
    length = np.linalg.norm(m, axis=-1, keepdims=True)
    first = np.zeros(len(m), np.int64)
    first[w[::-1]] = np.arange(len(w))[::-1]
    cancel = length < 1e-6
    m = np.where(cancel, refined.normals[first], m / np.maximum(length, 1e-300))
    push = weld_means(w, h)[:, None]
    if weld == "miter":
        push = push * np.where(cancel, 1.0, np.minimum(1.0 / np.maximum(length, 1e-300), MAX_MITER))
    p = refined.positions[first] + m * push
    return p[w].astype(np.float32), refined.faces.astype(np.uint32)
