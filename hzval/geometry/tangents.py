"""Tangent frames: how a mesh's UVs become the frame in which a texture's tangent space meets the world.

This is the one module that owns it (docs/meshes.md, "Tangent frames").

A frame is ``(t, w, n)``: ``n`` the unit normal, ``t`` the unit tangent along +u (orthogonal to
``n``), ``w = +1/-1`` the handedness, and the bitangent along +v is ``b = w * cross(n, t)``
(FGED2 ch. 7, ``CalculateTangentSpaceVL``; glTF 2.0's ``TANGENT`` attribute, whose ``w`` is this
sign). hzval's tangent space (:mod:`hzval.core.conventions`) has +x along increasing columns = +u,
+y up the image = +v (hzval's UVs put ``v = 0`` at the bottom row, :mod:`hzval.geometry.model`) and +z
out of the surface, so a tangent-space vector ``(x, y, z)`` is ``x t + y b + z n`` in the world.

Frames come from the file (glTF's ``TANGENT``, :func:`from_file`) or are computed from the UV
derivatives (:func:`compute`, FGED2's ``CalculateTangents``, /work/shared/seeds/
fged2-ch7-shading-notes.txt): per triangle ``dP/du``, ``dP/dv`` solved from its two edges,
summed to its three vertices, then Gram-Schmidt against the vertex normal and the handedness from
the sign of ``dot(cross(t, b), n)``.

The frame at a point inside a triangle (a camera's hit) is the vertices' frames interpolated and
re-orthonormalised there (:func:`orthonormal`, FGED2's ``FetchObjectNormalVector``): the
techniques and the truth both call it, on NumPy arrays (``(..., 3)``) or on Dr.Jit ``Array3f``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hzval.core import conventions as cv

__all__ = [
    "Y_UP_TO_Z_UP",
    "METHODS",
    "resolve",
    "DEGENERATE_UV",
    "FRAME_MODES",
    "reject",
    "orthonormal",
    "to_world",
    "to_tangent",
    "uv_derivatives",
    "compute",
    "any_tangent",
    "from_file",
    "rotate",
    "Frames",
    "handedness",
    "face_frames",
    "frames",
]

#: A UV triangle whose ``|du1 dv2 - du2 dv1|`` is at most this share of its UV extent squared has
#: no UV derivatives (FGED2 divides by it); it adds nothing to its vertices' sums.
DEGENERATE_UV = 1e-12
FRAME_MODES: tuple[str, ...] = ("vertex", "face")
#: The rotation that turns a y-up file's vectors into hzval's z-up world: (x, y, z) -> (x, -z, y)
#: (glTF 2.0 is y up; a frame turns with its mesh, :func:`rotate`).
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])

#: How a mesh's tangent frames are made (``--tangents``; docs/meshes.md, "Tangent frames"):
#: ``mikktspace`` (:mod:`hzval.geometry.mikktspace`, what bakers and engines compute), ``fged2``
#: (:func:`compute`), ``file`` (the file's ``TANGENT``, :func:`from_file`), or ``auto``
#: (:func:`resolve`).
METHODS: tuple[str, ...] = ("auto", "mikktspace", "fged2", "file")


def resolve(method: str, has_file_tangents: bool, builtin: bool) -> str:
    """Return the frames ``method`` stands for on one mesh.

    ``auto`` is the file's ``TANGENT`` where it has one, else MikkTSpace, as glTF 2.0 asks of a
    client; hzval's built-in shapes, which have no file, keep the FGED2 frames they were measured
    with (so that their sweeps' scores stay what they were).

    Parameters
    ----------
    method : str
        One of :data:`METHODS`.
    has_file_tangents : bool
        Whether the mesh's file holds tangents.
    builtin : bool
        Whether the mesh is one of hzval's built-in shapes.

    Returns
    -------
    str
        ``mikktspace``, ``fged2`` or ``file``.

    Raises
    ------
    ValueError
        For an unknown method, or ``file`` on a mesh without tangents.

    Examples
    --------
    >>> resolve("auto", True, False), resolve("auto", False, False), resolve("auto", False, True)
    ('file', 'mikktspace', 'fged2')
    """
    if method not in METHODS:
        raise ValueError(f"unknown tangent frames {method!r} (choose from {', '.join(METHODS)})")
    if method == "file" and not has_file_tangents:
        raise ValueError("the mesh has no TANGENT of its own: choose auto, mikktspace or fged2")
    if method != "auto":
        return method
    return "file" if has_file_tangents else ("fged2" if builtin else "mikktspace")


# ----------------------------------------------------------------------------------------------
# Vector helpers on NumPy (..., 3) arrays or Dr.Jit Array3f
# ----------------------------------------------------------------------------------------------


def _dot(a, b):
    if cv.is_drjit(a):
        # only on the Dr.Jit path: NumPy callers never load Dr.Jit
        from hzval.core.backend import dr

        return dr.dot(a, b)
    return np.sum(np.asarray(a) * np.asarray(b), axis=-1)


def _cross(a, b):
    if cv.is_drjit(a):
        # only on the Dr.Jit path: NumPy callers never load Dr.Jit
        from hzval.core.backend import dr

        return dr.cross(a, b)
    return np.cross(a, b)


def normalize(a):
    """Return ``a / |a|``; a zero vector stays zero (NumPy) rather than becoming NaN."""
    if cv.is_drjit(a):
        # only on the Dr.Jit path: NumPy callers never load Dr.Jit
        from hzval.core.backend import dr

        return dr.normalize(a)
    a = np.asarray(a, np.float64)
    length = np.linalg.norm(a, axis=-1, keepdims=True)
    return np.divide(a, length, out=np.zeros_like(a), where=length > 0)


def _scale(v, s):
    """``v * s`` with ``s`` one number per vector."""
    if cv.is_drjit(v):
        return v * s
    return np.asarray(v) * np.asarray(s)[..., None]


def sign(w):
    """+1 where ``w >= 0``, else -1 (an interpolated handedness is a sign again)."""
    if cv.is_drjit(w):
        # only on the Dr.Jit path: NumPy callers never load Dr.Jit
        from hzval.core.backend import dr

        return dr.select(w >= 0, 1.0, -1.0)
    return np.where(np.asarray(w) >= 0, 1.0, -1.0)


# ----------------------------------------------------------------------------------------------
# Frames at a point, and vectors between tangent space and the world
# ----------------------------------------------------------------------------------------------


def reject(t, n):
    """Gram-Schmidt: ``normalize(t - n dot(n, t))``, the part of ``t`` orthogonal to the unit ``n``."""
    return normalize(t - _scale(n, _dot(n, t)))


def orthonormal(n, t, w):
    """Return the frame ``(t, b, n)`` at a point from interpolated ``n``, ``t`` and handedness ``w``.

    The interpolated ``n`` and ``t`` are not unit, not orthogonal: ``n`` is normalised, ``t`` rejected from it
    (FGED2's ``FetchObjectNormalVector``), and ``b = sign(w) cross(n, t)``. Returns ``(t, b, n)``.
    """
    n = normalize(n)
    t = reject(t, n)
    return t, _scale(_cross(n, t), sign(w)), n


def to_world(v, n, t, w):
    """Return a tangent-space vector ``v = (x, y, z)`` in the world.

    x is along +u, y along +v, z out; the result is ``x t + y b + z n`` with the frame :func:`orthonormal`
    makes of ``(n, t, w)``.
    """
    t, b, n = orthonormal(n, t, w)
    if cv.is_drjit(v):
        return t * v.x + b * v.y + n * v.z
    v = np.asarray(v, np.float64)
    return _scale(t, v[..., 0]) + _scale(b, v[..., 1]) + _scale(n, v[..., 2])


def to_tangent(v, n, t, w):
    """Return a world vector ``v`` in tangent space.

    The result is ``(dot(t, v), dot(b, v), dot(n, v))`` (FGED2's TBN product), the inverse of :func:`to_world`
    for the same ``(n, t, w)``.
    """
    t, b, n = orthonormal(n, t, w)
    if cv.is_drjit(v):
        # only on the Dr.Jit path: NumPy callers never load Dr.Jit
        from hzval.core.backend import mi

        return mi.Vector3f(_dot(t, v), _dot(b, v), _dot(n, v))
    return np.stack([_dot(t, v), _dot(b, v), _dot(n, v)], axis=-1)


# ----------------------------------------------------------------------------------------------
# Per-vertex frames of a mesh
# ----------------------------------------------------------------------------------------------


def uv_derivatives(positions, uvs, faces):
    """Return per triangle ``(dP/du, dP/dv, det)``, shaped ``(F, 3)``, ``(F, 3)`` and ``(F,)``.

    They are FGED2's ``t = (e1 y2 - e2 y1) / det``, ``b = (e2 x1 - e1 x2) / det`` with ``e1, e2`` the edges
    from vertex 0 and ``(x, y)`` their UV differences, ``det = x1 y2 - x2 y1`` (the UV area doubled, signed).
    Triangles with a degenerate UV map (:data:`DEGENERATE_UV`) get zero derivatives.
    """
    p = np.asarray(positions, np.float64)[faces]
    w = np.asarray(uvs, np.float64)[faces]
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    x1, x2 = w[:, 1, 0] - w[:, 0, 0], w[:, 2, 0] - w[:, 0, 0]
    y1, y2 = w[:, 1, 1] - w[:, 0, 1], w[:, 2, 1] - w[:, 0, 1]
    det = x1 * y2 - x2 * y1
    extent = np.maximum(np.abs(np.stack([x1, x2, y1, y2])).max(axis=0), 1e-300)
    ok = np.abs(det) > DEGENERATE_UV * extent**2
    r = np.divide(1.0, det, out=np.zeros_like(det), where=ok)[:, None]
    return (e1 * y2[:, None] - e2 * y1[:, None]) * r, (e2 * x1[:, None] - e1 * x2[:, None]) * r, det


def compute(positions, normals, uvs, faces) -> np.ndarray:
    """Return ``(V, 4)`` float64 per-vertex tangents by FGED2's ``CalculateTangents``.

    Each triangle's ``dP/du``, ``dP/dv`` (:func:`uv_derivatives`) is added to its three vertices, ``t``
    rejected from the unit vertex normal, ``w = +1`` where ``dot(cross(t, b), n) > 0`` else ``-1`` (FGED2
    takes the sums for ``t, b``). A vertex whose sum vanishes (only degenerate UVs around it) gets a tangent
    orthogonal to its normal (:func:`any_tangent`) and ``w = +1``.
    """
    faces = np.asarray(faces, np.int64)
    n = normalize(normals)
    dpdu, dpdv, _ = uv_derivatives(positions, uvs, faces)
    t_sum = np.zeros((len(n), 3))
    b_sum = np.zeros((len(n), 3))
    for k in range(3):
        np.add.at(t_sum, faces[:, k], dpdu)
        np.add.at(b_sum, faces[:, k], dpdv)
    t = reject(t_sum, n)
    lost = np.linalg.norm(t, axis=-1) == 0
    t[lost] = any_tangent(n[lost])
    w = np.where(_dot(np.cross(t_sum, b_sum), n) >= 0, 1.0, -1.0)
    w[lost] = 1.0
    return np.concatenate([t, w[:, None]], axis=-1)


def any_tangent(n) -> np.ndarray:
    """Return a unit vector orthogonal to each unit ``n`` (``(k, 3)``).

    It is ``x`` rejected from ``n``, or ``y`` where ``n`` is nearly ``x``.
    """
    n = np.asarray(n, np.float64).reshape(-1, 3)
    axis = np.where((np.abs(n[:, 0]) < 0.9)[:, None], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    return reject(axis, n)


def from_file(tangents, normals) -> np.ndarray:
    """Return a file's ``(V, 4)`` tangents as hzval keeps them.

    The file's tangents are glTF ``TANGENT``: xyz along +u, w the handedness. xyz is rejected from the unit
    normal (a writer's rounding), w reduced to its sign. ``ValueError`` names what is wrong (the reader turns
    it into one line naming the file).
    """
    t4 = np.asarray(tangents, np.float64)
    if t4.ndim != 2 or t4.shape[1] != 4:
        raise ValueError(f"TANGENT must have 4 components per vertex, got shape {t4.shape}")
    if not np.all(np.isfinite(t4)):
        raise ValueError(
            f"TANGENT has {int(np.sum(~np.isfinite(t4).all(axis=1)))} vertices with NaN or infinity"
        )
    n = normalize(normals)
    t = reject(t4[:, :3], n)
    bad = np.linalg.norm(t, axis=-1) == 0
    if np.any(bad):
        raise ValueError(f"TANGENT is zero or along the normal at {int(bad.sum())} vertices")
    return np.concatenate([t, sign(t4[:, 3])[:, None]], axis=-1)


def rotate(tangents, matrix) -> np.ndarray:
    """Return tangents ``(V, 4)`` under a linear map ``matrix`` (3 x 3, applied as ``M @ t``).

    xyz is mapped and normalised, ``w`` multiplied by ``sign(det M)`` (a mirror turns the bitangent's side
    over).
    """
    m = np.asarray(matrix, np.float64)
    t = normalize(np.asarray(tangents, np.float64)[:, :3] @ m.T)
    return np.concatenate([t, tangents[:, 3:4] * np.sign(np.linalg.det(m))], axis=-1)


# ----------------------------------------------------------------------------------------------
# Frames of a mesh, per vertex or per face
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Frames:
    """The frames a renderer interpolates, one per vertex or per triangle.

    They are ``normal (k, 3)`` unit and ``tangent (k, 4)`` (xyz unit, w = +1/-1), with ``per = "vertex"`` or
    ``"face"``.
    """

    per: str
    normal: np.ndarray
    tangent: np.ndarray


def handedness(t, b, n) -> np.ndarray:
    """Return the sign ``w`` of frames given as ``(N, 3)`` arrays, shaped ``(N,)``.

    It is ``sign(dot(cross(n, t), b))`` (+1: the UVs as drawn, -1: mirrored; this module's ``b = w cross(n,
    t)``), 0 for a degenerate one.
    """
    t, b, n = (np.asarray(a, np.float64) for a in (t, b, n))
    return np.sign(_dot(np.cross(n, t), b))


def face_frames(positions, uvs, faces) -> tuple[np.ndarray, np.ndarray]:
    """Return per triangle ``(normal (F, 3), tangent (F, 4))``.

    The normal is the geometric one (counterclockwise winding), the tangent ``dP/du`` rejected from it, ``w``
    the sign of ``dot(cross(dP/du, dP/dv), n)``, the same as the sign of the UV area seen from the normal's
    side. A triangle without UV derivatives gets :func:`any_tangent` and ``w = +1``.
    """
    p = np.asarray(positions, np.float64)[faces]
    n = normalize(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]))
    dpdu, dpdv, _ = uv_derivatives(positions, uvs, faces)
    t = reject(dpdu, n)
    lost = np.linalg.norm(t, axis=-1) == 0
    t[lost] = any_tangent(n[lost])
    w = np.where(_dot(np.cross(dpdu, dpdv), n) >= 0, 1.0, -1.0)
    w[lost] = 1.0
    return n, np.concatenate([t, w[:, None]], axis=-1)


def frames(mesh, mode: str = "vertex") -> Frames:
    """Return the frames of a :class:`hzval.geometry.model.BaseMesh`, per vertex or per face.

    ``"vertex"`` gives its own per-vertex normals and tangents (the file's or :func:`compute`'s), which a
    renderer interpolates; ``"face"`` each triangle's own flat frame (:func:`face_frames`), the faceted frame
    a careless exporter gives (:mod:`hzval.geometry.tangent_bugs` has the other bugs).
    """
    if mode == "vertex":
        return Frames("vertex", mesh.normals, mesh.tangents)
    if mode == "face":
        n, t = face_frames(mesh.positions, mesh.uvs, mesh.faces)
        return Frames("face", n, t)
    raise ValueError(f"unknown frame mode {mode!r}; known: {', '.join(FRAME_MODES)}")
