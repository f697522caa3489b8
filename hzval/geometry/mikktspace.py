"""MikkTSpace tangent frames (Mikkelsen 2008), the frames bakers and engines agree on.

Blender, Substance, Marmoset, xNormal, Unity and Unreal compute a mesh's tangents with
Mikkelsen's algorithm ("Simulation of wrinkled surfaces revisited", 2008; the reference
implementation ``mikktspace.c``), and glTF 2.0 asks for it where a mesh has no ``TANGENT``. A
tangent-space map decodes right only with the frames it was baked with, so hzval computes the
same frames (:mod:`hzval.geometry.tangents` owns which frames a mesh uses). No installable
package brings MikkTSpace to Python (``pymikktspace``'s only release is an sdist that does not
build); this is a NumPy implementation of the reference's documented behaviour, checked against
the reference compiled from C (``tests/oracles/mikktspace/``).

The steps, as the reference takes them (``genTangSpace`` with its default angular threshold):

1. **Welding.** Corners with identical position, normal and texture coordinate (bit for bit, in
   float32) are one vertex.
2. **Triangles.** A triangle with two equal positions is degenerate and left out. For the others,
   with ``d1 = P1 - P0``, ``d2 = P2 - P0`` and the texture differences ``t21``, ``t31``:
   ``Os = t31.v d1 - t21.v d2``, ``Ot = -t31.u d1 + t21.u d2`` (eqs. 18 and 19), the signed
   texture area ``A = t21.u t31.v - t21.v t31.u``, the triangle *orientation preserving* where
   ``A > 0``; ``Os`` and ``Ot`` normalised and multiplied by the sign of ``A``. A triangle whose
   ``A``, ``|Os| / |A|`` or ``|Ot| / |A|`` is zero has no frame of its own ("group with any").
3. **Groups.** Around each welded vertex, triangles that share an edge (the same two welded
   vertices, wound oppositely) and have the same orientation form one group, found depth first
   from each corner in triangle order; a frameless triangle joins the first group that reaches it
   and takes its orientation. So a UV seam (different texture coordinates, no shared welded edge)
   and a mirror line (opposite orientations) both keep a frame on each side.
4. **Frames.** A group's tangent is the sum, over its triangles with a frame, of ``Os`` projected
   onto the vertex's tangent plane and normalised, weighted by the triangle's angle at the vertex
   (the angle between its two edges there, also projected), then normalised. Its sign is the
   group's orientation: ``+1`` where orientation preserving, ``-1`` where not; the bitangent is
   ``sign * cross(n, t)``, as glTF's ``TANGENT.w`` defines it.
5. **Leftovers.** A corner of a degenerate triangle takes the frame of the first corner of a good
   triangle at the same welded vertex; a corner no group reached keeps the reference's default,
   ``t = (1, 0, 0)`` and sign ``-1``.

The reference's angular threshold (180 degrees by default) splits a group only where two of its
triangles' tangents point exactly opposite; that split is not made here. Quads are not handled
(hzval's meshes are triangles). Arithmetic is float64; the reference's float32 agrees to its
rounding.
"""

from __future__ import annotations

import numpy as np

__all__ = ["corner_tangents", "per_vertex"]

#: The reference's ``NotZero``: a value counts as zero when its magnitude is at most float32's
#: smallest normal number.
FLT_MIN = float(np.finfo(np.float32).tiny)


def _normalized(v: np.ndarray) -> np.ndarray:
    """``v / |v|`` along the last axis where ``|v|`` is not zero (the reference's ``VNotZero``)."""
    length = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.divide(v, length, out=np.array(v, dtype=np.float64), where=length > FLT_MIN)


def _project(v: np.ndarray, n: np.ndarray) -> np.ndarray:
    """``v`` projected onto the plane orthogonal to the unit ``n``, then normalised."""
    return _normalized(v - n * np.sum(n * v, axis=-1, keepdims=True))


def _weld(p, n, w) -> np.ndarray:
    """``(F, 3)`` welded vertex ids: corners of equal float32 position, normal and UV share one."""
    key = np.concatenate([p, n, w], axis=-1).reshape(-1, 8).astype(np.float32)
    _, ids = np.unique(key.view(np.dtype((np.void, 32))).ravel(), return_inverse=True)
    return ids.reshape(-1, 3)


