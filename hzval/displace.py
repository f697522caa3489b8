"""The truth's displaced surface on a base mesh (docs/meshes.md, "The displaced surface").

On the plane the truth traces the bilinear height field tessellated to a tolerance
(:mod:`hzval.mesh`, docs/truth-surface.md). On a model the analogue is a **texel-scale
subdivision** of the base mesh in UV space (:func:`refine`), each vertex pushed along its
interpolated normal by the bilinear height there (:func:`displace`):
``p + n * H(uv) * depth * world_per_uv``, ``depth`` in texture widths as on the plane.

Watertight
    Every base triangle is cut at a *level* ``n``: an inner lattice of its barycentric nodes
    ``(n - a - b, a, b) / n`` with ``a, b >= 1``, stitched to its three sides. A side's level ``m``
    is the number of pieces that leaves none longer than ``max_edge_texels`` texels (UV length
    times the image's size), the largest that any triangle on it asks for, on both sides of a UV
    seam (edges are keyed by their welded end points, :func:`hzval.model.edge_table`); a triangle's
    ``n`` is the largest of its sides'. Each side is cut into exactly its ``m`` pieces and joined to
    the row of lattice nodes next to it by a strip merged in order along the side (:func:`strip`,
    the way a GPU tessellator joins its inner ring to its outer edges): no T-junction, no
    zero-area triangle, nothing folds over. The node ``k / m`` of a side is one point, computed by
    one float64 expression from the welded end points; it has one weld id on both sides of a seam,
    and :func:`displace` gives every welded vertex the same displaced position (the mean height
    along the mean of the normals, mitred at hard edges), so no light leaks through a crack. Long
    thin triangles, whose ``n`` their longest side sets, are bisected first (:mod:`hzval.slivers`).
The plane
    The unit quad at ``n = 2 cols`` (``max_edge_texels = 0.7072``) has a node at every texel
    centre, displaced by exactly ``H * depth``: the plane's surface up to the tessellation
    (tests/test_displace.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from hzval import conventions as cv
from hzval import tangents as tg
from hzval.model import BaseMesh, edge_table
from hzval.slivers import split

#: Bytes per refined triangle to budget: :func:`refine` and :func:`displace` peak at 280-390 bytes a
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
    ``base_face (F,)`` the base triangle each came from, ``levels`` the ``n`` of each piece that was
    cut (the base triangles, or their pieces where slivers were bisected, :mod:`hzval.slivers`)."""

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
    the same for every triangle on one welded edge: the number of pieces that leaves none longer
    than ``max_edge_texels`` texels on any side of it (``texels = (rows, cols)``), or with
    ``powers_of_two`` the next power of two (a third more triangles on a torus, docs/meshes.md)."""
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
             powers_of_two: bool = False, split_slivers: bool = True) -> tuple[int, int]:
    """``(triangles, bytes)`` of :func:`refine` before it runs (its exact count,
    :func:`triangles_of`) and :data:`BYTES_PER_TRIANGLE` each."""
    if split_slivers:
        base = split(base, texels, max_edge_texels)[0]
    elev = edge_levels(base, texels, max_edge_texels, powers_of_two=powers_of_two)
    triangles = int(np.sum(triangles_of(elev.max(axis=1), elev)))
    return triangles, triangles * BYTES_PER_TRIANGLE


# ----------------------------------------------------------------------------------------------
# One triangle's tessellation: an inner lattice and three stitched strips
# ----------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class _Lattice:
    """The inside of a triangle at level ``n``: its interior nodes, barycentric ``bary (I, 3)``
    over corners 0, 1, 2 (the lattice nodes ``(n - a - b, a, b) / n`` with ``a, b >= 1``,
    ``a + b <= n - 1``; for ``n = 2`` the centroid), ``inner (T, 3)`` the lattice's triangles
    among them (``(n - 3)^2``), ``chains (3, L)`` the interior nodes next to each side ``e`` (corner
    ``e`` to ``e + 1``) in order along it and ``params (L,)`` where they project onto the side
    (``(j + 1.5) / n``, the same for each side by symmetry)."""

    n: int
    bary: np.ndarray
    inner: np.ndarray
    chains: np.ndarray
    params: np.ndarray


@lru_cache(maxsize=64)
def lattice(n: int) -> _Lattice:
    """The :class:`_Lattice` of level ``n`` (cached)."""
    if n <= 2:
        bary = np.full((n - 1, 3), 1.0 / 3.0)
        return _Lattice(n, bary, np.zeros((0, 3), np.int64), np.zeros((3, n - 1), np.int64), np.full(n - 1, 0.5))
    b, a = np.divmod(np.arange((n + 1) ** 2), n + 1)
    keep = (a >= 1) & (b >= 1) & (a + b <= n - 1)
    a, b = a[keep], b[keep]
    index = np.full((n + 1, n + 1), -1, np.int64)
    index[a, b] = np.arange(len(a))
    up = (a + b <= n - 2)
    down = (a + b <= n - 3)
    inner = np.concatenate([np.stack([index[a[up], b[up]], index[a[up] + 1, b[up]], index[a[up], b[up] + 1]], -1),
                            np.stack([index[a[down] + 1, b[down]], index[a[down] + 1, b[down] + 1],
                                      index[a[down], b[down] + 1]], -1)])
    j = np.arange(1, n - 1)
    chains = np.stack([index[j, 1], index[n - 1 - j, j], index[1, j[::-1]]])
    bary = np.stack([n - a - b, a, b], -1) / n
    return _Lattice(n, bary, inner, chains, (np.arange(n - 2) + 1.5) / n)


@lru_cache(maxsize=4096)
def strip(n: int, m: int) -> np.ndarray:
    """``(m + L - 1, 3)`` int64: the triangles between a side cut into ``m`` pieces (its nodes
    ``k = 0 .. m`` at ``k / m``) and the ``L`` interior nodes next to it (:func:`lattice`), merged
    in order along the side (each triangle joins the next node of the chain whose next node comes
    first), counterclockwise; entries ``k >= 0`` are side nodes, ``-(j + 1)`` chain node ``j``.
    Both chains lie on parallel lines, so no triangle folds over."""
    params = lattice(n).params
    last = len(params) - 1
    i = j = 0
    tris = []
    while i < m or j < last:
        if j == last or (i < m and (i + 1) / m <= params[j + 1]):
            tris.append((i, i + 1, -(j + 1)))
            i += 1
        else:
            tris.append((i, -(j + 2), -(j + 1)))
            j += 1
    return np.array(tris, np.int64).reshape(-1, 3)


def triangles_of(n: np.ndarray, elev: np.ndarray) -> np.ndarray:
    """Triangles of each base triangle at level ``n`` with edge levels ``elev (F, 3)``:
    ``(n - 3)^2 + sum_e (m_e + n - 3)`` (``n >= 3``), ``sum_e m_e`` (``n = 2``), 1 (``n = 1``)."""
    m = elev.sum(axis=1)
    return np.where(n >= 3, (n - 3) ** 2 + m + 3 * (n - 3), np.where(n == 2, m, 1))


@dataclass
class _Nodes:
    """The nodes of a group of triangles at one level, one row per (triangle, node): ``kind`` 0 (a
    base vertex, ``node`` its id), 1 (inside a base edge) or 2 (inside the triangle); ``weights
    (K, 3)`` over ``corners (K, 3)``; the edge nodes' rows ``edge`` with ``key`` (their base ids and
    ``k``) and ``wkey`` (their welded ids and ``k``); ``faces`` in rows, ``base_face`` per face."""

    kind: np.ndarray
    node: np.ndarray
    weights: np.ndarray
    corners: np.ndarray
    edge: np.ndarray
    key: np.ndarray
    wkey: np.ndarray
    faces: np.ndarray
    base_face: np.ndarray


def _side_nodes(base: BaseMesh, c: np.ndarray, e: int, m: int):
    """The ``m - 1`` nodes inside side ``e`` of triangles with corners ``c``: ``(key, wkey,
    weights)``, ``(N, m - 1, 3)`` each, node ``k`` of the side (from corner ``e``) being node
    ``k_can`` from the end of the smaller welded id, at ``k_can / m`` (one float64 expression for
    both sides of a seam)."""
    f = (e + 1) % 3
    w = base.weld[c]
    flip = w[:, e] > w[:, f]
    k = np.arange(1, m)[None, :]
    k_can = np.where(flip[:, None], m - k, k)
    lo_slot, hi_slot = np.where(flip, f, e), np.where(flip, e, f)
    rows = np.arange(len(c))
    lo, hi = c[rows, lo_slot], c[rows, hi_slot]
    t = k_can / m
    weights = np.zeros(k_can.shape + (3,))
    np.put_along_axis(weights, lo_slot[:, None, None], (1.0 - t)[..., None], axis=2)
    np.put_along_axis(weights, hi_slot[:, None, None], t[..., None], axis=2)
    pair = lambda x, y: np.broadcast_to(np.sort(np.stack([x, y], 1), axis=1)[:, None], k_can.shape + (2,))
    key = np.concatenate([pair(lo, hi), k_can[..., None]], -1)
    wkey = np.concatenate([pair(base.weld[lo], base.weld[hi]), k_can[..., None]], -1)
    return key, wkey, weights


def _group_nodes(base: BaseMesh, tris: np.ndarray, n: int, elev: np.ndarray) -> _Nodes:
    """The :class:`_Nodes` of base triangles ``tris``, all at level ``n`` (``elev`` their edge
    levels): corners, the inner lattice (:func:`lattice`) and each side's nodes, stitched to the
    lattice by :func:`strip`."""
    lat = lattice(n)
    c = base.faces[tris]
    N, I = len(tris), len(lat.bary)
    rows = [(np.zeros(3 * N, np.int64), c.ravel(), np.tile(np.eye(3), (N, 1)), np.repeat(c, 3, axis=0)),
            (np.full(N * I, 2), np.full(N * I, -1), np.tile(lat.bary, (N, 1)), np.repeat(c, I, axis=0))]
    corner_row = np.arange(3 * N).reshape(N, 3)
    inner_row = 3 * N + np.arange(N * I).reshape(N, I)
    size = 3 * N + N * I
    faces = [corner_row] if n == 1 else [inner_row[:, lat.inner].reshape(-1, 3)]
    owner = [np.arange(N)] if n == 1 else [np.repeat(np.arange(N), len(lat.inner))]
    edge, keys, wkeys = [], [], []
    for e in range(3):
        for m in (np.unique(elev[:, e]) if n > 1 else ()):
            sel = np.flatnonzero(elev[:, e] == m)
            key, wkey, weights = _side_nodes(base, c[sel], e, int(m))
            here = size + np.arange(len(sel) * (m - 1)).reshape(len(sel), m - 1)
            rows.append((np.ones(here.size, np.int64), np.full(here.size, -1), weights.reshape(-1, 3),
                         np.repeat(c[sel], m - 1, axis=0)))
            edge.append(here.ravel())
            keys.append(key.reshape(-1, 3))
            wkeys.append(wkey.reshape(-1, 3))
            size += here.size
            table = np.concatenate([corner_row[sel, e:e + 1], here, corner_row[sel, (e + 1) % 3:(e + 1) % 3 + 1],
                                    inner_row[sel][:, lat.chains[e]]], axis=1)
            t = strip(n, int(m))
            faces.append(table[:, np.where(t >= 0, t, m + 1 - t - 1)].reshape(-1, 3))
            owner.append(np.repeat(sel, len(t)))
    cat = lambda parts, k: np.concatenate([p[k] for p in parts])
    empty = np.zeros((0, 3), np.int64)
    return _Nodes(cat(rows, 0), cat(rows, 1), cat(rows, 2), cat(rows, 3),
                  np.concatenate(edge) if edge else np.zeros(0, np.int64),
                  np.concatenate(keys) if keys else empty, np.concatenate(wkeys) if wkeys else empty,
                  np.concatenate(faces), tris[np.concatenate(owner)])


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

    return (mix(weld_pos[base.weld]),) + _unit_frame(mix(base.normals), mix(base.tangents)) + (mix(base.uvs),)


def _unit_frame(n: np.ndarray, t4: np.ndarray):
    """``(n, t4)`` interpolated (or a sliver's midpoint's means) as a unit frame: ``n`` normalised,
    ``t`` rejected from it, ``w`` its sign."""
    n = tg._normalize(n)
    return n, np.concatenate([tg.reject(t4[:, :3], n), tg._sign(t4[:, 3])[:, None]], 1)


def refine(base: BaseMesh, texels: tuple[int, int], *, max_edge_texels: float = 1.0,
           powers_of_two: bool = False, split_slivers: bool = True) -> Refined:
    """``base`` cut in UV space until every edge is at most about ``max_edge_texels`` texels of a
    ``texels = (rows, cols)`` image, watertight across UV seams (the module's "Watertight");
    ``split_slivers``: long thin triangles bisected first (:func:`hzval.slivers.split`)."""
    base, parent = split(base, texels, max_edge_texels) if split_slivers else (base, None)
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
    on_edge = np.concatenate([g.edge + o for g, o in zip(groups, offsets)])
    V, W = len(base.positions), int(base.weld.max()) + 1
    vid, weld = node.copy(), base.weld[np.maximum(node, 0)]
    inside = np.flatnonzero(kind == 2)
    first_e, inv_e = _unique_rows(cat("key"))
    wfirst, winv = _unique_rows(cat("wkey"))
    vid[on_edge], weld[on_edge] = V + inv_e, W + winv
    vid[inside] = V + len(first_e) + np.arange(len(inside))
    weld[inside] = W + len(wfirst) + np.arange(len(inside))
    new = np.concatenate([on_edge[first_e], inside])  # one node for each new vertex, in id order
    p, n, t, uv = _interpolate(base, weld_pos, cat("weights")[new], cat("corners")[new])
    out_weld = np.concatenate([base.weld, weld[new]])
    n0, t0 = _unit_frame(base.normals, base.tangents)
    piece = cat("base_face")
    positions = np.concatenate([weld_pos[base.weld], p])
    one = np.zeros(int(out_weld.max()) + 1, np.int64)
    one[out_weld[::-1]] = np.arange(len(out_weld))[::-1]
    positions = positions[one][out_weld]  # a seam's sides: one point, whatever the sum's rounding
    return Refined(positions, np.concatenate([n0, n]), np.concatenate([t0, t]),
                   np.concatenate([base.uvs, uv]), vid[faces], out_weld,
                   piece if parent is None else parent[piece], levels)


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
