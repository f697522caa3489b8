"""Long thin triangles cut before the texel-scale refinement (:func:`hzval.displace.refine`).

The refinement cuts a base triangle into ``n x n`` pieces with ``n`` set by its *longest* edge in
texels, so a sliver (a CAD model's cylinder, a game model's long strip) costs ``n^2`` triangles
where its area needs a few: a 192 x 7.5 texel sliver of a 6k-triangle capsule took 47,000. Such a
triangle is bisected first, by **longest-edge propagation** (Rivara 1997, "New longest-edge
algorithms for the refinement and/or improvement of unstructured triangulations", Int. J. Numer.
Meth. Eng. 40): a triangle to cut follows its longest edge to the neighbour until an edge is the
longest of every triangle on it (a *terminal* edge); that edge is split at its midpoint and every
triangle on it is cut through the midpoint, so the mesh stays conforming (no T-junction), and
across a UV seam too (edges are keyed by their welded end points, :func:`hzval.model.edge_table`).
Repeated, the pieces' angles stay bounded below.

The midpoint of an edge ``(a, b)`` on one side of a seam is one new vertex with the mean of ``a``'s
and ``b``'s attributes, **not normalised**, so that interpolating inside a piece is the same linear
interpolation as inside the original triangle (the refinement normalises at its nodes); its
position is the mean of the welded end points', the same bits on both sides.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from hzval.model import BaseMesh, edge_table

#: A triangle is cut when ``longest edge^2 / (2 area)`` in texels (the refinement's triangles per
#: texel of area, over the ideal; 1.15 for an equilateral, 2 for a right isosceles one) exceeds
#: this, and its longest edge is longer than :data:`MIN_EDGE` refinement pieces (a shorter one
#: costs at most 64 triangles). Measured: lower bounds cut far more pieces (66,000 from a 32-triangle
#: cylinder side at 256^2 with 4 and 4, 22,000 with 6 and 8) for the same refined count.
MAX_WASTE = 6.0
MIN_EDGE = 8.0
MAX_ROUNDS = 64


def _texel_geometry(mesh: BaseMesh, texels):
    """Per face: edge lengths ``(F, 3)`` in texels (edge ``e`` from corner ``e`` to ``e + 1``) and
    the UV area in texels squared."""
    rows, cols = texels
    uv = mesh.uvs[mesh.faces] * [cols, rows]
    d1, d2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    area = 0.5 * np.abs(d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1])
    return np.linalg.norm(np.roll(uv, -1, axis=1) - uv, axis=-1), area


def _to_split(mesh: BaseMesh, texels, max_edge_texels: float):
    """``(cut (F,) bool, longest (F,))``: the faces cut this round, each along its longest edge
    (``longest``, in texels), a terminal edge of a path from a wasteful face (:data:`MAX_WASTE`)."""
    length, area = _texel_geometry(mesh, texels)
    longest = np.argmax(length, axis=1)
    lmax = length[np.arange(len(length)), longest]
    bad = (lmax > MIN_EDGE * max_edge_texels) & (lmax ** 2 > MAX_WASTE * 2.0 * area)
    if not bad.any():
        return bad, longest
    _, unique, inverse, counts = edge_table(mesh.faces, mesh.weld)
    own = inverse[np.arange(len(inverse)), longest]               # each face's longest edge
    terminal = np.bincount(own, minlength=len(unique))[own] == counts[own]  # longest of all on it
    marked = bad.copy()
    for _ in range(MAX_ROUNDS):                                    # follow the longest edges
        walk = np.zeros(len(unique), bool)
        walk[own[marked & ~terminal]] = True
        grown = marked.copy()
        grown[np.flatnonzero(walk[inverse.ravel()]) // 3] = True
        if np.array_equal(grown, marked):
            break
        marked = grown
    cut = np.zeros(len(unique), bool)
    cut[own[marked & terminal]] = True
    return cut[own], longest


def _midpoints(mesh: BaseMesh, a: np.ndarray, b: np.ndarray):
    """New vertices at the midpoints of the vertex pairs ``(a, b)`` (each pair once): ``(index of
    each pair's vertex, positions, normals, tangents, uvs, weld ids)``, attributes averaged (not
    normalised); the midpoints of one welded pair share one weld id (numbered after the mesh's)."""
    pairs, inverse = np.unique(np.sort(np.stack([a, b], 1), axis=1), axis=0, return_inverse=True)
    lo, hi = pairs[:, 0], pairs[:, 1]
    first = np.zeros(int(mesh.weld.max()) + 1, np.int64)
    first[mesh.weld[::-1]] = np.arange(len(mesh.weld))[::-1]
    wpair = np.sort(np.stack([mesh.weld[lo], mesh.weld[hi]], 1), axis=1)
    p = 0.5 * (mesh.positions[first[wpair[:, 0]]] + mesh.positions[first[wpair[:, 1]]])
    _, wid = np.unique(wpair, axis=0, return_inverse=True)
    mean = lambda x: 0.5 * (x[lo] + x[hi])
    return (len(mesh.positions) + inverse.ravel(), p, mean(mesh.normals), mean(mesh.tangents),
            mean(mesh.uvs), int(mesh.weld.max()) + 1 + wid.ravel())


def _split_once(mesh: BaseMesh, parent: np.ndarray, cut: np.ndarray, longest: np.ndarray):
    """``mesh`` with the faces ``cut`` bisected along their ``longest`` edge: ``(mesh, parent)``."""
    f, e = mesh.faces[cut], longest[cut]
    rot = np.stack([f[np.arange(len(f)), (e + k) % 3] for k in range(3)], 1)  # longest edge first
    m, p, n, t, uv, weld = _midpoints(mesh, rot[:, 0], rot[:, 1])
    halves = np.concatenate([np.stack([rot[:, 0], m, rot[:, 2]], 1), np.stack([m, rot[:, 1], rot[:, 2]], 1)])
    out = replace(mesh, positions=np.concatenate([mesh.positions, p]), normals=np.concatenate([mesh.normals, n]),
                  tangents=np.concatenate([mesh.tangents, t]), uvs=np.concatenate([mesh.uvs, uv]),
                  faces=np.concatenate([mesh.faces[~cut], halves]))
    out.__dict__["weld"] = np.concatenate([mesh.weld, weld])  # a cached_property, set once here
    return out, np.concatenate([parent[~cut], parent[cut], parent[cut]])


def split(base: BaseMesh, texels, max_edge_texels: float = 1.0) -> tuple[BaseMesh, np.ndarray]:
    """``(mesh, parent)``: ``base`` with its wasteful slivers bisected (the module's docstring),
    ``parent (F',)`` the base face each new face lies in. ``base`` itself (and ``arange``) when
    nothing needs it, as for every built-in shape at any size."""
    mesh, parent = base, np.arange(len(base.faces))
    for _ in range(MAX_ROUNDS):
        cut, longest = _to_split(mesh, texels, max_edge_texels)
        if not cut.any():
            break
        mesh, parent = _split_once(mesh, parent, cut, longest)
    return mesh, parent
