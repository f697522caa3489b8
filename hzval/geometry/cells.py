"""A base mesh cut along the texel grid: the truth's tessellation on a model (docs/meshes.md).

The truth's surface is the *bilinear* interpolation of the height samples (docs/truth-surface.md),
whose creases run along the lines through the texel centres, ``x = i + 0.5`` and ``y = j + 0.5`` in
texels (:mod:`hzval.core.conventions`: ``x = u cols``, ``y = v rows``). Between them, in one *cell*, it
is one bilinear patch. A tessellation whose vertices miss the creases cuts the peaks off: on the
unit quad, vertices a texel apart but off the texel centres put the truth's mean V 0.015 above the
plane's at 30 degrees, and halving the spacing halved that, no more (the error of a crease is of
the first order). So each base triangle is cut, in UV space, into its pieces in each cell (the
convex polygon where the triangle and the cell overlap: :func:`_polygons`), and each piece is a fan
around its centroid, so that no diagonal is preferred: a cell inside a triangle is the plane's four
triangles around its centre (:func:`hzval.geometry.tile.cell_levels`). A twisted cell's fans are cut into
``n`` rings (``n`` the plane's level for the cell's twist and the truth's tolerance,
:func:`hzval.geometry.tile.cell_levels`), whose edges
run parallel to the cell's sides where the patch is straight: no point of them is more than about
``|d| / (16 n^2)`` texels off the patch. On the unit quad whose UVs are its ``(x, y)`` the surface
is the plane's.

Canonical points
    A piece's vertices are cell corners inside the triangle, the triangle's corners inside the cell,
    and the crossings of the triangle's edges with the cell's sides. A crossing is computed from the
    edge's end points in the order of their vertex ids, so the two triangles of an edge compute it
    bit for bit alike; points on a base edge take their values from the edge's two ends alone.
Seams
    Where UVs are discontinuous (a UV seam), the two sides of one edge are cut at different points.
    Every point of either side is put on both (:func:`_stitch`), and the points at one place along
    the edge share one weld id, so that :func:`hzval.geometry.displace.displace` gives them one position and
    the mesh stays closed.
"""

from __future__ import annotations

import numpy as np

from hzval.geometry import tangents as tg
from hzval.geometry.tile import cell_levels

__all__ = ["CHUNK_PAIRS", "ring_levels", "CORNER", "EDGE", "INSIDE", "cut", "mesh"]

#: Pairs of (triangle, cell) clipped at a time: about 19 candidate points each, 40 floats a point.
CHUNK_PAIRS = 1 << 18


def ring_levels(height_texels: np.ndarray, boundary: str, tolerance: float) -> np.ndarray:
    """Return the rings of each cell's fans as a ``(rows, cols)`` int array (module docstring).

    Each is the plane's own level for the cell's twist and the tolerance
    (:func:`hzval.geometry.tile.cell_levels`; a planar cell one ring). Cell ``(ky, kx)`` spans ``x`` in ``[kx
    + 0.5, kx + 1.5]``, ``y`` in ``[ky + 0.5, ky + 1.5]`` (texel row ``rows - 1 - ky``); ``wrap`` wraps the
    last cells around, ``open`` clamps them flat.
    """
    h = np.asarray(height_texels, np.float64)[::-1]  # row 0: the first texel centre along y
    z = np.pad(h, ((0, 1), (0, 1)), mode="wrap" if boundary == "wrap" else "edge")
    return np.maximum(cell_levels(z, float(tolerance)), 1).astype(np.int64)


# ----------------------------------------------------------------------------------------------
# The pieces of each triangle in each cell
# ----------------------------------------------------------------------------------------------

#: Kinds of a piece's vertex: a base corner, a point on a base edge, a point inside a base triangle.
CORNER, EDGE, INSIDE = 0, 1, 2


