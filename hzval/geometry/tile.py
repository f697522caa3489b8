"""The displaced triangle mesh: the surface that the ground truth renders.

One vertex per texel centre at ``(x, y, h)`` in texel units (x, y from
:func:`hzval.core.conventions.texel_centres`, ``h = H * depth * cols``); between
them the surface is the *bilinear* interpolation of the four centres of each
cell, the surface every technique's bilinear filter reads, tessellated with no
preferred diagonal to within a tolerance (:func:`tessellate`, :func:`cell_levels`;
docs/truth-surface.md), so that a map mirrored, rotated or transposed is the
same surface mirrored, rotated or transposed. The mesh lives in the same
tangent space as the technique's textures, so a camera looking down -z sees
pixel ``(row, col)`` of both at the same surface point.

Boundaries (docs/ARCHITECTURE.md):

``wrap``
    The mesh carries a margin of neighbouring tiles around the central one,
    wide enough that a shadow ray from the tile toward a light at the
    sweep's lowest elevation ``e_min`` rises above the highest point before it
    leaves the mesh: ``margin = ceil(relief / tan(e_min)) + 1`` texels.
``open``
    A terrain: nothing outside the image. The centres' grid is extended by
    half a texel to the image border with the edge heights (a flat skirt), so
    the mesh covers exactly ``[0, cols] x [0, rows]``.

UVs are image coordinates, ``(0, 0)`` at the top-left corner, as Mitsuba's
bitmap texture indexes its rows; they run past [0, 1] in the wrap margin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hzval.core import budget, errors, resources
from hzval.core import conventions as cv
from hzval.core.backend import mi  # Dr.Jit loads at first use, once the LLVM is chosen
from hzval.core.conventions import normal_map
from hzval.core.errors import InputError
from hzval.io import atomic

__all__ = [
    "MIN_ELEVATION_DEG",
    "MAX_MARGIN_TILES",
    "MIN_MARGIN_CAP",
    "Grid",
    "wrap_margin",
    "grid",
    "vertex_normals",
    "triangles",
    "displaced_mesh",
    "write_ply",
    "DEFAULT_TOLERANCE",
    "PLANAR_TWIST",
    "MAX_LEVEL",
    "twists",
    "cell_levels",
    "triangle_count",
    "mesh_size",
    "check_fits",
    "tessellate",
    "piece",
    "piece_mesh",
    "row_triangles",
    "edge_level",
]

#: Lowest light elevation, in degrees, whose shadows the wrap margin must hold.
MIN_ELEVATION_DEG = 10.0
#: The truth's wrap margin (``capped``) is at most :data:`MIN_MARGIN_CAP` texels, or this many tile
#: widths if more: a deep relief would otherwise ask for a margin of ``relief / tan(10 deg)`` (depth 5
#: on 512 texels: 14,500 texels a side, a mesh of 30,000 x 30,000 vertices). Rays that need more than
#: the margin hop (docs/internals.md, the truth's "Boundaries"), each hop as far as the mesh reaches
#: from where it starts (the tile's width from most points), so the cap costs a second hop to the rays that
#: leave near the tile's edge, not accuracy; a margin for the whole shadow was a fifth of the mesh
#: (the 2048 bricks at 30 degrees: 165 texels, 36.7M triangles against 28.9M with 32).
MAX_MARGIN_TILES = 0.0
MIN_MARGIN_CAP = 32


@dataclass(frozen=True)
class Grid:
    """The vertex grid of a displaced mesh, before it becomes a Mitsuba mesh.

    ``x``, ``y``: vertex coordinates along columns and rows (1-D, texel
    units); ``z``: ``(len(y), len(x))`` heights; ``margin``: texels of
    neighbouring tiles on each side (0 for ``open``).
    """

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    margin: int


def wrap_margin(
    h_texels: np.ndarray, min_elevation_deg: float = MIN_ELEVATION_DEG, *, capped: bool = False
) -> int:
    """Texels of neighbouring tiles that a wrap mesh needs on each side.

    A shadow ray toward elevation ``e`` rises ``tan(e)`` per texel, so past
    ``relief / tan(e)`` texels it is above every point of the surface.
    ``capped``: at most :data:`MIN_MARGIN_CAP` texels (or :data:`MAX_MARGIN_TILES` of the tile's
    smaller side, if more), for a renderer whose rays hop.
    """
    relief = float(np.max(h_texels) - np.min(h_texels))
    need = int(math.ceil(relief / math.tan(math.radians(min_elevation_deg)))) + 1
    if not capped:
        return need
    return min(need, max(MIN_MARGIN_CAP, int(MAX_MARGIN_TILES * min(np.shape(h_texels)))))


def grid(
    h_texels: np.ndarray,
    boundary: str,
    *,
    min_elevation_deg: float = MIN_ELEVATION_DEG,
    margin: int | None = None,
) -> Grid:
    """Vertex grid of the displaced surface for heights in texel units."""
    h = np.asarray(h_texels, dtype=np.float32)
    rows, cols = h.shape
    xc, yc = cv.texel_centres(rows, cols)
    xc, yc = xc[0], yc[:, 0]
    if boundary == "wrap":
        m = wrap_margin(h, min_elevation_deg) if margin is None else int(margin)
        z = cv.pad_heights(h, m, "wrap")
        x = np.concatenate([xc[0] - np.arange(m, 0, -1), xc, xc[-1] + np.arange(1, m + 1)])
        y = np.concatenate([yc[0] + np.arange(m, 0, -1), yc, yc[-1] - np.arange(1, m + 1)])
        return Grid(x, y, z, m)
    if boundary == "open":
        z = np.pad(h, 1, mode="edge")
        x = np.concatenate([[0.0], xc, [float(cols)]])
        y = np.concatenate([[float(rows)], yc, [0.0]])
        return Grid(x, y, z, 0)
    raise ValueError(f"unknown boundary {boundary!r}")


def vertex_normals(h_texels: np.ndarray, positions: np.ndarray, boundary: str) -> np.ndarray:
    """Return the normal map's normals interpolated bilinearly at each vertex and normalised.

    The result is ``(V, 3)`` float32: the normals of :func:`hzval.core.conventions.normal_map`, interpolated
    between texel centres at each vertex's ``(x, y)``, as the truth's ``smooth`` shading reads them
    (docs/internals.md, the truth's "Shading"). A texel centre takes its texel's normal, a margin vertex that
    of the texel it repeats (``wrap``), the skirt the border's (``open``, clamped).
    """
    nmap = normal_map(np.asarray(h_texels, np.float32), boundary)
    n = cv.bilinear_at(nmap, positions[:, 0], positions[:, 1], boundary)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return np.ascontiguousarray(n, dtype=np.float32)


def triangles(n_rows: int, n_cols: int) -> np.ndarray:
    """Faces ``(2 (n_rows-1)(n_cols-1), 3)`` uint32 of a vertex grid, counterclockwise from +z.

    Vertex ``(r, c)`` has index ``r * n_cols + c``; row index grows toward -y,
    so the quad's corners ``a = (r, c), b = (r, c+1), d = (r+1, c)`` run
    clockwise on screen unless ordered ``a, d, b``: each quad is split along
    the ``b``-``d`` diagonal into ``(a, d, b)`` and ``(b, d, e)``.
    """
    # written straight into uint32 (a grid of more than 2^32 vertices could not be a mesh anyway):
    # no int64 index grids, a fifth of the time for the 2048 bricks' 11.3M faces
    a = (
        np.arange(n_rows - 1, dtype=np.uint32)[:, None] * np.uint32(n_cols)
        + np.arange(n_cols - 1, dtype=np.uint32)[None, :]
    ).ravel()
    faces = np.empty((a.size, 2, 3), np.uint32)
    b, d = faces[:, 0, 2], faces[:, 0, 1]
    faces[:, 0, 0] = a
    np.add(a, 1, out=b)
    np.add(a, n_cols, out=d)
    faces[:, 1, 0], faces[:, 1, 1] = b, d
    np.add(d, 1, out=faces[:, 1, 2])
    return faces.reshape(-1, 3)


def displaced_mesh(
    height: np.ndarray,
    depth: float,
    boundary: str,
    *,
    min_elevation_deg: float = MIN_ELEVATION_DEG,
    margin: int | None = None,
    normals: bool = False,
    texcoords: bool = True,
    name: str = "displaced",
    tolerance: float | None = None,
    info: dict | None = None,
    budget_bytes: int | None = None,
):
    """Return the displaced surface of a normalised height map as a ``mitsuba.Mesh``.

    The surface is the bilinear interpolation of the texel centres' heights, tessellated to within
    ``tolerance`` texels (:func:`tessellate`; default :data:`DEFAULT_TOLERANCE`), margin and skirt included.

    ``texcoords``: each vertex's texture coordinates (:func:`hzval.core.conventions.tangent_to_uv`), for
    a file that others texture; the truth reads none (``False``: 0.3 s and 0.2 GB less at 2048).

    ``normals=True`` adds vertex normals: the normal map's normals (:func:`hzval.core.conventions.normal_map`,
    the very central differences the techniques shade with) interpolated bilinearly at each vertex
    (:func:`vertex_normals`), as the truth shades. Mitsuba interpolates them over each triangle for
    its shading frame (``si.sh_frame.n``); without them it shades with the
    triangles' own normals. Needs a Mitsuba variant to be set
    (:func:`hzval.core.backend.variant`). ``budget_bytes``: as :func:`tessellate`'s. ``info``: a dict that
    receives the cells' ``levels``
    (:func:`cell_levels`) and the ``tolerance`` used.
    """
    h = cv.heights_in_texels(height, depth)
    rows, cols = h.shape
    g = grid(h, boundary, min_elevation_deg=min_elevation_deg, margin=margin)
    positions, faces, levels = tessellate(
        g, DEFAULT_TOLERANCE if tolerance is None else tolerance, budget_bytes=budget_bytes
    )
    mesh = mi.Mesh(
        name, len(positions), len(faces), has_vertex_normals=normals, has_vertex_texcoords=texcoords
    )
    params = mi.traverse(mesh)
    params["vertex_positions"] = mi.Float(positions.ravel())
    params["faces"] = mi.UInt32(faces.ravel())
    del faces
    if texcoords:
        params["vertex_texcoords"] = mi.Float(
            np.stack(cv.tangent_to_uv(positions[:, 0], positions[:, 1], rows, cols), axis=-1).ravel()
        )
    if normals:
        params["vertex_normals"] = mi.Float(vertex_normals(h, positions, boundary).ravel())
    params.update()
    if info is not None:
        info.update(levels=levels, tolerance=DEFAULT_TOLERANCE if tolerance is None else float(tolerance))
    return mesh


def write_ply(m, path) -> None:
    """Write the Mitsuba mesh ``m`` to ``path`` as PLY, atomically (:func:`hzval.io.atomic.atomic_path`).

    Mitsuba reports a failed write (a full disk) as a ``RuntimeError`` with its own text; it is one line
    naming the file here (:class:`hzval.core.errors.InputError`).
    """
    with atomic.atomic_path(path) as tmp:
        try:
            m.write_ply(str(tmp))
        except RuntimeError as exc:
            problem = errors.first_line(exc).rpartition(": ")[2] or "cannot be written"
            raise InputError(path, problem) from None


# ----------------------------------------------------------------------
# The bilinear surface
# ----------------------------------------------------------------------

#: Default :func:`cell_levels` tolerance, texels of height: the largest vertical distance allowed
#: between the triangles and the bilinear surface (docs/truth-surface.md, the convergence study:
#: halving it moves mean V by at most 0.0016 and horizon's |F - V| by at most 0.7% on every map
#: measured, the 2048 bricks' relief included).
DEFAULT_TOLERANCE = 0.08
#: A cell whose twist is at most this share of the largest height (and of 1 texel) is planar: the
#: rounding of float32 heights (2^-24 of them) leaves twists of a few of their ulps.
PLANAR_TWIST = 2.0**-20
#: Most fans per side of one cell: a cell of twist ``t`` texels is then within ``t / 4096`` texels.
MAX_LEVEL = 16


def twists(z: np.ndarray) -> np.ndarray:
    """Return each cell's twist ``h00 - h10 - h01 + h11`` (texels), ``(ny-1, nx-1)`` float64.

    It is the ``d`` of the bilinear patch ``a + b u + c v + d u v`` on its four corners; 0 for a planar cell.
    """
    z = np.asarray(z, np.float64)
    return z[:-1, :-1] - z[:-1, 1:] - z[1:, :-1] + z[1:, 1:]


def cell_levels(z: np.ndarray, tolerance: float) -> np.ndarray:
    """Return how each cell of a vertex grid of heights ``z`` (texels) is tessellated.

    The result is ``(ny-1, nx-1)`` uint8, chosen so that no point of a cell's triangles is more than
    ``tolerance`` texels above or below the bilinear surface of its four corners.

    0: a planar cell (twist ``d`` = 0 to the heights' rounding, :func:`twists`,
    :data:`PLANAR_TWIST`), two triangles, either way round: they are the bilinear patch. ``n >= 1`` (a power
    of two up to :data:`MAX_LEVEL`): ``n x n`` sub-cells, each four
    triangles around its centre, a point of the bilinear surface (the mean of its corners), so that no
    diagonal is preferred; the patch minus its fan is ``d' (uv - v/2)`` on a sub-cell's lower triangle
    (``d' = d / n^2``), at most ``|d| / (16 n^2)`` (at ``u = v = 1/4``), zero-mean, and 0 along the
    sub-cells' edges, so neighbouring cells meet on the bilinear surface's own (straight) cell edges
    whatever their levels. Two triangles of a twisted cell would be ``|d| / 4`` off at its centre
    and biased by ``d / 12`` in volume, one way or the other by the diagonal: on a grainy photo that
    bias moved horizon's |F - V| by 2.5% between tolerances 0.04 and 0.02 (docs/truth-surface.md).
    """
    if not (isinstance(tolerance, (int, float)) and math.isfinite(tolerance) and tolerance > 0):
        raise ValueError(f"tolerance must be a positive number of texels, got {tolerance!r}")
    a = np.abs(twists(z))
    need = np.sqrt(a / (16.0 * tolerance))
    level = np.where(need <= 1.0, 1.0, 2.0 ** np.ceil(np.log2(np.maximum(need, 1.0))))
    level = np.minimum(level, MAX_LEVEL).astype(np.uint8)
    # planar to the float32 heights' own rounding (a ramp of slope 0.3 has twists of 1e-8 texels)
    level[a <= PLANAR_TWIST * max(1.0, float(np.max(np.abs(z), initial=0.0)))] = 0
    return level


def _fan_template(n: int):
    """Return the local tessellation of a cell at level ``n`` as ``(uv, faces)``.

    ``uv`` is ``(k, 2)`` float64 of its vertices that are not the cell's corners (sub-grid nodes, then
    sub-cell centres) and ``faces`` ``(4 n^2, 3)`` int64 of local indices, 0-3 the corners ``a (u=0, v=0), b
    (1, 0), d (0, 1), e (1, 1)`` and ``4 + i`` vertex ``i`` of ``uv``. ``u`` runs with the columns, ``v`` with
    the rows (toward -y), so that ``(A, M, B)`` around the sub-cell's corners is counterclockwise seen from
    +z, as :func:`triangles`.
    """
    code = np.full((n + 1, n + 1), -1, np.int64)
    code[0, 0], code[0, n], code[n, 0], code[n, n] = 0, 1, 2, 3
    nodes = [(i, j) for i in range(n + 1) for j in range(n + 1) if code[i, j] < 0]
    for k, (i, j) in enumerate(nodes):
        code[i, j] = 4 + k
    uv = [(j / n, i / n) for i, j in nodes] + [
        ((j + 0.5) / n, (i + 0.5) / n) for i in range(n) for j in range(n)
    ]
    faces = []
    for i in range(n):
        for j in range(n):
            A, B, C, D = code[i, j], code[i, j + 1], code[i + 1, j + 1], code[i + 1, j]
            M = 4 + len(nodes) + i * n + j
            faces += [(A, M, B), (B, M, C), (C, M, D), (D, M, A)]
    return np.array(uv, np.float64).reshape(-1, 2), np.array(faces, np.int64)


def _bilinear(g: Grid, r: np.ndarray, c: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Return the points of the bilinear patches of cells ``(r, c)`` at ``uv``.

    The result is ``(len(r), len(uv), 3)`` float32, from the same float64 expression for every cell, so a node
    on a shared edge has the same bits from either side (the other corners' weights are exactly 0 there).
    """
    u, v = uv[None, :, 0], uv[None, :, 1]
    x = (1.0 - u) * g.x[c][:, None] + u * g.x[c + 1][:, None]
    y = (1.0 - v) * g.y[r][:, None] + v * g.y[r + 1][:, None]
    z = g.z.astype(np.float64, copy=False)
    zz = (1.0 - v) * ((1.0 - u) * z[r, c][:, None] + u * z[r, c + 1][:, None]) + v * (
        (1.0 - u) * z[r + 1, c][:, None] + u * z[r + 1, c + 1][:, None]
    )
    return np.stack([x, y, zz], axis=-1).astype(np.float32)


