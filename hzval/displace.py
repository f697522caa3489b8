"""The truth's displaced surface on a base mesh (docs/meshes.md, "The displaced surface").

On the plane the truth traces the bilinear height field tessellated to a tolerance
(:mod:`hzval.mesh`, docs/truth-surface.md). On a model the analogue is a **texel-scale
subdivision** of the base mesh in UV space (:func:`refine`), each vertex pushed along its
interpolated normal by the bilinear height there (:func:`displace`):
``p + n * H(uv) * depth * world_per_uv``, ``depth`` in texture widths as on the plane.

Watertight
    Every base triangle is cut into ``n x n`` sub-triangles (``n`` a power of two, its *level*),
    enough that its longest edge is cut into pieces of at most ``max_edge_texels`` texels (UV length
    times the image's size). An edge's level is the largest its triangles ask for, on both sides of
    a UV seam (edges are keyed by their welded end points, :func:`hzval.model.edge_table`); a
    triangle's level is the largest of its edges'. A triangle finer than one of its edges snaps its
    nodes on that edge to the edge's own ``m + 1`` nodes (rounded along the edge in the order of the
    welded ids, so both sides round alike), which leaves zero-area triangles (harmless to a ray
    tracer) and no T-junction. The node ``k / m`` of an edge is one point, computed by one float64
    expression from the welded end points; it has one weld id on both sides of a seam, and
    :func:`displace` gives every welded vertex the same displaced position (the mean height along
    the mean of the normals, mitred at hard edges), so no light leaks through a crack.
The plane
    The unit quad at ``n = 2 cols`` has a node at every texel centre, displaced by exactly
    ``H * depth``: the plane's surface up to the tessellation (tests/test_displace.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from hzval import conventions as cv
from hzval import tangents as tg
from hzval.model import BaseMesh, edge_table

#: Bytes per refined triangle to budget: :func:`refine` and :func:`displace` peak at 330-390 bytes a
#: triangle over their start (a 20k-triangle torus and model, the plane, 512^2 and 1024^2,
#: benchmarks/bench_meshes.py) and keep 130-250 (the refined arrays and the displaced positions),
#: to which Mitsuba's mesh and Embree's BVH add 140 (:data:`hzval.mesh.BYTES_PER_TRIANGLE`).
BYTES_PER_TRIANGLE = 420


@dataclass(frozen=True)
class Refined:
    """A base mesh cut to the texel scale. Per vertex: ``positions (V, 3)`` (on the base mesh),
    ``normals (V, 3)`` (interpolated, normalised), ``tangents (V, 4)`` (interpolated,
    re-orthonormalised against the normal, ``w`` kept), ``uvs (V, 2)``, ``weld (V,)`` (one id per
    position, equal across a seam); ``faces (F, 3)`` int64 counterclockwise as the base's,
    ``base_face (F,)`` the base triangle each came from, ``levels`` the base triangles' ``n``."""

    positions: np.ndarray
    normals: np.ndarray
    tangents: np.ndarray
    uvs: np.ndarray
    faces: np.ndarray
    weld: np.ndarray
    base_face: np.ndarray
    levels: np.ndarray


# ----------------------------------------------------------------------------------------------
# Levels
# ----------------------------------------------------------------------------------------------

def _levels_for(length: np.ndarray, max_edge_texels: float, powers_of_two: bool) -> np.ndarray:
    """Pieces an edge of ``length`` texels is cut into: the smallest count (or power of two) that
    leaves none longer than ``max_edge_texels``; at least 1."""
    need = np.maximum(length / max_edge_texels, 1.0)
    if powers_of_two:
        return (2 ** np.ceil(np.log2(need) - 1e-12)).astype(np.int64)
    return np.ceil(need - 1e-9).astype(np.int64)