def _pair_chunks(X: np.ndarray, Y: np.ndarray, faces: np.ndarray, usable: np.ndarray):
    """Yield ``(face, kx, ky)`` of every cell that each usable triangle's bounding box touches, in chunks.

    The chunks are of about :data:`CHUNK_PAIRS`; a cell ``(ky, kx)`` spans ``[kx + 0.5, kx + 1.5] x [ky + 0.5,
    ky + 1.5]``.
    """
    fx, fy = X[faces], Y[faces]
    kx0, kx1 = (np.floor(v - 0.5).astype(np.int64) for v in (fx.min(1), fx.max(1)))
    ky0, ky1 = (np.floor(v - 0.5).astype(np.int64) for v in (fy.min(1), fy.max(1)))
    nx, ny = kx1 - kx0 + 1, ky1 - ky0 + 1
    count = np.where(usable, nx * ny, 0)
    ends = np.cumsum(count)
    first = 0
    while first < len(faces):
        stop = int(np.searchsorted(ends, ends[first] - count[first] + CHUNK_PAIRS, side="right"))
        stop = max(stop, first + 1)
        f = np.repeat(np.arange(first, stop), count[first:stop])
        local = np.arange(len(f)) - np.repeat(
            ends[first:stop] - count[first:stop] - (ends[first] - count[first]), count[first:stop]
        )
        yield f, kx0[f] + local % nx[f], ky0[f] + local // nx[f]
        first = stop


def _where(X, Y, faces, f, kx, ky) -> np.ndarray:
    """Return, per pair, where the cell lies against its triangle: 1 inside, -1 outside, 0 near an edge.

    1 means wholly inside, -1 wholly outside; 0 is near one of its edges (the cell's centre within half a
    diagonal of the edge's line: cut it).
    """
    cx, cy = X[faces[f]], Y[faces[f]]
    mx, my = kx + 1.0, ky + 1.0  # the cell's centre
    inside = np.ones(len(f), bool)
    outside = np.zeros(len(f), bool)
    for e in range(3):
        ax, ay, bx, by = cx[:, e], cy[:, e], cx[:, (e + 1) % 3], cy[:, (e + 1) % 3]
        ox, oy = cx[:, (e + 2) % 3], cy[:, (e + 2) % 3]
        length = np.hypot(bx - ax, by - ay)
        side = np.sign((bx - ax) * (oy - ay) - (by - ay) * (ox - ax))
        d = ((bx - ax) * (my - ay) - (by - ay) * (mx - ax)) * side / np.maximum(length, 1e-300)
        inside &= d > 0.71  # half the diagonal, 0.7071
        outside |= d < -0.71
    return np.where(inside, 1, np.where(outside, -1, 0))


def _square(kx, ky):
    """Return the :func:`_polygons` of cells wholly inside their triangles: their four corners."""
    x0, y0 = kx + 0.5, ky + 0.5
    px = np.stack([x0, x0 + 1.0, x0 + 1.0, x0], 1)
    py = np.stack([y0, y0, y0 + 1.0, y0 + 1.0], 1)
    P = len(kx)
    return (
        px,
        py,
        np.full((P, 4), INSIDE),
        np.full((P, 4), -1, np.int64),
        np.zeros((P, 4)),
        np.full(P, 4, np.int64),
    )