def triangle_count(levels: np.ndarray) -> int:
    """Triangles of a tessellation of these cell levels (:func:`cell_levels`)."""
    counts = np.bincount(levels.ravel(), minlength=MAX_LEVEL + 1).astype(np.int64)
    n = np.arange(len(counts), dtype=np.int64)
    return int(2 * counts[0] + np.sum(4 * n[1:] ** 2 * counts[1:]))


def mesh_size(
    h_texels: np.ndarray, boundary: str, margin: int | None = None, tolerance: float = DEFAULT_TOLERANCE
) -> tuple[int, int]:
    """Return ``(vertices, triangles)`` of :func:`displaced_mesh`'s mesh of heights ``h_texels``.

    The heights are in texels. They are counted without building its grid: a ``wrap`` mesh's margin repeats
    the tile, so its cells' levels (:func:`cell_levels`) are the tile's own, each counted as often as the
    margin repeats it. ``margin``: as :func:`grid`'s (default :func:`wrap_margin`).

    Examples
    --------
    >>> import numpy as np
    >>> mesh_size(np.zeros((4, 4)), "wrap", margin=0)
    (16, 18)
    >>> mesh_size(np.zeros((4, 4)), "wrap", margin=2)
    (64, 98)
    """
    h = np.asarray(h_texels, np.float32)
    rows, cols = h.shape
    if boundary != "wrap":
        g = grid(h, boundary)
        return _size(g.z.shape, cell_levels(g.z, tolerance), 1, 1)
    m = wrap_margin(h, MIN_ELEVATION_DEG) if margin is None else int(margin)
    levels = cell_levels(np.pad(h, ((0, 1), (0, 1)), mode="wrap"), tolerance)  # the periodic cells
    # padded cell (k, j) is the tile's cell ((k - m) mod rows, (j - m) mod cols)
    per_row = np.bincount((np.arange(rows + 2 * m - 1) - m) % rows, minlength=rows)
    per_col = np.bincount((np.arange(cols + 2 * m - 1) - m) % cols, minlength=cols)
    return _size((rows + 2 * m, cols + 2 * m), levels, per_row, per_col)