def edge_levels(base: BaseMesh, texels: tuple[int, int], max_edge_texels: float = 1.0, *,
                powers_of_two: bool = False):
    """``(F, 3)`` int64: the level ``m`` of each triangle's edge ``e`` (corner ``e`` to ``e + 1``),
    the same for every triangle on one welded edge: the power of two that cuts the edge into
    pieces of at most ``max_edge_texels`` texels on every side (``texels = (rows, cols)``): any
    count (the default: a fifth to a half of the triangles that powers of two give, docs/meshes.md)
    or, ``powers_of_two``, the next power of two (an edge's nodes are then a subset of its finer
    triangle's)."""
    if not (isinstance(max_edge_texels, (int, float)) and max_edge_texels > 0):
        raise ValueError(f"max_edge_texels must be positive, got {max_edge_texels!r}")
    rows, cols = texels
    uv = base.uvs[base.faces] * [cols, rows]
    length = np.linalg.norm(np.roll(uv, -1, axis=1) - uv, axis=-1)
    need = _levels_for(length, max_edge_texels, powers_of_two)
    _, unique, inverse, _ = edge_table(base.faces, base.weld)
    level = np.zeros(len(unique), np.int64)
    np.maximum.at(level, inverse.ravel(), need.ravel())
    return level[inverse]


def estimate(base: BaseMesh, texels: tuple[int, int], max_edge_texels: float = 1.0, *,
             powers_of_two: bool = False) -> tuple[int, int]:
    """``(triangles, bytes)`` of :func:`refine` before it runs: ``sum n^2`` over the base
    triangles (the zero-area ones that snapping removes included, an upper bound) and
    :data:`BYTES_PER_TRIANGLE` each."""
    n = edge_levels(base, texels, max_edge_texels, powers_of_two=powers_of_two).max(axis=1)
    triangles = int(np.sum(n * n))
    return triangles, triangles * BYTES_PER_TRIANGLE


# ----------------------------------------------------------------------------------------------
# The lattice of one triangle
# ----------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class _Lattice:
    """The nodes ``(a, b)``, ``a + b <= n``, of a triangle at level ``n``: barycentric weights
    ``((n - a - b) / n, a / n, b / n)`` of corners 0, 1, 2. ``corner`` (P,) the corner a node is
    (-1 if none), ``edge`` (P,) the edge it lies inside (0: corner 0 to 1, 1: 1 to 2, 2: 2 to 0;
    -1 if none) and ``step`` (P,) its index along that edge from the edge's first corner;
    ``faces (n^2, 3)`` the sub-triangles in node indices, counterclockwise as the triangle."""

    n: int
    ab: np.ndarray
    corner: np.ndarray
    edge: np.ndarray
    step: np.ndarray
    faces: np.ndarray


@lru_cache(maxsize=32)
def lattice(n: int) -> _Lattice:
    """The :class:`_Lattice` of level ``n`` (cached)."""
    b, a = np.divmod(np.arange((n + 1) ** 2), n + 1)
    keep = a + b <= n
    a, b = a[keep], b[keep]
    index = np.full((n + 1, n + 1), -1, np.int64)
    index[a, b] = np.arange(len(a))
    corner = np.full(len(a), -1)
    corner[index[0, 0]], corner[index[n, 0]], corner[index[0, n]] = 0, 1, 2
    edge = np.full(len(a), -1)
    step = np.zeros(len(a), np.int64)
    inside = corner < 0
    for e, on, s in ((0, b == 0, a), (1, a + b == n, b), (2, a == 0, n - b)):
        edge[on & inside], step[on & inside] = e, s[on & inside]
    ua, ub = np.nonzero(np.add.outer(np.arange(n + 1), np.arange(n + 1)) <= n - 1)
    up = np.stack([index[ua, ub], index[ua + 1, ub], index[ua, ub + 1]], -1)
    da, db = np.nonzero(np.add.outer(np.arange(n + 1), np.arange(n + 1)) <= n - 2)
    down = np.stack([index[da + 1, db], index[da + 1, db + 1], index[da, db + 1]], -1)
    return _Lattice(n, np.stack([a, b], -1), corner, edge, step, np.concatenate([up, down]))


# ----------------------------------------------------------------------------------------------
# Refinement
# ----------------------------------------------------------------------------------------------