def _polygons(X, Y, faces, f, kx, ky):
    """Return the convex piece of triangle ``f`` in cell ``(ky, kx)``, for each pair.

    The pieces are ``(px, py, kind, vid, t, count)``, ``(P, S)`` slots sorted counterclockwise in texel space
    (invalid slots last), ``count`` the distinct vertices (< 3: no piece). ``kind``: :data:`CORNER` (``vid``
    the base vertex), :data:`EDGE` (``vid`` the edge's corner index ``e``, ``t`` along it from its lower
    vertex id), :data:`INSIDE`.
    """
    tri = faces[f]  # (P, 3) vertex ids
    cx, cy = X[tri], Y[tri]
    x0, y0 = kx + 0.5, ky + 0.5
    x1, y1 = x0 + 1.0, y0 + 1.0
    xs, ys, kinds, vids, ts, ok = [], [], [], [], [], []
    # the canonical edges: A the lower vertex id, so both triangles of an edge compute alike
    edges = []
    for e in range(3):
        a, b = tri[:, e], tri[:, (e + 1) % 3]
        swap = a > b
        ia, ib = np.where(swap, (e + 1) % 3, e), np.where(swap, e, (e + 1) % 3)
        ax, ay = np.take_along_axis(cx, ia[:, None], 1)[:, 0], np.take_along_axis(cy, ia[:, None], 1)[:, 0]
        bx, by = np.take_along_axis(cx, ib[:, None], 1)[:, 0], np.take_along_axis(cy, ib[:, None], 1)[:, 0]
        ox, oy = cx[:, (e + 2) % 3], cy[:, (e + 2) % 3]
        side = np.sign((bx - ax) * (oy - ay) - (by - ay) * (ox - ax))
        edges.append((ax, ay, bx, by, side))

    def inside(qx, qy):
        good = np.ones(qx.shape, bool)
        for ax, ay, bx, by, side in edges:
            good &= ((bx - ax) * (qy - ay) - (by - ay) * (qx - ax)) * side > 0.0
        return good

    for qx, qy in ((x0, y0), (x1, y0), (x1, y1), (x0, y1)):  # cell corners strictly inside
        xs.append(qx), ys.append(qy), kinds.append(INSIDE), vids.append(-1), ts.append(0.0)
        ok.append(inside(qx, qy))
    for c in range(3):  # triangle corners in the closed cell
        xs.append(cx[:, c]), ys.append(cy[:, c]), kinds.append(CORNER), vids.append(tri[:, c]), ts.append(0.0)
        ok.append((cx[:, c] >= x0) & (cx[:, c] <= x1) & (cy[:, c] >= y0) & (cy[:, c] <= y1))
    for e, (ax, ay, bx, by, _) in enumerate(edges):  # edges across the cell's sides
        for vertical, c, lo, hi in (
            (True, x0, y0, y1),
            (True, x1, y0, y1),
            (False, y0, x0, x1),
            (False, y1, x0, x1),
        ):
            pa, pb, qa, qb = (ax, bx, ay, by) if vertical else (ay, by, ax, bx)
            across = (np.minimum(pa, pb) < c) & (c < np.maximum(pa, pb))
            t = np.where(across, (c - pa) / np.where(across, pb - pa, 1.0), 0.0)
            q = qa + t * (qb - qa)
            xs.append(np.broadcast_to(c, q.shape) if vertical else q)
            ys.append(q if vertical else np.broadcast_to(c, q.shape))
            kinds.append(EDGE), vids.append(e), ts.append(t)
            ok.append(across & (q >= lo) & (q <= hi))
    P = len(f)

    def stack(vals):
        return np.stack([np.broadcast_to(np.asarray(v), (P,)) for v in vals], axis=1)

    px, py, kind, vid, t, valid = (stack(v) for v in (xs, ys, kinds, vids, ts, ok))
    # the valid slots first, and no more slots than the most any piece has (about 8 of 19)
    order = np.argsort(~valid, axis=1, kind="stable")[:, : max(int(valid.sum(1).max(initial=0)), 1)]
    px, py, kind, vid, t, valid = (np.take_along_axis(a, order, 1) for a in (px, py, kind, vid, t, valid))
    return _sorted_distinct(px, py, kind, vid.astype(np.int64), t, valid)


def _sorted_distinct(px, py, kind, vid, t, valid):
    """Return the valid slots sorted by angle about their mean, near-duplicates merged, invalid slots last.

    Near-duplicates are within 1e-9 texels and are merged into the most exact of them (a corner, then an edge
    point of lowest ``t``).
    """
    S = px.shape[1]
    n = np.maximum(valid.sum(1), 1)
    mx = np.where(valid, px, 0.0).sum(1) / n
    my = np.where(valid, py, 0.0).sum(1) / n
    ang = np.where(valid, np.arctan2(py - my[:, None], px - mx[:, None]), np.inf)
    arrays = [px, py, kind, vid, t, valid]

    def reorder(order):
        return [np.take_along_axis(a, order, 1) for a in arrays]

    arrays = reorder(np.argsort(ang, axis=1, kind="stable"))
    slot = np.arange(S)[None, :]
    for _ in range(3):  # a point may be found three ways
        px, py, kind, vid, t, valid = arrays
        last = valid.sum(1)[:, None] - 1
        succ = np.where(slot >= last, 0, slot + 1)  # cyclic successor among the valid
        pred = np.where(slot == 0, last, slot - 1)

        def g(a, i):
            return np.take_along_axis(a, np.maximum(i, 0), 1)

        close = valid & (last > 0) & (np.abs(px - g(px, succ)) + np.abs(py - g(py, succ)) < 1e-9)
        # of two close points, the successor is kept when it is better (lower kind, then lower t)
        succ_better = (g(kind, succ) < kind) | ((g(kind, succ) == kind) & (g(t, succ) <= t))
        drop = (close & succ_better) | (g(close, pred) & ~g(succ_better, pred) & (slot <= last))
        if not drop.any():
            break
        arrays[5] = valid & ~drop
        arrays = reorder(np.argsort(~arrays[5], axis=1, kind="stable"))
    px, py, kind, vid, t, valid = arrays
    return px, py, kind, vid, t, valid.sum(1)