def _size(shape: tuple[int, int], levels: np.ndarray, per_row, per_col) -> tuple[int, int]:
    """Return ``(vertices, triangles)`` of a grid of ``shape`` vertices whose cells are repeated.

    Cell ``(r, c)`` of ``levels`` is repeated ``per_row[r] * per_col[c]`` times.
    """
    weight = np.outer(np.broadcast_to(per_row, levels.shape[:1]), np.broadcast_to(per_col, levels.shape[1:]))
    counts = np.bincount(levels.ravel(), weights=weight.ravel().astype(np.float64), minlength=MAX_LEVEL + 1)
    n = np.arange(len(counts), dtype=np.float64)
    triangles = 2 * counts[0] + np.sum(4 * n[1:] ** 2 * counts[1:])
    # a fanned cell adds its sub-grid's inner nodes and its sub-cells' centres
    extra = np.sum(((n[1:] + 1) ** 2 - 4 + n[1:] ** 2) * counts[1:])
    return int(shape[0]) * int(shape[1]) + int(extra), int(triangles)


def check_fits(
    what, height: np.ndarray, depth: float, boundary: str, *, margin: int | None = None, also: float = 0
) -> int:
    """Refuse, before its grid is allocated, a :func:`displaced_mesh` too large for the memory available.

    The mesh is of the normalised ``height`` at ``depth``; the check is
    :func:`hzval.core.resources.refuse_over` on its triangles (:func:`mesh_size`) at
    :data:`hzval.core.budget.MESH_BYTES_PER_TRIANGLE`, and ``also`` bytes held beside it. A tall relief asks
    for a wide wrap margin and fine cells; the line names ``what`` (the map), its height range and
    ``--depth``. Returns the estimate in bytes.
    """
    h = cv.heights_in_texels(height, depth)
    rows, cols = h.shape
    m = (wrap_margin(h) if margin is None else int(margin)) if boundary == "wrap" else 0
    vertices, triangles = mesh_size(h, boundary, m)
    need = budget.mesh_bytes(triangles, also)
    lo, hi = float(np.min(height)), float(np.max(height))
    count = f"{triangles / 1e6:,.0f}M" if triangles >= 1e6 else f"{triangles:,}"
    task = (
        f"the displaced mesh of {cols}x{rows} texels with heights {lo:g} to {hi:g} at --depth {depth:g} "
        f"({count} triangles" + (f", a wrap margin of {m} texels)" if m else ")")
    )
    resources.refuse_over(what, need, task, "a smaller --depth or a smaller map")
    if vertices >= 2**32:
        raise InputError(what, f"{task} has {vertices:.3g} vertices, more than a mesh can index (2^32)")
    return int(need)