def _triangle_frames(p, w):
    """Per triangle ``(Os, orientation preserving, has a frame)`` (module docstring, step 2)."""
    d1, d2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    t21, t31 = w[:, 1] - w[:, 0], w[:, 2] - w[:, 0]
    area = t21[:, 0] * t31[:, 1] - t21[:, 1] * t31[:, 0]
    os_ = t31[:, 1:2] * d1 - t21[:, 1:2] * d2
    ot = -t31[:, 0:1] * d1 + t21[:, 0:1] * d2
    preserving = area > 0
    sign = np.where(preserving, 1.0, -1.0)[:, None]
    len_s, len_t = np.linalg.norm(os_, axis=-1), np.linalg.norm(ot, axis=-1)
    nonzero = np.abs(area) > FLT_MIN
    safe = np.where(nonzero, np.abs(area), 1.0)
    framed = nonzero & (len_s / safe > FLT_MIN) & (len_t / safe > FLT_MIN)
    os_ = np.where((nonzero & (len_s > FLT_MIN))[:, None], sign * _normalized(os_), 0.0)
    return os_, preserving, framed


def _neighbours(weld: np.ndarray, good: np.ndarray) -> np.ndarray:
    """Return, as ``(F, 3)``, the good triangle across each edge of a good triangle, or -1.

    Edge ``i`` runs from corner ``i`` to ``i + 1``; the triangle across is wound oppositely over the same
    welded vertices. An edge that only two triangles share is paired by sorting; where more share it, each
    directed edge takes the first free opposite one in triangle order, as the reference pairs them.
    """
    out = np.full(weld.shape, -1, np.int64)
    faces = np.flatnonzero(good)
    a, b = weld[faces], np.roll(weld[faces], -1, axis=1)
    m = int(weld.max(initial=0)) + 1
    key, rev = (a * m + b).ravel(), (b * m + a).ravel()
    order = np.argsort(key, kind="stable")
    ranked = key[order]
    lo, hi = np.searchsorted(ranked, rev, "left"), np.searchsorted(ranked, rev, "right")
    own = np.searchsorted(ranked, key, "right") - np.searchsorted(ranked, key, "left")
    simple = (hi - lo == 1) & (own == 1)
    tri = np.repeat(faces, 3)
    partner = order[np.minimum(lo, len(order) - 1)]
    out.reshape(-1)[(tri * 3 + np.tile(np.arange(3), len(faces)))[simple]] = tri[partner[simple]]
    _pair_shared(out, faces, a.tolist(), b.tolist(), np.flatnonzero(~simple))
    return out


def _pair_shared(out: np.ndarray, faces, a: list, b: list, edges) -> None:
    """Pair the directed edges ``edges`` (flat indices) that more than two triangles share."""
    by_key: dict[tuple[int, int], list[tuple[int, int]]] = {}
    for e in edges.tolist():
        k, i = divmod(e, 3)
        by_key.setdefault((a[k][i], b[k][i]), []).append((int(faces[k]), i))
    for (u, v), sides in by_key.items():
        if u > v or (v, u) not in by_key:
            continue
        others = by_key[(v, u)]
        for f, i in sides:
            for n, (g, j) in enumerate(others):
                if out[g, j] == -1 and g != f:
                    out[f, i], out[g, j] = g, f
                    others.pop(n)
                    break


def _groups(weld, neighbours, preserving, framed, good) -> tuple[np.ndarray, np.ndarray]:
    """Return the group of each corner and the orientation of each group (module docstring, step 3).

    The group is -1 for a corner no group reached. The search is depth first, as the reference's
    ``AssignRecur``: from a corner, its triangle's neighbour across the edge leaving it, then across the edge
    arriving at it.
    """
    w, nb = weld.tolist(), neighbours.tolist()
    orient, has_frame = preserving.tolist(), framed.tolist()
    group = [[-1, -1, -1] for _ in w]
    orientation: list[bool] = []
    for f in np.flatnonzero(good & framed).tolist():
        for i in range(3):
            if group[f][i] != -1:
                continue
            g, vertex, o = len(orientation), w[f][i], orient[f]
            orientation.append(o)
            group[f][i] = g
            stack = [nb[f][(i - 1) % 3], nb[f][i]]  # popped: the edge leaving the corner first
            while stack:
                t = stack.pop()
                if t < 0:
                    continue
                j = w[t].index(vertex)
                if group[t][j] != -1:
                    continue
                if not has_frame[t] and group[t] == [-1, -1, -1]:
                    orient[t] = o  # a frameless triangle takes the first group's orientation
                if orient[t] != o:
                    continue
                group[t][j] = g
                stack += [nb[t][(j - 1) % 3], nb[t][j]]
    return np.array(group, np.int64).reshape(-1, 3), np.array(orientation, bool)