def _fans(px, py, kind, vid, t, count, rings, flip):
    """Return the triangles of each piece: a fan about its vertices' mean, cut into ``rings`` rings.

    The rings are as in the module docstring. The triangles are counterclockwise in texel space (``flip``: the
    other way round, for a triangle mirrored in UV). Returns the vertex records ``(x, y, kind, vid, t, pair)``
    and ``(T, 3)`` indices into them, ``pair`` the piece each came from.
    """
    P, S = px.shape
    slot = np.arange(S)[None, :]
    live = slot < count[:, None]
    n = np.maximum(count, 1)
    cx = np.where(live, px, 0.0).sum(1) / n
    cy = np.where(live, py, 0.0).sum(1) / n
    recs = {"x": [], "y": [], "kind": [], "vid": [], "t": [], "pair": [], "fresh": []}
    tris = []
    base = 0

    def add(x, y, k, v, tt, pair, fresh=False):
        nonlocal base
        for key, val in zip(recs, (x, y, k, v, tt, pair, np.full(len(x), fresh))):
            recs[key].append(val)
        first, base = base, base + len(x)
        return first

    pieces = np.flatnonzero(count >= 3)
    # the piece's own vertices: slot s of piece p is record first + row * S + s
    rows = np.arange(len(pieces))
    first_v = add(
        px[pieces].ravel(),
        py[pieces].ravel(),
        kind[pieces].ravel(),
        vid[pieces].ravel(),
        t[pieces].ravel(),
        np.repeat(pieces, S),
    )

    def own(r, s):
        return first_v + r * S + s

    for level in np.unique(rings[pieces]):
        sel = rows[rings[pieces] == level]
        p = pieces[sel]
        m = count[p]
        # spoke points: ring j (1..level-1, and the centre as ring 0) on the spoke to slot s
        frac = np.arange(level) / level  # 0 = the centre
        sx = cx[p, None, None] + frac[None, :, None] * (px[p][:, None, :] - cx[p, None, None])
        sy = cy[p, None, None] + frac[None, :, None] * (py[p][:, None, :] - cy[p, None, None])
        sx[:, 0, :], sy[:, 0, :] = cx[p, None], cy[p, None]  # the centre, once per piece
        first_s = add(
            sx.ravel(),
            sy.ravel(),
            np.full(sx.size, INSIDE),
            np.full(sx.size, -1),
            np.zeros(sx.size),
            np.repeat(p, level * S),
            fresh=True,
        )  # one piece's own

        def ring(i, j, s):
            return np.where(j == 0, first_s + (i * level) * S, first_s + (i * level + j) * S + s)  # noqa: B023 - called within this iteration

        i = np.arange(len(p))[:, None]
        s0 = np.arange(S)[None, :]
        s1 = np.where(s0 + 1 >= m[:, None], 0, s0 + 1)
        use = s0 < m[:, None]
        for j in range(level):
            inner0, inner1 = ring(i, j, s0), ring(i, j, s1)
            if j + 1 < level:
                outer0, outer1 = ring(i, j + 1, s0), ring(i, j + 1, s1)
            else:
                outer0, outer1 = own(sel[:, None], s0), own(sel[:, None], s1)
            if j == 0:
                tris.append(np.stack([inner0, outer0, outer1], -1)[use])
            else:
                tris.append(np.stack([inner0, outer0, outer1], -1)[use])
                tris.append(np.stack([inner0, outer1, inner1], -1)[use])
    faces = np.concatenate(tris) if tris else np.zeros((0, 3), np.int64)
    out = {k: np.concatenate(v) if v else np.zeros(0) for k, v in recs.items()}
    owner = out["pair"][faces[:, 0]]
    faces = np.where(flip[owner][:, None], faces[:, ::-1], faces)
    return out, faces


# ----------------------------------------------------------------------------------------------
# The mesh
# ----------------------------------------------------------------------------------------------


