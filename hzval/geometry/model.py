"""The base mesh a material is mapped onto: a built-in shape or the user's UV-mapped model (docs/meshes.md).

Conventions (each one pinned by tests/geometry/test_model.py):

World
    **z up**, as hzval's tangent space and its plane (+z out of the surface). A file whose up
    axis is y is turned to z up by a rotation of +90 degrees about x: ``(x, y, z) -> (x, -z, y)``
    (x stays, y becomes z, z becomes -y), so that glTF's "front" (+z) faces -y.
Up axis of files
    ``up=None`` means **y for every format**: glTF by its spec, and OBJ/PLY because that is what
    the tools that make them write by default (Blender's and Maya's OBJ exporters, photogrammetry
    and sculpting packages: Meshroom, RealityCapture, ZBrush); a z-up file (3ds Max, some CAD) is
    read with ``up="z"`` (``--up z``). The built-in shapes are z up.
UVs
    ``u`` along the image's columns (0 at the left, 1 at the right), ``v`` up the image (0 at the
    bottom row, 1 at the top): OBJ's and PLY's own convention. glTF puts ``v = 0`` at the top row
    (glTF 2.0 spec, "Images": the first pixel is the upper left corner), so its ``v`` is read as
    ``1 - v``. ``uv_scale`` multiplies them (the texture repeats ``uv_scale`` times).
Texture width in the world
    ``world_per_uv = sqrt(world area / UV area)`` over the mesh: the world length of one texture
    width, which turns ``depth`` (in texture widths) into world units. The plane is 1.
Tangent frames
    :mod:`hzval.geometry.tangents`: glTF's ``TANGENT`` when the file has it, else FGED2's
    ``CalculateTangents``.

Readers: OBJ and PLY by trimesh (which splits a vertex where its UVs differ and keeps the file's
normals); glTF and GLB by pygltflib, because trimesh 4-5 drops ``TANGENT`` and keeps
``TEXCOORD_0`` only for primitives that have a material (docs/meshes.md, "Readers").
"""

from __future__ import annotations

import dataclasses
import difflib
import inspect
import math
import os
from dataclasses import dataclass, field
from functools import cached_property
from typing import Callable

import numpy as np

from hzval.core.errors import InputError
from hzval.geometry import gltf, mikktspace
from hzval.geometry import tangents as tg

__all__ = [
    "WELD_TOLERANCE",
    "MAX_DEGENERATE_UV_AREA",
    "UP_AXES",
    "Y_UP_TO_Z_UP",
    "BaseMesh",
    "weld_ids",
    "edge_table",
    "count_seams",
    "seam_edge_ends",
    "smooth_normals",
    "build",
    "to_z_up",
    "plane",
    "CUBE_FACES",
    "cube",
    "sphere",
    "mirrored_sphere",
    "torus",
    "cylinder",
    "SHAPES",
    "read_trimesh",
    "read_gltf",
    "READERS",
    "load",
]

#: Weld tolerance: positions closer than this share of the mesh's bounding-box diagonal are one
#: point (a seam's two copies of a vertex, written from the same float or from sin(2 pi) ~ 1e-16).
WELD_TOLERANCE = 1e-7
#: Degenerate UV triangles (:data:`hzval.geometry.tangents.DEGENERATE_UV`) are tolerated up to this share of
#: the world area (a scan's slivers); more is refused.
MAX_DEGENERATE_UV_AREA = 0.01
#: The sizes (a bounding box's longest side) a mesh may have, in its file's units: the truth traces
#: it in float32, whose products of coordinates underflow or overflow far outside this range.
EXTENT_RANGE = (1e-6, 1e7)
#: The least world area, as a share of the squared size: below it the vertices are collinear.
MIN_AREA_SHARE = 1e-9
#: The least UV area (1 = the whole texture): below it the mesh shows less than a texel of a
#: 16384-wide map (``--uv-scale`` far too small).
MIN_UV_AREA = 1e-10
UP_AXES: tuple[str, ...] = ("y", "z")
#: The rotation that turns a y-up file z up (:data:`hzval.geometry.tangents.Y_UP_TO_Z_UP`).
Y_UP_TO_Z_UP = tg.Y_UP_TO_Z_UP