def corner_tangents(positions, normals, uvs, faces) -> np.ndarray:
    """MikkTSpace tangents of every triangle corner (module docstring).

    Parameters
    ----------
    positions, normals : array_like
        ``(V, 3)`` vertex positions and unit normals.
    uvs : array_like
        ``(V, 2)`` texture coordinates, ``v`` up (hzval's and Blender's convention).
    faces : array_like
        ``(F, 3)`` vertex indices of each triangle, counterclockwise from outside.

    Returns
    -------
    numpy.ndarray
        ``(F, 3, 4)`` float64: per corner the unit tangent along +u and the sign ``w`` of the
        bitangent ``w * cross(n, t)``.

    Examples
    --------
    >>> import numpy as np
    >>> p = np.array([[0.0, 0, 0], [2, 0, 0], [2, 1, 0], [0, 1, 0]])
    >>> n = np.tile([0.0, 0, 1], (4, 1))
    >>> uv = np.array([[0.0, 0], [1, 0], [1, 1], [0, 1]])
    >>> corner_tangents(p, n, uv, [[0, 1, 2], [0, 2, 3]])[0].tolist()
    [[1.0, 0.0, 0.0, 1.0], [1.0, 0.0, 0.0, 1.0], [1.0, 0.0, 0.0, 1.0]]
    """
    faces = np.asarray(faces, np.int64).reshape(-1, 3)
    p = np.asarray(positions, np.float64)[faces]
    n = np.asarray(normals, np.float64)[faces]
    w = np.asarray(uvs, np.float64)[faces]
    weld = _weld(p, n, w)
    p32 = p.astype(np.float32)
    good = ~(
        (p32[:, 0] == p32[:, 1]).all(-1) | (p32[:, 0] == p32[:, 2]).all(-1) | (p32[:, 1] == p32[:, 2]).all(-1)
    )
    os_, preserving, framed = _triangle_frames(p, w)
    group, orientation = _groups(weld, _neighbours(weld, good), preserving, framed, good)
    # each corner's contribution: Os projected, weighted by the triangle's angle at the corner
    v1 = _project(np.roll(p, 1, axis=1) - p, n)
    v2 = _project(np.roll(p, -1, axis=1) - p, n)
    angle = np.arccos(np.clip(np.sum(v1 * v2, axis=-1), -1.0, 1.0))
    contribution = angle[..., None] * _project(np.broadcast_to(os_[:, None], p.shape), n)
    counts = (group >= 0) & framed[:, None]
    sums = np.zeros((len(orientation), 3))
    np.add.at(sums, group[counts], contribution[counts])
    out = np.zeros(faces.shape + (4,))
    out[..., :3], out[..., 3] = [1.0, 0.0, 0.0], -1.0  # the reference's default for a lone corner
    seen = group >= 0
    out[seen, :3] = _normalized(sums)[group[seen]]
    out[seen, 3] = np.where(orientation[group[seen]], 1.0, -1.0)
    _leftovers(out, weld, good, seen)
    return out


def _leftovers(out: np.ndarray, weld: np.ndarray, good: np.ndarray, seen: np.ndarray) -> None:
    """Give a degenerate triangle's corners the first good, grouped corner's frame at their welded vertex.

    See the module docstring, step 5.
    """
    bad = np.flatnonzero(~good)
    if not len(bad):
        return
    first: dict[int, tuple[int, int]] = {}
    for f, i in zip(*np.nonzero(seen & good[:, None])):
        first.setdefault(int(weld[f, i]), (f, i))
    for f in bad:
        for i in range(3):
            if int(weld[f, i]) in first:
                out[f, i] = out[first[int(weld[f, i])]]


def per_vertex(positions, normals, uvs, faces, corners: np.ndarray):
    """Return a mesh's arrays with a vertex for each distinct frame its corners hold.

    MikkTSpace gives each corner a frame; a vertex whose corners hold different frames (a mirror
    line with shared texture coordinates) becomes one vertex per frame, with its position, normal
    and UV repeated.

    Parameters
    ----------
    positions, normals, uvs, faces : array_like
        As :func:`corner_tangents`.
    corners : numpy.ndarray
        ``(F, 3, 4)`` its result.

    Returns
    -------
    tuple of numpy.ndarray
        ``(positions, normals, uvs, faces, tangents)``, the tangents ``(V', 4)``; the arrays as
        given where no vertex splits.
    """
    faces = np.asarray(faces, np.int64).reshape(-1, 3)
    flat = faces.reshape(-1)
    key = np.concatenate([flat[:, None].astype(np.float64), corners.reshape(-1, 4)], axis=1)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    # new vertices ordered by the vertex they copy, then by the corner that first holds them: a mesh
    # whose vertices do not split keeps its own order
    order = np.lexsort((first, flat[first]))
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    vertex_of = flat[first[order]]
    new_faces = rank[inverse.reshape(-1)].reshape(-1, 3)
    tangents = corners.reshape(-1, 4)[first[order]]
    return (
        np.asarray(positions)[vertex_of],
        np.asarray(normals)[vertex_of],
        np.asarray(uvs)[vertex_of],
        new_faces,
        tangents,
    )