def cut(
    base,
    texels: tuple[int, int],
    boundary: str,
    *,
    height_texels: np.ndarray | None = None,
    tolerance: float | None = None,
):
    """Cut ``base`` along the texel grid of a ``texels = (rows, cols)`` image (module docstring).

    Returns ``(vertices, faces, base_face, rings)`` with ``vertices`` a dict of per-vertex arrays (``kind``,
    ``vid``, ``face``, ``t``, ``x``, ``y``) that :func:`attributes` turns into positions and frames; ``rings``
    per cell from ``height_texels`` and ``tolerance`` (None: one ring).
    """
    rows, cols = texels
    X, Y = base.uvs[:, 0] * cols, base.uvs[:, 1] * rows
    faces = base.faces
    area = (X[faces[:, 1]] - X[faces[:, 0]]) * (Y[faces[:, 2]] - Y[faces[:, 0]]) - (
        X[faces[:, 2]] - X[faces[:, 0]]
    ) * (Y[faces[:, 1]] - Y[faces[:, 0]])
    usable = np.abs(area) > 1e-12
    levels = None if height_texels is None else ring_levels(height_texels, boundary, tolerance)
    parts, tri_parts, face_parts = [], [], []
    offset = 0
    for f_all, kx_all, ky_all in _pair_chunks(X, Y, faces, usable):
        where = _where(X, Y, faces, f_all, kx_all, ky_all)
        for inside in (True, False):
            sel = where == (1 if inside else 0)
            f, kx, ky = f_all[sel], kx_all[sel], ky_all[sel]
            if len(f) == 0:
                continue
            # a cell wholly inside its triangle is its square; one near an edge is cut
            px, py, kind, vid, t, count = _square(kx, ky) if inside else _polygons(X, Y, faces, f, kx, ky)
            if levels is None:
                rings = np.ones(len(f), np.int64)
            elif boundary == "wrap":
                rings = levels[np.mod(ky, rows), np.mod(kx, cols)]
            else:
                rings = levels[np.clip(ky, 0, rows - 1), np.clip(kx, 0, cols - 1)]
            recs, tris = _fans(px, py, kind, vid, t, count, rings, area[f] < 0)
            recs["face"] = f[recs["pair"]]
            parts.append(recs)
            tri_parts.append(tris + offset)
            face_parts.append(f[recs["pair"][tris[:, 0]]])
            offset += len(recs["x"])
    # degenerate UV triangles stay whole: heights at their corners
    flat = np.flatnonzero(~usable)
    if len(flat):
        c = faces[flat].ravel()
        parts.append(
            {
                "x": X[c],
                "y": Y[c],
                "kind": np.full(len(c), CORNER),
                "vid": c,
                "t": np.zeros(len(c)),
                "pair": np.zeros(len(c), np.int64),
                "face": np.repeat(flat, 3),
                "fresh": np.zeros(len(c), bool),
            }
        )
        tri_parts.append(offset + np.arange(len(c)).reshape(-1, 3))
        face_parts.append(flat)
    vertices = {
        k: np.concatenate([p[k] for p in parts]) for k in ("x", "y", "kind", "vid", "t", "face", "fresh")
    }
    return vertices, np.concatenate(tri_parts), np.concatenate(face_parts)


def _group(*columns) -> np.ndarray:
    """Return ``(N,)`` int64 ids of the integer ``columns``' distinct rows, and the first row of each.

    They are found by a lexicographic sort, far faster than ``np.unique(axis=0)``.
    """
    order = np.lexsort(columns[::-1])
    diff = np.zeros(len(order), bool)
    diff[0] = True
    for c in columns:
        cs = c[order]
        diff[1:] |= cs[1:] != cs[:-1]
    ids = np.empty(len(order), np.int64)
    ids[order] = np.cumsum(diff) - 1
    return ids, order[diff]


def _edge_ends(base, face: np.ndarray, e: np.ndarray):
    """Return the lower and higher vertex ids of edge ``e`` (corner ``e`` to ``e + 1``) of ``face``."""
    tri = base.faces[face]
    a = np.take_along_axis(tri, e[:, None].astype(np.int64), 1)[:, 0]
    b = np.take_along_axis(tri, ((e + 1) % 3)[:, None].astype(np.int64), 1)[:, 0]
    return np.minimum(a, b), np.maximum(a, b)