def tessellate(
    g: Grid,
    tolerance: float = DEFAULT_TOLERANCE,
    budget_bytes: int | None = None,
    levels: np.ndarray | None = None,
):
    """Return the triangles of the bilinear surface of a vertex grid (:func:`cell_levels`).

    Returns ``(positions, faces, levels)``: ``(V, 3)`` float32 vertices (the grid's ``r * nx + c`` first, then
    each tessellated cell's own), ``(F, 3)`` uint32 faces counterclockwise from +z, and the cells' levels.
    ``budget_bytes``: refuse (:class:`hzval.core.errors.InputError`), before allocating them, triangles that
    would need more (:data:`hzval.core.budget.TRUTH_BYTES_PER_TRIANGLE`). A node on an edge that two fanned
    cells share is made by each (the same bits); where levels differ, the finer cell's nodes lie on the
    coarser one's straight edge. ``levels``: the cells' levels as given (``tolerance`` unused), for a piece of
    a larger grid (:func:`piece`) whose levels were decided on the whole, so that its triangles are the
    whole's own (:func:`cell_levels`' planar rule reads the grid's largest height).
    """
    ny, nx = g.z.shape
    X, Y = np.meshgrid(g.x.astype(np.float32), g.y.astype(np.float32))
    parts = [np.stack([X, Y, g.z.astype(np.float32)], axis=-1).reshape(-1, 3)]
    del X, Y
    levels = cell_levels(g.z, tolerance) if levels is None else np.asarray(levels, np.uint8)
    if budget_bytes is not None:
        n = triangle_count(levels)
        resources.refuse_over(
            "--truth-tolerance",
            n * budget.TRUTH_BYTES_PER_TRIANGLE,
            f"the truth's surface at a tolerance of {tolerance:g} texels ({n / 1e6:.0f}M triangles, "
            "with its BVH)",
            "a larger tolerance or a smaller map",
            have=budget_bytes,
        )
    corner = (
        np.arange(ny - 1, dtype=np.uint32)[:, None] * np.uint32(nx)
        + np.arange(nx - 1, dtype=np.uint32)[None, :]
    )
    base, faces = ny * nx, []
    flat = levels.ravel()
    two = np.flatnonzero(flat == 0)
    if two.size:
        # planar: the two triangles of hzval.geometry.tile.triangles, (a, d, b) and (b, d, e)
        a = corner.ravel()[two]
        f = np.empty((two.size, 2, 3), np.uint32)
        f[:, 0, 0], f[:, 0, 1], f[:, 0, 2] = a, a + np.uint32(nx), a + np.uint32(1)
        f[:, 1, 0], f[:, 1, 1], f[:, 1, 2] = a + np.uint32(1), a + np.uint32(nx), a + np.uint32(nx + 1)
        faces.append(f.reshape(-1, 3))
    for n in sorted(int(k) for k in np.unique(flat) if k > 0):
        cells = np.flatnonzero(flat == n)
        r, c = np.divmod(cells, nx - 1)
        uv, local = _fan_template(n)
        parts.append(_bilinear(g, r, c, uv).reshape(-1, 3))
        a = corner.ravel()[cells]
        idx = np.empty((cells.size, 4 + len(uv)), np.uint32)
        idx[:, 0], idx[:, 1], idx[:, 2], idx[:, 3] = a, a + 1, a + nx, a + nx + 1
        idx[:, 4:] = (
            base + np.arange(cells.size, dtype=np.int64)[:, None] * len(uv) + np.arange(len(uv))[None, :]
        ).astype(np.uint32)
        base += cells.size * len(uv)
        faces.append(idx[:, local].reshape(-1, 3))
    if base >= 2**32:
        raise ValueError("the tessellation has more than 2^32 vertices")
    return np.concatenate(parts), np.concatenate(faces), levels


