"""The displaced triangle mesh: the surface that the ground truth renders.

One vertex per texel centre at ``(x, y, h)`` in texel units (x, y from
:func:`hzval.conventions.texel_centres`, ``h = H * depth * cols``), two
triangles per quad of neighbouring centres. The mesh lives in the same
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

from hzval import conventions as cv

#: Lowest light elevation, in degrees, whose shadows the wrap margin must hold.
MIN_ELEVATION_DEG = 10.0
#: The wrap margin is never wider than this many tile widths (nor below :data:`MIN_MARGIN_CAP`
#: texels): a deep relief would otherwise ask for a margin of ``relief / tan(10 deg)`` (depth 5 on
#: 512 texels: 14,500 texels a side, a mesh of 30,000 x 30,000 vertices). Rays that need more
#: than the margin hop (:mod:`hzval.truth`, "Boundaries"), so the cap costs hops, not accuracy.
MAX_MARGIN_TILES = 0.5
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


def wrap_margin(h_texels: np.ndarray, min_elevation_deg: float = MIN_ELEVATION_DEG, *,
                capped: bool = False) -> int:
    """Texels of neighbouring tiles that a wrap mesh needs on each side.

    A shadow ray toward elevation ``e`` rises ``tan(e)`` per texel, so past
    ``relief / tan(e)`` texels it is above every point of the surface.
    ``capped``: at most :data:`MAX_MARGIN_TILES` of the tile's smaller side (at
    least :data:`MIN_MARGIN_CAP` texels), for a renderer whose rays hop.
    """
    relief = float(np.max(h_texels) - np.min(h_texels))
    need = int(math.ceil(relief / math.tan(math.radians(min_elevation_deg)))) + 1
    if not capped:
        return need
    return min(need, max(MIN_MARGIN_CAP, int(MAX_MARGIN_TILES * min(np.shape(h_texels)))))


def grid(h_texels: np.ndarray, boundary: str, *, min_elevation_deg: float = MIN_ELEVATION_DEG,
         margin: int | None = None) -> Grid:
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


def vertex_normals(h_texels: np.ndarray, g: Grid, boundary: str) -> np.ndarray:
    """``(len(g.y), len(g.x), 3)`` float32: the normal map's normal of the texel under each vertex
    (texel centres are vertices; margin vertices repeat the tile, skirt vertices the border)."""
    from hzval.bake import normal_map

    rows, cols = h_texels.shape
    nmap = normal_map(np.asarray(h_texels, np.float32), boundary)
    col = np.floor(g.x).astype(np.int64)
    row = np.floor(rows - np.asarray(g.y, np.float64)).astype(np.int64)
    if boundary == "wrap":
        col, row = col % cols, row % rows
    else:
        col, row = np.clip(col, 0, cols - 1), np.clip(row, 0, rows - 1)
    return np.ascontiguousarray(nmap[row[:, None], col[None, :]], dtype=np.float32)


def triangles(n_rows: int, n_cols: int) -> np.ndarray:
    """Faces ``(2 (n_rows-1)(n_cols-1), 3)`` uint32 of a vertex grid, counterclockwise from +z.

    Vertex ``(r, c)`` has index ``r * n_cols + c``; row index grows toward -y,
    so the quad's corners ``a = (r, c), b = (r, c+1), d = (r+1, c)`` run
    clockwise on screen unless ordered ``a, d, b``: each quad is split along
    the ``b``-``d`` diagonal into ``(a, d, b)`` and ``(b, d, e)``.
    """
    # written straight into uint32 (a grid of more than 2^32 vertices could not be a mesh anyway):
    # no int64 index grids, a fifth of the time for the 2048 bricks' 11.3M faces
    a = (np.arange(n_rows - 1, dtype=np.uint32)[:, None] * np.uint32(n_cols)
         + np.arange(n_cols - 1, dtype=np.uint32)[None, :]).ravel()
    faces = np.empty((a.size, 2, 3), np.uint32)
    b, d = faces[:, 0, 2], faces[:, 0, 1]
    faces[:, 0, 0] = a
    np.add(a, 1, out=b)
    np.add(a, n_cols, out=d)
    faces[:, 1, 0], faces[:, 1, 1] = b, d
    np.add(d, 1, out=faces[:, 1, 2])
    return faces.reshape(-1, 3)


def displaced_mesh(height: np.ndarray, depth: float, boundary: str, *,
                   min_elevation_deg: float = MIN_ELEVATION_DEG, margin: int | None = None,
                   normals: bool = False, texcoords: bool = True, name: str = "displaced"):
    """The displaced surface of a normalised height map as a ``mitsuba.Mesh``.

    ``texcoords``: each vertex's texture coordinates (:func:`hzval.conventions.tangent_to_uv`), for
    a file that others texture; the truth reads none (``False``: 0.3 s and 0.2 GB less at 2048).

    ``normals=True`` adds vertex normals: each vertex takes the normal map's
    normal (:func:`hzval.bake.normal_map`, the very central differences the
    techniques shade with) of the texel it stands on, a margin vertex that of
    the texel it repeats (``wrap``), a skirt vertex on an ``open`` tile's
    border that of the border texel, whose one-sided slope the normal map
    uses (so the skirt is shaded as the techniques shade it, though its
    geometry stays flat). Mitsuba interpolates them over each triangle for
    its shading frame (``si.sh_frame.n``); without them it shades with the
    triangles' own normals. Needs a Mitsuba variant to be set
    (:func:`hzval.backend.variant`).
    """
    import mitsuba as mi

    h = cv.heights_in_texels(height, depth)
    rows, cols = h.shape
    g = grid(h, boundary, min_elevation_deg=min_elevation_deg, margin=margin)
    ny, nx = g.z.shape
    X, Y = np.meshgrid(g.x, g.y)
    positions = np.stack([X, Y, g.z], axis=-1).astype(np.float32)
    faces = triangles(ny, nx)

    mesh = mi.Mesh(name, nx * ny, len(faces), has_vertex_normals=normals, has_vertex_texcoords=texcoords)
    params = mi.traverse(mesh)
    params["vertex_positions"] = mi.Float(positions.ravel())
    params["faces"] = mi.UInt32(faces.ravel())
    if texcoords:
        params["vertex_texcoords"] = mi.Float(np.stack(cv.tangent_to_uv(X, Y, rows, cols), axis=-1).ravel())
    del X, Y, positions
    if normals:
        params["vertex_normals"] = mi.Float(vertex_normals(h, g, boundary).ravel())
    params.update()
    return mesh


def write_ply(m, path) -> None:
    """Write the Mitsuba mesh ``m`` to ``path`` as PLY, atomically (:func:`hzval.files.atomic_path`).
    Mitsuba reports a failed write (a full disk) as a ``RuntimeError`` with its own text; it is one
    line naming the file here (:class:`hzval.errors.InputError`)."""
    from hzval import files
    from hzval.errors import InputError

    with files.atomic_path(path) as tmp:
        try:
            m.write_ply(str(tmp))
        except RuntimeError as exc:
            problem = files.first_line(exc).rpartition(": ")[2] or "cannot be written"
            raise InputError(path, problem) from None