def _unique_vertices(base, v: dict, tris: np.ndarray):
    """Return the distinct vertices of the records ``v`` and ``tris`` in their indices.

    Triangles that collapsed are dropped. On its side of any seam a vertex is: a base corner by its id; an
    edge point by its edge's two vertex ids and ``t``; a cell corner by its triangle and texel position (exact
    half-integers); a fan's centre or ring point (``fresh``) is its piece's alone.
    """
    n = len(v["kind"])
    ident = np.full(n, -1, np.int64)
    first_rows, count = [], 0
    kind, fresh = v["kind"], v["fresh"]
    groups = [np.flatnonzero(fresh)]
    c = np.flatnonzero((kind == CORNER) & ~fresh)
    e = np.flatnonzero((kind == EDGE) & ~fresh)
    i = np.flatnonzero((kind == INSIDE) & ~fresh)
    a, b = _edge_ends(base, v["face"][e], v["vid"][e])
    keyed = [
        (c, (v["vid"][c],)),
        (e, (a, b, np.ascontiguousarray(v["t"][e], np.float64).view(np.int64))),
        (i, (v["face"][i], np.rint(2 * v["x"][i]).astype(np.int64), np.rint(2 * v["y"][i]).astype(np.int64))),
    ]
    ident[groups[0]] = np.arange(len(groups[0]))
    first_rows.append(groups[0])
    count = len(groups[0])
    for rows, cols in keyed:
        if len(rows) == 0:
            continue
        ids, first = _group(*cols)
        ident[rows] = count + ids
        first_rows.append(rows[first])
        count += len(first)
    first = np.concatenate(first_rows)
    u = {k: arr[first] for k, arr in v.items() if k != "fresh"}
    f = ident[tris]
    ok = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])
    return u, f, ok


def _weld_edge(base, u: dict):
    """Return, per vertex, its weld edge key, its ``t`` along that edge and its weld id.

    The key is ``wlo * W + whi`` (edge points; -1 otherwise), ``t`` runs along the edge from ``wlo`` (edge
    points), and the weld id is the corners' (-1 otherwise).
    """
    W = int(base.weld.max()) + 1
    e = u["kind"] == EDGE
    E = np.full(len(e), -1, np.int64)
    t3 = np.zeros(len(e))
    a, b = _edge_ends(base, u["face"][e], u["vid"][e])
    wa, wb = base.weld[a], base.weld[b]
    E[e] = np.minimum(wa, wb) * W + np.maximum(wa, wb)
    t3[e] = np.where(wa < wb, u["t"][e], 1.0 - u["t"][e])
    w = np.where(u["kind"] == CORNER, base.weld[np.maximum(u["vid"], 0)], -1)
    return E, t3, w, W


def _snap(E: np.ndarray, t3: np.ndarray, eps: float = 1e-9) -> np.ndarray:
    """Return ``t3`` with a weld edge's points closer than ``eps`` given their cluster's lowest ``t``.

    Both sides of a seam cut at the same grid line then share one point.
    """
    on = np.flatnonzero(E >= 0)
    order = on[np.lexsort((t3[on], E[on]))]
    e, t = E[order], t3[order]
    start = np.ones(len(order), bool)
    start[1:] = (e[1:] != e[:-1]) | (t[1:] - t[:-1] > eps)
    rep = t[np.maximum.accumulate(np.where(start, np.arange(len(order)), 0))]
    out = t3.copy()
    out[order] = rep
    return out


def _seam_keys(base, W: int) -> np.ndarray:
    """Sorted weld-edge keys of the UV seams: edges whose triangles meet with different vertices."""
    tri = base.faces
    a, b = tri, np.roll(tri, -1, axis=1)
    wa, wb = base.weld[a], base.weld[b]
    E = (np.minimum(wa, wb) * W + np.maximum(wa, wb)).ravel()
    pair = (np.minimum(a, b) * len(base.weld) + np.maximum(a, b)).ravel()
    order = np.lexsort((pair, E))
    E, pair = E[order], pair[order]
    differs = (E[1:] == E[:-1]) & (pair[1:] != pair[:-1])
    return np.unique(E[1:][differs])


def _edge_on(u: dict, E, t3, w, W: int, i: np.ndarray, j: np.ndarray):
    """Return, for triangle edges ``(i, j)``, the weld edge both ends lie on and their ``t`` along it.

    ``i`` and ``j`` are vertex indices; the weld edge is -1 where there is none.
    """
    ki, kj = u["kind"][i], u["kind"][j]
    key = np.full(len(i), -1, np.int64)
    ti, tj = t3[i].copy(), t3[j].copy()
    ee = (ki == EDGE) & (kj == EDGE) & (E[i] == E[j])
    key[ee] = E[i][ee]
    for a, b, _ta, tb in ((i, j, ti, tj), (j, i, tj, ti)):  # an edge point and a corner
        ec = (u["kind"][a] == EDGE) & (u["kind"][b] == CORNER)
        lo, hi = E[a] // W, E[a] % W
        at_lo, at_hi = ec & (w[b] == lo), ec & (w[b] == hi)
        key[at_lo | at_hi] = E[a][at_lo | at_hi]
        tb[at_lo], tb[at_hi] = 0.0, 1.0
    cc = (ki == CORNER) & (kj == CORNER) & (w[i] != w[j])
    lo, hi = np.minimum(w[i], w[j]), np.maximum(w[i], w[j])
    key[cc] = (lo * W + hi)[cc]
    ti[cc], tj[cc] = np.where(w[i] < w[j], 0.0, 1.0)[cc], np.where(w[i] < w[j], 1.0, 0.0)[cc]
    return key, ti, tj