@dataclass(frozen=True, eq=False)
class BaseMesh:
    """A triangle mesh with UVs and tangent frames, in hzval's world (z up).

    ``positions (V, 3)``, ``normals (V, 3)`` unit, ``uvs (V, 2)`` (u right, v up the image,
    ``uv_scale`` applied), ``faces (F, 3)`` int64 counterclockwise seen from outside,
    ``tangents (V, 4)`` (xyz unit along +u, w = +1/-1: bitangent ``w cross(n, t)`` along +v),
    all float64. ``tangent_source``: ``"file"`` or ``"computed"``, ``tangent_method`` which frames
    (:data:`hzval.geometry.tangents.METHODS`: ``mikktspace``, ``fged2`` or ``file``); ``up``: the
    file's up axis as
    read (``"z"`` for the shapes); ``source``: a shape name or the file's path.
    """

    source: str
    positions: np.ndarray
    normals: np.ndarray
    uvs: np.ndarray
    faces: np.ndarray
    tangents: np.ndarray
    tangent_source: str = "computed"
    up: str = "z"
    uv_scale: float = field(default=1.0)
    tangent_method: str = "fged2"

    @cached_property
    def weld(self) -> np.ndarray:
        """``(V,)`` int64: the id of each vertex's position (:func:`weld_ids`), equal across a seam."""
        return weld_ids(self.positions)

    @cached_property
    def face_areas(self) -> np.ndarray:
        """``(F,)`` world area of each triangle."""
        p = self.positions[self.faces]
        return 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=-1)

    @cached_property
    def uv_areas(self) -> np.ndarray:
        """``(F,)`` signed UV area of each triangle (positive: counterclockwise in UV)."""
        return 0.5 * tg.uv_derivatives(self.positions, self.uvs, self.faces)[2]

    @property
    def world_per_uv(self) -> float:
        """``sqrt(world area / UV area)``: the world length of one texture width."""
        return math.sqrt(float(self.face_areas.sum()) / float(np.abs(self.uv_areas).sum()))

    @property
    def mirrored_fraction(self) -> float:
        """Return the share of the UV area on mirrored UV islands.

        Those are the triangles whose handedness is -1 (the sign of their vertices' summed ``w``).
        """
        w = self.tangents[self.faces, 3].sum(axis=1)
        a = np.abs(self.uv_areas)
        return float(a[w < 0].sum() / a.sum())

    @cached_property
    def seam_edges(self) -> int:
        """Edges whose two triangles meet at the same positions with different UVs or tangents."""
        return count_seams(self)

    def bounding_sphere(self) -> tuple[np.ndarray, float]:
        """``(centre (3,), radius)``: the bounding box's centre and the farthest vertex from it."""
        lo, hi = self.positions.min(axis=0), self.positions.max(axis=0)
        centre = 0.5 * (lo + hi)
        return centre, float(np.linalg.norm(self.positions - centre, axis=-1).max())

    def record(self) -> dict:
        """Return ``metrics.json``'s ``mesh`` record.

        It is ``{source, triangles, world_per_uv, tangents, mirrored_fraction, seam_edges}``.
        """
        return {
            "source": self.source,
            "triangles": int(len(self.faces)),
            "world_per_uv": self.world_per_uv,
            "tangents": self.tangent_source,
            "tangent_method": self.tangent_method,
            "mirrored_fraction": self.mirrored_fraction,
            "seam_edges": int(self.seam_edges),
        }


# ----------------------------------------------------------------------------------------------
# Welding and edges
# ----------------------------------------------------------------------------------------------


def weld_ids(positions: np.ndarray, tolerance: float = WELD_TOLERANCE) -> np.ndarray:
    """Return ``(V,)`` int64 ids, one per distinct position, numbered in the order of first appearance.

    A position is distinct to ``tolerance`` of the bounding-box diagonal. Vertex 0's id is therefore 0.
    """
    p = np.asarray(positions, np.float64)
    if len(p) == 0:
        return np.zeros(0, np.int64)
    q = max(float(np.linalg.norm(p.max(axis=0) - p.min(axis=0))) * tolerance, 1e-300)
    _, first, inverse = np.unique(
        np.round(p / q).astype(np.int64), axis=0, return_index=True, return_inverse=True
    )
    order = np.argsort(np.argsort(first))  # renumber the groups by their first vertex
    return order[inverse.ravel()].astype(np.int64)


def edge_table(faces: np.ndarray, weld: np.ndarray):
    """Return the edges of a mesh on welded ids: ``(key (F, 3), unique, inverse, counts)``.

    Face ``f``'s edge ``e`` runs from corner ``e`` to ``(e + 1) % 3`` and its key is ``lo * W + hi`` of the
    two welded ids (``W`` their count); ``unique`` the distinct keys, ``inverse (F, 3)`` each edge's row in it
    and ``counts`` the triangles on each.
    """
    w = weld[faces]
    a, b = w, np.roll(w, -1, axis=1)
    n = int(weld.max(initial=0)) + 1
    key = np.minimum(a, b) * n + np.maximum(a, b)
    unique, inverse, counts = np.unique(key.ravel(), return_inverse=True, return_counts=True)
    return key, unique, inverse.reshape(key.shape), counts


def count_seams(mesh: BaseMesh, tolerance: float = 1e-9) -> int:
    """Edges shared by two triangles whose ends carry different UVs or tangents on each side."""
    return len(seam_edge_ends(mesh, tolerance))