@dataclass
class _Nodes:
    """The nodes of a group of triangles, one row per (triangle, lattice node): ``kind`` 0 (a base
    vertex, ``node`` its id), 1 (inside a base edge: ``key`` its base ids and ``k``, ``wkey`` its
    welded ids and ``k``) or 2 (inside the triangle); ``weights (K, 3)`` over ``corners (K, 3)``."""

    kind: np.ndarray
    node: np.ndarray
    key: np.ndarray
    wkey: np.ndarray
    weights: np.ndarray
    corners: np.ndarray
    faces: np.ndarray
    base_face: np.ndarray


def _snap_edge(lat: _Lattice, e: int, c: np.ndarray, w: np.ndarray, m: np.ndarray):
    """The nodes of edge ``e`` of triangles with corners ``c`` (welded ``w``) snapped to the edge's
    ``m + 1`` nodes: ``(cols, k, lo_slot, hi_slot, lo, hi)`` with ``k`` counted from the end point
    of the smaller welded id (``lo``, in corner slot ``lo_slot``), rounded half up."""
    cols = np.flatnonzero(lat.edge == e)
    f = (e + 1) % 3
    flip = w[:, e] > w[:, f]
    a = np.where(flip[:, None], lat.n - lat.step[cols][None, :], lat.step[cols][None, :])
    k = (2 * a * m[:, None] + lat.n) // (2 * lat.n)
    lo_slot, hi_slot = np.where(flip, f, e), np.where(flip, e, f)
    rows = np.arange(len(c))
    return cols, k, lo_slot, hi_slot, c[rows, lo_slot], c[rows, hi_slot]


def _group_nodes(base: BaseMesh, tris: np.ndarray, n: int, elev: np.ndarray) -> _Nodes:
    """The :class:`_Nodes` of base triangles ``tris``, all at level ``n`` (``elev`` their edge levels)."""
    lat = lattice(n)
    c = base.faces[tris]
    w = base.weld[c]
    N, P = len(tris), len(lat.ab)
    bary = np.concatenate([(n - lat.ab.sum(1))[:, None], lat.ab], axis=1) / n
    weights = np.broadcast_to(bary, (N, P, 3)).copy()
    kind = np.broadcast_to(np.where(lat.corner >= 0, 0, 2), (N, P)).copy()
    node = np.zeros((N, P), np.int64)
    key = np.zeros((N, P, 3), np.int64)
    wkey = np.zeros((N, P, 3), np.int64)
    for corner in range(3):
        node[:, lat.corner == corner] = c[:, corner:corner + 1]
    for e in range(3):
        cols, k, lo_slot, hi_slot, lo, hi = _snap_edge(lat, e, c, w, elev[:, e])
        if not cols.size:
            continue
        t = k / elev[:, e:e + 1]
        wt = np.zeros((N, len(cols), 3))
        np.put_along_axis(wt, lo_slot[:, None, None], (1.0 - t)[..., None], axis=2)
        np.put_along_axis(wt, hi_slot[:, None, None], t[..., None], axis=2)
        weights[:, cols] = wt
        end = (k == 0) | (k == elev[:, e:e + 1])
        kind[:, cols] = np.where(end, 0, 1)
        node[:, cols] = np.where(k == 0, lo[:, None], hi[:, None])
        pq = np.sort(np.stack([lo, hi], 1), axis=1)
        key[:, cols] = np.concatenate([np.broadcast_to(pq[:, None], (N, len(cols), 2)), k[..., None]], -1)
        wpq = np.sort(base.weld[np.stack([lo, hi], 1)], axis=1)
        wkey[:, cols] = np.concatenate([np.broadcast_to(wpq[:, None], (N, len(cols), 2)), k[..., None]], -1)
    faces = (lat.faces[None] + P * np.arange(N)[:, None, None]).reshape(-1, 3)
    return _Nodes(kind.ravel(), node.ravel(), key.reshape(-1, 3), wkey.reshape(-1, 3),
                  weights.reshape(-1, 3), np.repeat(c, P, axis=0), faces, np.repeat(tris, n * n))