def piece(g: Grid, first: int, stop: int) -> Grid:
    """Return the vertex rows ``first <= r <= stop`` of ``g``, its cell rows ``first <= i < stop``.

    They keep the same coordinates and heights, so a piece tessellated with the whole's levels
    (:func:`tessellate`) is made of the whole's own triangles, bit for bit.
    """
    return Grid(g.x, g.y[first : stop + 1], g.z[first : stop + 1], g.margin)


def piece_mesh(g: Grid, levels: np.ndarray, first: int, stop: int, name: str = "band"):
    """Return the cell rows ``first <= i < stop`` of the grid ``g`` as a ``mitsuba.Mesh``.

    It has positions and faces only (what the truth reads), tessellated with the whole grid's ``levels``
    (:func:`piece`, :func:`tessellate`): a band of the truth's mesh (:mod:`hzval.truth.bands`).
    """
    positions, faces, _ = tessellate(piece(g, first, stop), levels=levels[first:stop])
    mesh = mi.Mesh(name, len(positions), len(faces), has_vertex_normals=False, has_vertex_texcoords=False)
    params = mi.traverse(mesh)
    params["vertex_positions"] = mi.Float(positions.ravel())
    del positions
    params["faces"] = mi.UInt32(faces.ravel())
    del faces
    params.update()
    return mesh


def row_triangles(levels: np.ndarray) -> np.ndarray:
    """Return the number of triangles in each cell row of a tessellation of these levels, ``(ny-1,)`` int64.

    It is :func:`triangle_count`, row by row.
    """
    lv = np.asarray(levels, np.int64)
    return np.where(lv == 0, 2, 4 * lv * lv).sum(axis=1)


def edge_level(levels: np.ndarray) -> int:
    """Return the finest sub-cell grid of a tessellation: its largest level, at least 1.

    Every edge of the mesh lies on a line ``(x - 1/2) n``, ``(y - 1/2) n`` integer, or on a diagonal of that
    grid's cells.
    """
    return max(1, int(levels.max(initial=0)))