def seam_edge_ends(mesh: BaseMesh, tolerance: float = 1e-9) -> np.ndarray:
    """``(E, 2)`` int64: one side's two vertices of each seam edge (:func:`count_seams`'s edges)."""
    key, _, inverse, counts = edge_table(mesh.faces, mesh.weld)
    f = mesh.faces
    ends = np.stack([f, np.roll(f, -1, axis=1)], axis=-1).reshape(-1, 2)
    flip = mesh.weld[ends[:, 0]] > mesh.weld[ends[:, 1]]
    ends[flip] = ends[flip][:, ::-1]  # both sides' ends in the order of the welded ids
    row = inverse.ravel()
    pair = np.flatnonzero(counts == 2)
    order = np.argsort(row, kind="stable")
    starts = np.searchsorted(row[order], pair)
    one, two = ends[order[starts]], ends[order[starts + 1]]
    attrs = np.concatenate([mesh.uvs, mesh.tangents], axis=1)
    differ = np.abs(attrs[one] - attrs[two]).max(axis=(1, 2)) > tolerance
    return one[differ].astype(np.int64)


# ----------------------------------------------------------------------------------------------
# Building and checking a mesh
# ----------------------------------------------------------------------------------------------


def smooth_normals(positions: np.ndarray, faces: np.ndarray, weld: np.ndarray) -> np.ndarray:
    """Return angle-weighted vertex normals, summed over each welded position.

    Each triangle's unit normal is weighted by its angle at the vertex (Thuermer & Wuethrich 1998). Both sides
    of a UV seam then get the same normal, and a quad's triangulation does not change it. They serve a file
    without normals.
    """
    p = positions[faces]
    face_n = tg.normalize(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]))
    acc = np.zeros((int(weld.max(initial=0)) + 1, 3))
    for k in range(3):
        a = tg.normalize(p[:, (k + 1) % 3] - p[:, k])
        b = tg.normalize(p[:, (k + 2) % 3] - p[:, k])
        angle = np.arccos(np.clip(np.sum(a * b, -1), -1.0, 1.0))
        np.add.at(acc, weld[faces[:, k]], face_n * angle[:, None])
    return tg.normalize(acc[weld])


def _check_finite(source: str, **arrays) -> None:
    for name, a in arrays.items():
        bad = ~np.isfinite(a).all(axis=-1)
        if np.any(bad):
            raise InputError(source, f"{int(bad.sum())} vertices have NaN or infinite {name}")


def _check_extent(source: str, positions: np.ndarray, uvs: np.ndarray, faces: np.ndarray) -> None:
    """Refuse, before anything is built or rendered, a mesh too small or too large to trace.

    Too small or too large means outside :data:`EXTENT_RANGE` (a node scale of 0, coordinates of 1e-200 or
    1e200). Also refused: a mesh whose triangles have no area (:data:`MIN_AREA_SHARE` of the squared size:
    collinear vertices) and UVs that cover almost nothing (:data:`MIN_UV_AREA`).
    """
    low, high = EXTENT_RANGE
    size = float(np.ptp(positions, axis=0).max())
    if not low <= size <= high:
        raise InputError(
            source,
            f"the mesh is {size:.3g} units across; hzval traces meshes {low:g} to {high:g} "
            "units across (scale it in the file)",
        )
    p = positions[faces] / size  # scaled first: 1e-200 and 1e200 have no product in float64
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=-1).sum()
    if not area > MIN_AREA_SHARE:
        raise InputError(source, "the triangles have no area: their vertices are collinear")
    t = uvs[faces]
    d1, d2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    uv_area = 0.5 * np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]).sum()
    if 0 < uv_area < MIN_UV_AREA:  # none at all: _check_uvs says so
        raise InputError(
            source, f"the UVs cover {uv_area:.3g} of the texture (less than a texel): check --uv-scale"
        )


def _check_uvs(source: str, mesh: BaseMesh) -> None:
    """Refuse a mesh with zero UV area or too much of its world area on degenerate UV triangles.

    The limit is :data:`MAX_DEGENERATE_UV_AREA` of the world area. The texture has no size there, no frame, no
    displacement.
    """
    area = np.abs(mesh.uv_areas)
    if not area.sum() > 0:
        raise InputError(source, "the UVs have zero area (every triangle's UVs are degenerate)")
    flat = (
        area <= tg.DEGENERATE_UV * np.maximum(np.ptp(mesh.uvs[mesh.faces], axis=1).max(axis=1), 1e-300) ** 2
    )
    if mesh.face_areas[flat].sum() > MAX_DEGENERATE_UV_AREA * mesh.face_areas.sum():
        raise InputError(
            source, f"{int(flat.sum())} of {len(flat)} triangles have degenerate (zero-area) UVs"
        )


def _check_manifold(source: str, mesh: BaseMesh) -> None:
    _, _, _, counts = edge_table(mesh.faces, mesh.weld)
    bad = int(np.sum(counts > 2))
    if bad:
        raise InputError(
            source,
            f"{bad} edges are shared by 3 or more triangles (non-manifold): the "
            "displaced surface cannot be welded there",
        )