def _stitch(base, u: dict, faces: np.ndarray, base_face: np.ndarray, eps: float = 1e-9):
    """Put every point of a seam's either side on both (module docstring, "Seams").

    Each triangle with an edge on a seam is fanned from its third vertex through the other side's points on
    that edge. ``u`` gains the new edge points (``t3`` their place along the weld edge).
    """
    E, t3, w, W = _weld_edge(base, u)
    t3 = _snap(E, t3, eps)
    seams = _seam_keys(base, W)
    u = dict(u, t3=t3)
    if len(seams) == 0:
        return u, faces, base_face
    on = np.isin(E, seams)
    pts = {}
    for e, t in zip(E[on], t3[on]):
        pts.setdefault(int(e), set()).add(float(t))
    pts = {e: np.array(sorted(ts)) for e, ts in pts.items()}
    for _ in range(3):  # a triangle on two seams: again
        new_faces, new_base, added = [], [], {k: [] for k in ("kind", "vid", "face", "t", "x", "y", "t3")}
        count = len(u["kind"])
        changed = np.zeros(len(faces), bool)
        # only a triangle with two vertices on base edges or corners can have an edge on a seam
        near = np.flatnonzero((u["kind"][faces] != INSIDE).sum(1) >= 2)
        for c in range(3):
            i, j, k = faces[near, c], faces[near, (c + 1) % 3], faces[near, (c + 2) % 3]
            key, ti, tj = _edge_on(u, E, u["t3"], w, W, i, j)
            hit = np.flatnonzero(np.isin(key, seams) & ~changed[near])
            for h in hit:
                f = near[h]
                ts = pts.get(int(key[h]))
                if ts is None:
                    continue
                lo, hi = min(ti[h], tj[h]), max(ti[h], tj[h])
                inner = ts[(ts > lo + eps) & (ts < hi - eps)]
                if len(inner) == 0:
                    continue
                if ti[h] > tj[h]:
                    inner = inner[::-1]
                ids = _new_edge_points(base, u, added, int(base_face[f]), int(key[h]), inner, W, count)
                count += len(ids)
                chain = [int(i[h]), *ids, int(j[h])]
                new_faces += [(chain[m], chain[m + 1], int(k[h])) for m in range(len(chain) - 1)]
                new_base += [int(base_face[f])] * (len(chain) - 1)
                changed[f] = True
        if not changed.any():
            break
        u = {key_: np.concatenate([u[key_], np.asarray(added[key_], u[key_].dtype)]) for key_ in u}
        E, _, w, W = _weld_edge(base, u)
        faces = np.concatenate([faces[~changed], np.array(new_faces, np.int64).reshape(-1, 3)])
        base_face = np.concatenate([base_face[~changed], np.array(new_base, np.int64)])
    return u, faces, base_face


def _new_edge_points(base, u, added: dict, face: int, E: int, ts, W: int, first: int) -> list[int]:
    """Edge points at ``ts`` along weld edge ``E`` on ``face``'s side; their indices from ``first``."""
    tri = base.faces[face]
    for e in range(3):
        a, b = tri[e], tri[(e + 1) % 3]
        wa, wb = base.weld[a], base.weld[b]
        if min(wa, wb) * W + max(wa, wb) == E:
            break
    lo_v = min(a, b)
    lo_w_is_lo_v = base.weld[lo_v] == min(wa, wb)
    ids = []
    for t in ts:
        t_side = t if lo_w_is_lo_v else 1.0 - t
        for key, val in (
            ("kind", EDGE),
            ("vid", e),
            ("face", face),
            ("t", t_side),
            ("x", 0.0),
            ("y", 0.0),
            ("t3", t),
        ):
            added[key].append(val)
        ids.append(first + len(ids))
    return ids