def _unique_rows(rows: np.ndarray):
    """``(first, inverse)`` of :func:`numpy.unique` over the rows of a non-negative int64 array."""
    if len(rows) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    span = rows.max(axis=0) + 1
    if float(np.prod(span.astype(np.float64))) < 2.0 ** 62:
        flat = np.ravel_multi_index(tuple(rows.T), tuple(int(s) for s in span))
        _, first, inverse = np.unique(flat, return_index=True, return_inverse=True)
    else:
        _, first, inverse = np.unique(rows, axis=0, return_index=True, return_inverse=True)
    return first, inverse.ravel()


def _interpolate(base: BaseMesh, weld_pos: np.ndarray, weights: np.ndarray, corners: np.ndarray):
    """Positions, normals, tangents and UVs at nodes of ``weights`` over base ``corners``."""
    def mix(values):
        return np.einsum("kc,kcd->kd", weights, values[corners])

    n = tg._normalize(mix(base.normals))
    t4 = mix(base.tangents)
    t = tg.reject(t4[:, :3], n)
    return mix(weld_pos[base.weld]), n, np.concatenate([t, tg._sign(t4[:, 3])[:, None]], 1), mix(base.uvs)


def refine(base: BaseMesh, texels: tuple[int, int], *, max_edge_texels: float = 1.0,
           powers_of_two: bool = False) -> Refined:
    """``base`` cut in UV space until every edge is at most about ``max_edge_texels`` texels of a
    ``texels = (rows, cols)`` image, watertight across UV seams (the module's "Watertight")."""
    elev = edge_levels(base, texels, max_edge_texels, powers_of_two=powers_of_two)
    levels = elev.max(axis=1)
    first_of_weld = np.zeros(int(base.weld.max()) + 1, np.int64)
    first_of_weld[base.weld[::-1]] = np.arange(len(base.weld))[::-1]
    weld_pos = base.positions[first_of_weld]
    groups = [_group_nodes(base, np.flatnonzero(levels == n), int(n), elev[levels == n])
              for n in np.unique(levels)]
    cat = lambda name: np.concatenate([getattr(g, name) for g in groups])
    kind, node = cat("kind"), cat("node")
    offsets = np.cumsum([0] + [len(g.kind) for g in groups])
    faces = np.concatenate([g.faces + o for g, o in zip(groups, offsets)])
    V, W = len(base.positions), int(base.weld.max()) + 1
    vid, weld = node.copy(), base.weld[np.minimum(node, V - 1)]
    on_edge, inside = np.flatnonzero(kind == 1), np.flatnonzero(kind == 2)
    first_e, inv_e = _unique_rows(cat("key")[on_edge])
    wfirst, winv = _unique_rows(cat("wkey")[on_edge])
    vid[on_edge], weld[on_edge] = V + inv_e, W + winv
    vid[inside] = V + len(first_e) + np.arange(len(inside))
    weld[inside] = W + len(wfirst) + np.arange(len(inside))
    new = np.concatenate([on_edge[first_e], inside])  # one node for each new vertex, in id order
    p, n, t, uv = _interpolate(base, weld_pos, cat("weights")[new], cat("corners")[new])
    out_weld = np.concatenate([base.weld, weld[new]])
    f = vid[faces]
    ok = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])
    return Refined(np.concatenate([weld_pos[base.weld], p]), np.concatenate([base.normals, n]),
                   np.concatenate([base.tangents, t]), np.concatenate([base.uvs, uv]), f[ok],
                   out_weld, cat("base_face")[ok], levels)


# ----------------------------------------------------------------------------------------------
# Displacement
# ----------------------------------------------------------------------------------------------