def build(
    source: str, positions, uvs, faces, *, normals=None, tangents=None, uv_scale: float = 1.0, up: str = "z"
) -> BaseMesh:
    """Return a checked :class:`BaseMesh` from z-up arrays.

    ``normals`` are given or (None) :func:`smooth_normals`; ``tangents`` are the file's or (None)
    :func:`hzval.geometry.tangents.compute`; ``uvs`` get ``uv_scale``. Bad meshes raise :class:`InputError`
    naming ``source``.
    """
    p = np.asarray(positions, np.float64).reshape(-1, 3)
    f = np.asarray(faces, np.int64).reshape(-1, 3)
    if len(f) == 0 or len(p) == 0:
        raise InputError(source, "the mesh is empty (no triangles)")
    if f.min() < 0 or f.max() >= len(p):
        raise InputError(source, f"faces index vertices outside 0..{len(p) - 1}")
    w = np.asarray(uvs, np.float64).reshape(-1, 2) * float(uv_scale)
    used = np.zeros(len(p), bool)
    used[f.ravel()] = True
    if not used.all():  # vertices no triangle uses (a UV sphere's spare pole copy) have no frame
        keep = np.flatnonzero(used)
        remap = np.cumsum(used) - 1
        p, w, f = p[keep], w[keep], remap[f]
        normals = None if normals is None else np.asarray(normals, np.float64).reshape(-1, 3)[keep]
        tangents = None if tangents is None else np.asarray(tangents, np.float64).reshape(-1, 4)[keep]
    _check_finite(source, positions=p, UVs=w)
    _check_extent(source, p, w, f)
    weld = weld_ids(p)
    n = smooth_normals(p, f, weld) if normals is None else np.asarray(normals, np.float64).reshape(-1, 3)
    _check_finite(source, normals=n)
    n = tg.normalize(n)
    zero = np.linalg.norm(n, axis=-1) == 0
    n[zero] = smooth_normals(p, f, weld)[zero]
    if tangents is None:
        t, t_source = tg.compute(p, n, w, f), "computed"
    else:
        try:
            t, t_source = tg.from_file(tangents, n), "file"
        except ValueError as exc:
            raise InputError(source, str(exc)) from None
    method = "file" if t_source == "file" else "fged2"
    mesh = BaseMesh(source, p, n, w, f, t, t_source, up, float(uv_scale), method)
    mesh.__dict__["weld"] = weld  # computed once above (a cached_property on a frozen dataclass)
    _check_uvs(source, mesh)
    _check_manifold(source, mesh)
    return mesh


def to_z_up(up: str, positions, normals=None, tangents=None):
    """Arrays of a file whose up axis is ``up`` in hzval's z-up world (:data:`Y_UP_TO_Z_UP`)."""
    if up == "z":
        return positions, normals, tangents
    m = Y_UP_TO_Z_UP
    return (
        positions @ m.T,
        None if normals is None else normals @ m.T,
        None if tangents is None else tg.rotate(tangents, m),
    )


# ----------------------------------------------------------------------------------------------
# Built-in shapes (z up)
# ----------------------------------------------------------------------------------------------


def plane(*, uv_scale: float = 1.0) -> BaseMesh:
    """Return the unit quad ``[0, 1]^2`` at ``z = 0``, UVs ``(x, y)``, normal +z.

    It is today's tile (``world_per_uv`` = 1, frame ``(x, y, z)``), two triangles along the (0, 0)-(1, 1)
    diagonal.
    """
    p = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    return build(
        "plane", p, p[:, :2], [[0, 1, 2], [0, 2, 3]], normals=np.tile([0.0, 0, 1], (4, 1)), uv_scale=uv_scale
    )


#: The cube's faces as a real unwrap lays them out: ``(name, normal, +u axis, +v axis)``. Each face
#: carries the whole texture. -y (the front), +x and +y read as the texture seen from outside
#: (the sides' +v up); +z (the top) is turned 90 degrees (+u along +y); -x and -z are *mirrored*
#: (w = -1: -x reuses +x's layout; -z, the bottom, has u along +x and v along +y, the texture as
#: seen from above through the cube), as an artist's mirrored islands are. mirrored_fraction = 1/3.
CUBE_FACES = (
    ("+x", (1, 0, 0), (0, 1, 0), (0, 0, 1)),
    ("-x", (-1, 0, 0), (0, 1, 0), (0, 0, 1)),
    ("+y", (0, 1, 0), (-1, 0, 0), (0, 0, 1)),
    ("-y", (0, -1, 0), (1, 0, 0), (0, 0, 1)),
    ("+z", (0, 0, 1), (0, 1, 0), (-1, 0, 0)),
    ("-z", (0, 0, -1), (1, 0, 0), (0, 1, 0)),
)