def mesh(
    base,
    texels: tuple[int, int],
    boundary: str,
    *,
    height_texels: np.ndarray | None = None,
    tolerance: float | None = None,
) -> dict:
    """Return the cut base mesh (module docstring).

    It holds per vertex ``positions`` (on the base mesh), ``normals``, ``tangents`` (xyz and ``w``), ``uvs``
    and ``weld`` (one id per place, across seams); ``faces`` counterclockwise as the base's and ``base_face``
    the triangle each came from.
    """
    rows, cols = texels
    v, tris, base_face = cut(base, texels, boundary, height_texels=height_texels, tolerance=tolerance)
    u, faces, ok = _unique_vertices(base, v, tris)
    faces, base_face = faces[ok], base_face[ok]
    u, faces, base_face = _stitch(base, u, faces, base_face)
    used = np.zeros(len(u["kind"]), bool)
    used[faces.ravel()] = True  # a piece's unused slots: no vertex
    u = {k: a[used] for k, a in u.items()}
    faces = (np.cumsum(used) - 1)[faces]
    out = _attributes(base, u, rows, cols)
    out.update(faces=faces, base_face=base_face)
    return out


def _attributes(base, u: dict, rows: int, cols: int) -> dict:
    """Return the positions, frames, UVs and weld ids of the vertices ``u``.

    Corners are taken as the base's, edge points from their edge's two ends, inside points from their
    triangle's UV map (module docstring, "Canonical points").
    """
    n_v = len(u["kind"])
    first_of_weld = np.zeros(int(base.weld.max()) + 1, np.int64)
    first_of_weld[base.weld[::-1]] = np.arange(len(base.weld))[::-1]
    Pw = base.positions[first_of_weld]  # one position per weld id
    P, N, T, UV = np.zeros((n_v, 3)), np.zeros((n_v, 3)), np.zeros((n_v, 4)), np.zeros((n_v, 2))
    weld = np.zeros(n_v, np.int64)
    W = len(Pw)
    c = np.flatnonzero(u["kind"] == CORNER)
    vid = u["vid"][c]
    P[c], N[c], T[c], UV[c], weld[c] = (
        Pw[base.weld[vid]],
        base.normals[vid],
        base.tangents[vid],
        base.uvs[vid],
        base.weld[vid],
    )
    e = np.flatnonzero(u["kind"] == EDGE)
    a, b = _edge_ends(base, u["face"][e], u["vid"][e])
    t = u["t"][e][:, None]
    N[e] = (1 - t) * base.normals[a] + t * base.normals[b]
    T[e] = (1 - t) * base.tangents[a] + t * base.tangents[b]
    UV[e] = (1 - t) * base.uvs[a] + t * base.uvs[b]
    wa, wb = base.weld[a], base.weld[b]
    lo, hi = np.minimum(wa, wb), np.maximum(wa, wb)
    t3 = u["t3"][e][:, None]
    P[e] = Pw[lo] + t3 * (Pw[hi] - Pw[lo])
    ek = np.stack([lo, hi, np.ascontiguousarray(u["t3"][e]).view(np.int64)], 1)
    _, inv = np.unique(ek, axis=0, return_inverse=True)
    weld[e] = W + inv.ravel()
    W += int(inv.max()) + 1 if len(e) else 0
    i = np.flatnonzero(u["kind"] == INSIDE)
    bary = _barycentric(base, u["face"][i], u["x"][i] / cols, u["y"][i] / rows)
    corners = base.faces[u["face"][i]]

    def mix(values):
        return np.einsum("kc,kcd->kd", bary, values[corners])

    P[i], N[i], T[i] = mix(Pw[base.weld]), mix(base.normals), mix(base.tangents)
    UV[i] = np.stack([u["x"][i] / cols, u["y"][i] / rows], 1)
    weld[i] = W + np.arange(len(i))
    N = tg.normalize(N)
    T = np.concatenate([tg.reject(T[:, :3], N), tg.sign(T[:, 3])[:, None]], 1)
    return {"positions": P, "normals": N, "tangents": T, "uvs": UV, "weld": weld}


def _barycentric(base, face: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``(n, 3)`` barycentric weights of UV points ``(u, v)`` in their triangles ``face``."""
    uv = base.uvs[base.faces[face]]  # (n, 3, 2)
    e1, e2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    q = np.stack([u, v], 1) - uv[:, 0]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    b1 = (q[:, 0] * e2[:, 1] - q[:, 1] * e2[:, 0]) / det
    b2 = (e1[:, 0] * q[:, 1] - e1[:, 1] * q[:, 0]) / det
    return np.stack([1.0 - b1 - b2, b1, b2], 1)