def bilinear(image: np.ndarray, uvs: np.ndarray, boundary: str) -> np.ndarray:
    """``image`` (``(rows, cols)`` or ``(rows, cols, k)``) read bilinearly between texel centres at
    hzval UVs (u right, v up the image, :mod:`hzval.model`), as the plane reads it: texel
    ``(row, col)``'s centre is at ``x = col + 0.5``, ``y = rows - row - 0.5``
    (:func:`hzval.conventions.texel_centres`) with ``x = u cols``, ``y = v rows``; ``wrap``
    repeats the image, ``open`` clamps to its border. Returns ``(V,)`` or ``(V, k)`` float64."""
    if boundary not in cv.BOUNDARIES:
        raise ValueError(f"unknown boundary {boundary!r}")
    img = np.asarray(image, np.float64)
    rows, cols = img.shape[:2]
    fx = np.asarray(uvs[:, 0], np.float64) * cols - 0.5          # column coordinate of the centres
    fy = rows - np.asarray(uvs[:, 1], np.float64) * rows - 0.5   # row coordinate
    c0, r0 = np.floor(fx), np.floor(fy)
    a, b = fx - c0, fy - r0
    if img.ndim == 3:
        a, b = a[:, None], b[:, None]
    c0, r0 = c0.astype(np.int64), r0.astype(np.int64)

    def at(r, c):
        if boundary == "wrap":
            return img[r % rows, c % cols]
        return img[np.clip(r, 0, rows - 1), np.clip(c, 0, cols - 1)]

    return ((1 - b) * ((1 - a) * at(r0, c0) + a * at(r0, c0 + 1))
            + b * ((1 - a) * at(r0 + 1, c0) + a * at(r0 + 1, c0 + 1)))


def sample_height(height: np.ndarray, uvs: np.ndarray, boundary: str) -> np.ndarray:
    """``(V,)`` float64: the height map ``H`` at ``uvs`` (:func:`bilinear`)."""
    return bilinear(height, uvs, boundary)


def shading_normals(refined: Refined, normal_map: np.ndarray, boundary: str) -> np.ndarray:
    """``(V, 3)`` float32 unit world normals of the refined vertices: the tangent-space normal map
    (``(rows, cols, 3)``, :func:`hzval.bake.normal_map`: x along +u, y along +v, z out) read at
    each vertex (:func:`bilinear`) and carried to the world by the vertex's frame
    (:func:`hzval.tangents.to_world`), as the techniques carry it at their hit points."""
    m = bilinear(normal_map, refined.uvs, boundary)
    n = tg.to_world(m, refined.normals, refined.tangents[:, :3], refined.tangents[:, 3])
    return tg._normalize(n).astype(np.float32)


def weld_means(weld: np.ndarray, values: np.ndarray) -> np.ndarray:
    """The mean of ``values`` (``(V,)`` or ``(V, k)``) over each weld id, ``(W, ...)``."""
    count = np.bincount(weld).astype(np.float64)
    if values.ndim == 1:
        return np.bincount(weld, values) / count
    return np.stack([np.bincount(weld, values[:, j]) for j in range(values.shape[1])], -1) / count[:, None]


#: Welds :func:`displace` knows: ``miter`` (the default) or ``mean``.
WELDS: tuple[str, ...] = ("miter", "mean")
#: The miter's longest push, in heights: a cube's corner (three normals at right angles, ``|m| =
#: 1/sqrt(3)``); sharper corners are pushed no further.
MAX_MITER = math.sqrt(3.0)


def displace(refined: Refined, height: np.ndarray, depth: float, world_per_uv: float,
             boundary: str, *, weld: str = "miter") -> tuple[np.ndarray, np.ndarray]:
    """The truth's surface: ``(positions (V, 3) float32, faces (F, 3) uint32)``, one position per
    refined vertex, ``p + n H(uv) depth world_per_uv`` with ``H`` from :func:`sample_height`
    (``height`` ``(rows, cols)`` in [0, 1], ``depth`` in texture widths). The vertices of one weld
    id (a seam's sides, a hard edge's) share one position, bit for bit, pushed by their mean height
    ``h`` along the mean ``m`` of their unit normals (their first normal where those cancel):
    ``mean`` by ``h m / |m|``; ``miter`` by ``h m / |m|^2`` (at most :data:`MAX_MITER` ``h``), which
    moves the point by ``h`` along each of two normals, or three at right angles, so that a hard
    edge's faces stay flat up to it (a constant height grows a cube into a cube). Along a smooth
    seam (equal normals) the two are the same."""
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