def cube(*, size: float = 1.0, uv_scale: float = 1.0) -> BaseMesh:
    """Return the cube of edge ``size`` centred at the origin, each face the whole texture.

    The faces are :data:`CUBE_FACES`, four vertices and two triangles a face, with flat normals.
    """
    uv = np.array([[0.0, 0], [1, 0], [1, 1], [0, 1]])
    p, n, w, f = [], [], [], []
    for k, (_, normal, t, b) in enumerate(CUBE_FACES):
        normal, t, b = (np.asarray(a, np.float64) for a in (normal, t, b))
        p.append(size * (0.5 * normal + (uv[:, :1] - 0.5) * t + (uv[:, 1:] - 0.5) * b))
        n.append(np.tile(normal, (4, 1)))
        w.append(uv)
        tri = np.array([[0, 1, 2], [0, 2, 3]])
        f.append(4 * k + (tri if np.dot(np.cross(t, b), normal) > 0 else tri[:, ::-1]))
    return build(
        "cube",
        np.concatenate(p),
        np.concatenate(w),
        np.concatenate(f),
        normals=np.concatenate(n),
        uv_scale=uv_scale,
    )


def _grid_faces(rows: int, cols: int, skip=None) -> np.ndarray:
    """Return the triangles of a ``(rows + 1) x (cols + 1)`` vertex grid.

    A vertex's index is ``i * (cols + 1) + j``, ``i`` along +v, ``j`` along +u; each cell is ``(a, b, c), (a,
    c, d)`` counterclockwise in UV; ``skip`` ``(rows, cols, 2)`` bool drops triangles (a pole's collapsed
    ones).
    """
    i, j = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    a = i * (cols + 1) + j
    b, c, d = a + 1, a + cols + 2, a + cols + 1
    tri = np.stack([np.stack([a, b, c], -1), np.stack([a, c, d], -1)], axis=2)
    return tri[~skip] if skip is not None else tri.reshape(-1, 3)


def _sphere_grid(radius: float, segments: int, rings: int, phi: tuple[float, float], u_of):
    """Return one ``(positions, uvs, normals, faces)`` part of a UV sphere about the z axis.

    It spans longitudes ``phi[0]..phi[1]`` (counterclockwise from +x seen from +z) in ``segments`` columns,
    ``rings`` rows from the south pole to the north, ``u = u_of(f)`` of the share ``f`` (0 to 1) of the span,
    ``v`` the latitude (0 south, 1 north); each pole's vertices sit at the middle of their column (its
    collapsed triangle dropped).
    """
    v = np.arange(rings + 1) / rings
    s = np.arange(segments + 1, dtype=float)
    ss, vv = np.meshgrid(s, v)
    ss[0, :] = ss[-1, :] = s + 0.5  # poles at the mid-span
    f = ss / segments
    theta, lon = np.pi * vv, phi[0] + (phi[1] - phi[0]) * f
    n = np.stack([np.sin(theta) * np.cos(lon), np.sin(theta) * np.sin(lon), -np.cos(theta)], -1)
    skip = np.zeros((rings, segments, 2), bool)
    skip[0, :, 0] = skip[-1, :, 1] = True
    return (
        radius * n.reshape(-1, 3),
        np.stack([u_of(f), vv], -1).reshape(-1, 2),
        n.reshape(-1, 3),
        _grid_faces(rings, segments, skip),
    )


def sphere(*, radius: float = 1.0, segments: int = 64, rings: int = 32, uv_scale: float = 1.0) -> BaseMesh:
    """Return a UV sphere about the z axis.

    ``u`` is the longitude / 2 pi (counterclockwise from +x seen from +z), ``v`` the latitude from the south
    pole (0) to the north (1); the seam is at ``u = 0 / 1`` (the +x half-plane) and each pole's vertices (one
    per segment, at the middle of its ``u`` span). World area ``4 pi r^2`` as ``segments, rings`` grow
    (``world_per_uv`` -> ``r sqrt(4 pi)``).
    """
    p, uv, n, f = _sphere_grid(radius, segments, rings, (0.0, 2 * np.pi), lambda f: f)
    return build("sphere", p, uv, f, normals=n, uv_scale=uv_scale)


def mirrored_sphere(
    *, radius: float = 1.0, segments: int = 64, rings: int = 32, uv_scale: float = 1.0
) -> BaseMesh:
    """Return the UV sphere unwrapped as an artist mirrors a symmetric model.

    The +y half (longitudes 0 to pi) has ``u = longitude / pi``, the -y half the same UVs mirrored (``u = (2
    pi - longitude) / pi``), so a point and its mirror image in the xz plane read the same texel and the -y
    half has handedness ``w = -1`` (``mirrored_fraction`` 1/2). The halves keep their own vertices along the
    two mirror meridians, as exporters split them (their tangents point opposite ways), which makes those
    meridians seams of equal UVs. ``world_per_uv`` -> ``r sqrt(2 pi)``.
    """
    segments = max(2, segments // 2)
    parts = [
        _sphere_grid(radius, segments, rings, (0.0, np.pi), lambda f: f),
        _sphere_grid(radius, segments, rings, (np.pi, 2 * np.pi), lambda f: 1.0 - f),
    ]
    return _join("mirrored-sphere", parts, uv_scale)


def torus(
    *, major: float = 1.0, minor: float = 0.25, segments: int = 64, sides: int = 32, uv_scale: float = 1.0
) -> BaseMesh:
    """Return a torus about the z axis, tube centre ``major`` from the axis, tube radius ``minor``.

    ``u`` runs around the axis (counterclockwise from +x seen from +z), ``v`` around the tube from the outer
    equator (0) over the top; there are seams where each wraps. The inner ring (``v = 1/2``) is a saddle:
    convex across the tube (normal curvature ``1 / minor``), concave around the axis (``-1 / (major -
    minor)``; ``hzval models``' ``ring`` case).
    """
    uu, vv = np.meshgrid(np.arange(segments + 1) / segments, np.arange(sides + 1) / sides)
    phi, psi = 2 * np.pi * uu, 2 * np.pi * vv
    n = np.stack([np.cos(psi) * np.cos(phi), np.cos(psi) * np.sin(phi), np.sin(psi)], -1)
    ring = np.stack([np.cos(phi), np.sin(phi), np.zeros_like(phi)], -1)
    p = major * ring + minor * n
    return build(
        "torus",
        p.reshape(-1, 3),
        np.stack([uu, vv], -1).reshape(-1, 2),
        _grid_faces(sides, segments),
        normals=n.reshape(-1, 3),
        uv_scale=uv_scale,
    )


def _disk_grid(k: int):
    """Return a ``k x k`` quad grid of the unit square mapped onto the unit disk.

    The mapping is the elliptical grid mapping ``(x sqrt(1 - y^2/2), y sqrt(1 - x^2/2))``, with no singular
    centre. The result is ``(xy (V, 2), faces, rim)``, ``rim`` the ``4 k`` boundary vertices counterclockwise
    from ``(1, 0)`` (``k`` even). Cells split along the diagonal that avoids the square's corners (no sliver
    there).
    """
    s = np.linspace(-1.0, 1.0, k + 1)
    x, y = np.meshgrid(s, s)  # vertex (i, j) = row i (y), column j (x), index i (k + 1) + j
    xy = np.stack([x * np.sqrt(1 - y * y / 2), y * np.sqrt(1 - x * x / 2)], -1).reshape(-1, 2)
    i, j = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
    a = i * (k + 1) + j
    b, c, d = a + 1, a + k + 2, a + k + 1
    same = ((i < k // 2) == (j < k // 2)).ravel()[:, None, None]  # quadrants whose corner is a or c
    ac = np.stack([np.stack([a, b, c], -1), np.stack([a, c, d], -1)], 2).reshape(-1, 2, 3)
    bd = np.stack([np.stack([a, b, d], -1), np.stack([b, c, d], -1)], 2).reshape(-1, 2, 3)
    faces = np.where(same, bd, ac).reshape(-1, 3)
    edge = (
        [(r, k) for r in range(k // 2, k)]
        + [(k, c) for c in range(k, 0, -1)]
        + [(r, 0) for r in range(k, 0, -1)]
        + [(0, c) for c in range(k)]
        + [(r, k) for r in range(k // 2)]
    )
    rim = np.array([r * (k + 1) + c for r, c in edge])
    return xy, faces, rim


def cylinder(
    *,
    radius: float = 0.5,
    height: float = 1.0,
    segments: int = 64,
    stacks: int = 32,
    caps: bool = True,
    uv_scale: float = 1.0,
) -> BaseMesh:
    """Return a cylinder about the z axis from ``-height/2`` to ``height/2``.

    It has ``segments`` (a multiple of 4) around and ``stacks`` up: the side's ``u`` is the angle / 2 pi
    (counterclockwise from +x seen from +z, seam at +x), ``v`` up. With ``caps`` it gets two disks (closed),
    each the texture's inscribed circle seen from outside (top: u along +x, v along +y; bottom: u along +x, v
    along -y; neither mirrored), a square grid mapped onto the disk (:func:`_disk_grid`) whose rim is the
    side's.
    """
    if segments % 4 or segments < 8:
        raise ValueError(f"segments must be a multiple of 4 (at least 8), got {segments}")
    xy, disk, rim = _disk_grid(segments // 4)
    ang = np.arctan2(xy[rim, 1], xy[rim, 0]) % (2 * np.pi)
    u = np.concatenate([ang, [2 * np.pi]]) / (2 * np.pi)
    uu, vv = np.meshgrid(u, np.arange(stacks + 1) / stacks)
    ring = np.concatenate([xy[rim], xy[rim[:1]]])
    n = np.broadcast_to(np.concatenate([ring, np.zeros((len(ring), 1))], 1), uu.shape + (3,))
    p = radius * n + np.stack([0 * uu, 0 * uu, (vv - 0.5) * height], -1)
    parts = [
        (
            p.reshape(-1, 3),
            np.stack([uu, vv], -1).reshape(-1, 2),
            n.reshape(-1, 3),
            _grid_faces(stacks, segments),
        )
    ]
    for s in (1.0, -1.0) if caps else ():
        cp = np.concatenate([radius * xy, np.full((len(xy), 1), s * height / 2)], axis=1)
        parts.append(
            (
                cp,
                0.5 + 0.5 * xy * [1.0, s],
                np.tile([0.0, 0.0, s], (len(xy), 1)),
                disk if s > 0 else disk[:, ::-1],
            )
        )
    return _join("cylinder", parts, uv_scale)


def _join(source: str, parts, uv_scale: float) -> BaseMesh:
    """One mesh of ``(positions, uvs, normals, faces)`` parts."""
    offsets = np.cumsum([0] + [len(q[0]) for q in parts])
    return build(
        source,
        np.concatenate([q[0] for q in parts]),
        np.concatenate([q[1] for q in parts]),
        np.concatenate([q[3] + o for q, o in zip(parts, offsets)]),
        normals=np.concatenate([q[2] for q in parts]),
        uv_scale=uv_scale,
    )


SHAPES: dict[str, Callable[..., BaseMesh]] = {
    "plane": plane,
    "cube": cube,
    "sphere": sphere,
    "cylinder": cylinder,
    "torus": torus,
    "mirrored-sphere": mirrored_sphere,
}


# ----------------------------------------------------------------------------------------------
# Files
# ----------------------------------------------------------------------------------------------


def read_trimesh(path: str, *, uv_scale: float = 1.0, up: str = "y") -> BaseMesh:
    """Return an OBJ or PLY read by trimesh, every triangle mesh of the file in one.

    Each triangle mesh comes with its node transform. trimesh splits a vertex where its UVs differ (OBJ's ``f
    v/vt``) and keeps the file's ``vn`` / PLY normals, which it holds in each geometry's cache; a file without
    them gets :func:`smooth_normals`. Its UVs are OBJ's: ``v = 0`` at the bottom row.
    """
    # trimesh: 0.6 s to import, paid only by a model read from a file
    import trimesh

    try:
        scene = trimesh.load(path, force="scene", process=False)
    except Exception as exc:  # trimesh raises many kinds for a broken file
        raise InputError(path, f"cannot be read as a mesh ({type(exc).__name__}: {exc})") from None
    parts, with_normals = [], True
    for node in scene.graph.nodes_geometry:
        matrix, name = scene.graph[node]
        g = scene.geometry[name]
        if not isinstance(g, trimesh.Trimesh) or len(g.faces) == 0:
            continue
        uv = getattr(g.visual, "uv", None)
        if uv is None or len(uv) != len(g.vertices):
            raise InputError(path, f"has no texture coordinates (UVs) on {name!r}")
        normals = g._cache.cache.get("vertex_normals")  # the file's own, when it has them
        with_normals &= normals is not None
        m = np.asarray(matrix, np.float64)
        p = np.asarray(g.vertices, np.float64) @ m[:3, :3].T + m[:3, 3]
        n = None if normals is None else np.asarray(normals, np.float64) @ np.linalg.inv(m[:3, :3])
        parts.append((p, np.asarray(uv, np.float64), n, np.asarray(g.faces, np.int64)))
    if not parts:
        raise InputError(path, "the mesh is empty (no triangles)")
    offsets = np.cumsum([0] + [len(q[0]) for q in parts])
    p = np.concatenate([q[0] for q in parts])
    n = np.concatenate([q[2] for q in parts]) if with_normals else None
    p, n, _ = to_z_up(up, p, n)
    return build(
        path,
        p,
        np.concatenate([q[1] for q in parts]),
        np.concatenate([q[3] + o for q, o in zip(parts, offsets)]),
        normals=n,
        uv_scale=uv_scale,
        up=up,
    )


def read_gltf(path: str, *, uv_scale: float = 1.0, up: str = "y") -> BaseMesh:
    """Return the triangles of a glTF 2.0 file's default scene, turned z-up.

    The file is a ``.gltf`` with its buffers, or a ``.glb``; the triangles come from
    :func:`hzval.geometry.gltf.read_parts`. Its ``TANGENT`` is used when every primitive has one, else all are
    computed.
    """
    p, uv, n, t, faces = gltf.read_parts(path)
    p, n, t = to_z_up(up, p, n, t)
    return build(
        path,
        p,
        uv,
        faces,
        normals=n,
        tangents=t if n is not None else None,
        uv_scale=uv_scale,
        up=up,
    )


READERS: dict[str, Callable[..., BaseMesh]] = {
    ".obj": read_trimesh,
    ".ply": read_trimesh,
    ".gltf": read_gltf,
    ".glb": read_gltf,
}


def _shape(name: str, uv_scale: float, args: dict) -> BaseMesh:
    """``SHAPES[name](**args)``, a bad keyword or value as one line naming the shape's argument."""
    params = {k: p.default for k, p in inspect.signature(SHAPES[name]).parameters.items() if k != "uv_scale"}
    for key, value in args.items():
        if key not in params:
            raise InputError(f"[mesh] {key}", f"{name} has no argument {key!r} (it has: {', '.join(params)})")
        kind = type(params[key])  # the default's type: bool, int (counts) or float (lengths)
        number = isinstance(value, (int, float)) and not isinstance(value, bool)
        if kind is bool and not isinstance(value, bool):
            raise InputError(f"[mesh] {key}", f"must be true or false, got {value!r}")
        if kind is int and not (number and value == int(value) and value > 0):
            raise InputError(f"[mesh] {key}", f"must be a positive whole number, got {value!r}")
        if kind is float and not (number and math.isfinite(value) and value > 0):
            raise InputError(f"[mesh] {key}", f"must be a positive number, got {value!r}")
        args[key] = int(value) if kind is int else value
    try:
        return SHAPES[name](uv_scale=uv_scale, **args)
    except (ValueError, TypeError) as exc:
        raise InputError(f"[mesh] {name}", str(exc)) from None


def with_frames(mesh: BaseMesh, method: str) -> BaseMesh:
    """``mesh`` with the tangent frames ``method`` names (:func:`hzval.geometry.tangents.resolve`).

    MikkTSpace gives each triangle corner a frame; a vertex whose corners disagree (a mirror line
    with shared UVs) is split into one vertex per frame (:func:`hzval.geometry.mikktspace.per_vertex`).
    A corner whose frame has no tangent (a vertex surrounded by degenerate UVs) gets one orthogonal
    to its normal. One line naming ``--tangents`` for a method the mesh cannot have.
    """
    try:
        used = tg.resolve(method, mesh.tangent_source == "file", mesh.source in SHAPES)
    except ValueError as exc:
        raise InputError("--tangents", f"{mesh.source}: {exc}") from None
    if used == mesh.tangent_method or (used == "file" and mesh.tangent_source == "file"):
        return dataclasses.replace(mesh, tangent_method=used)
    if used == "fged2":
        t = tg.compute(mesh.positions, mesh.normals, mesh.uvs, mesh.faces)
        return dataclasses.replace(mesh, tangents=t, tangent_source="computed", tangent_method=used)
    corners = mikktspace.corner_tangents(mesh.positions, mesh.normals, mesh.uvs, mesh.faces)
    p, n, w, f, t = mikktspace.per_vertex(mesh.positions, mesh.normals, mesh.uvs, mesh.faces, corners)
    lost = np.linalg.norm(t[:, :3], axis=-1) == 0
    t[lost, :3] = tg.any_tangent(n[lost])
    out = BaseMesh(mesh.source, p, n, w, f, t, "computed", mesh.up, mesh.uv_scale, used)
    out.__dict__["weld"] = weld_ids(p)
    return out


def load(
    spec: str,
    *,
    uv_scale: float = 1.0,
    up: str | None = None,
    shape_args: dict | None = None,
    tangents: str = "auto",
) -> BaseMesh:
    """Return the base mesh ``spec`` names, a built-in shape or a file read by its extension.

    A built-in shape is one of :data:`SHAPES`, with ``shape_args`` (e.g. ``{"radius": 2}``), and ignores
    ``up``: they are z up. A file is chosen by its extension (:data:`READERS`) and read with the up axis
    ``up`` (None: y, the module's "Up axis of files"). ``uv_scale`` > 0 repeats the texture; ``tangents``
    names its frames (:func:`with_frames`). Anything wrong is one :class:`InputError` naming the file or the
    flag.
    """
    return with_frames(_load(spec, uv_scale=uv_scale, up=up, shape_args=shape_args), tangents)


def _load(spec: str, *, uv_scale: float, up: str | None, shape_args: dict | None) -> BaseMesh:
    """:func:`load` with the frames the shape or the file comes with."""
    if not (isinstance(uv_scale, (int, float)) and math.isfinite(uv_scale) and uv_scale > 0):
        raise InputError("--uv-scale", f"must be a positive number, got {uv_scale!r}")
    if up is not None and up not in UP_AXES:
        raise InputError("--up", f"must be one of {', '.join(UP_AXES)}, got {up!r}")
    spec = os.fspath(spec)
    if spec in SHAPES:
        return _shape(spec, float(uv_scale), dict(shape_args or {}))
    ext = os.path.splitext(spec)[1].lower()
    if not ext:
        near = difflib.get_close_matches(spec, list(SHAPES), n=3)
        hint = f"; did you mean {' or '.join(near)}?" if near else ""
        raise InputError(
            "--mesh",
            f"unknown shape {spec!r}{hint} (shapes: {', '.join(SHAPES)}; or a {', '.join(READERS)} file)",
        )
    if ext not in READERS:
        raise InputError(spec, f"unknown mesh format {ext!r} (known: {', '.join(READERS)})")
    if not os.path.isfile(spec):
        raise InputError(spec, "no such file")
    return READERS[ext](spec, uv_scale=float(uv_scale), up=up or "y")
