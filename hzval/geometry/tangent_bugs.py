"""Engine bugs on purpose: the techniques' tangent frames as a careless engine builds them.

The truth keeps the correct ones (docs/meshes.md, "Tangent bugs").

A sample's frame is ``(t, b, n)`` (:mod:`hzval.geometry.tangents`: ``t`` along +u, ``b = w cross(n, t)``
along +v, ``n`` out). Everything the techniques do on a model goes through it: the light in
tangent space ``(dot(t, L), dot(b, L), dot(n, L))`` is what the horizon map and the ray march look
up, and what the tangent-space normal map is dotted with (:mod:`hzval.techniques.surface`). A bug here is
therefore a bug in both, exactly as in an engine whose TBN matrix is wrong. Each bug is one
function ``(t, b, n, face) -> (t, b, n)`` on ``(N, 3)`` arrays (``face()``: each sample's base
triangle's own frame, computed only when asked) and one line of :data:`BUGS`:

``none``
    The correct frame.
``ignore-handedness``
    ``b = cross(n, t)``: the sign ``w`` dropped (forced +1). Wrong only where the UVs are mirrored
    (``w = -1``), where ``b`` then points along -v: the light's ``y`` in tangent space and the
    normal map's green both turn over. Invisible where ``w = +1`` everywhere (the xy quad).
``swap-uv``
    The tangent taken along v: ``t' = b``, ``b' = t`` (what FGED2's formula gives with the UV
    components swapped; the handedness it then computes is the opposite, which this swap keeps).
    The light's ``x`` and ``y`` trade places: a reflection of every lookup about the u = v diagonal.
    Invisible only on a height map symmetric under transposition.
``flip-green``
    The normal map's green (y) read with the wrong sign, the DirectX/OpenGL convention mismatch.
    In a TBN shader a normal ``(x, -y, z)`` against ``(t, b, n)`` is ``(x, y, z)`` against
    ``(t, -b, n)``; an engine of the other convention builds its bitangent along -v (its v runs down
    the image) and reads the horizon map with the same frame, so hzval negates ``b`` for both the
    normal map and the horizon lookup: the engine's whole tangent space is mirrored in v. On a
    mirrored face (``w = -1``) this equals ``ignore-handedness``: both give ``b = cross(n, t)`` there.
``per-face``
    Each base triangle's own flat frame (:func:`hzval.geometry.tangents.face_frames`: the geometric normal,
    ``dP/du`` rejected from it, the triangle's own handedness) instead of the vertex frames
    interpolated: faceted shading and lookups that jump at every edge. Invisible on a flat quad
    whose UVs are affine in position (every face frame is the vertex frame).
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from hzval.core.errors import InputError
from hzval.geometry import tangents as tg

__all__ = ["Bug", "BUGS", "NAMES", "check", "apply", "face_frames_at"]

Bug = Callable[[np.ndarray, np.ndarray, np.ndarray, Callable], tuple]


def _none(t, b, n, face):
    return t, b, n


def _ignore_handedness(t, b, n, face):
    return t, np.cross(n, t).astype(t.dtype), n


def _swap_uv(t, b, n, face):
    return b, t, n


def _flip_green(t, b, n, face):
    return t, -b, n


def _per_face(t, b, n, face):
    return face()


#: Bug name -> how it turns each sample's correct frame into the engine's (module docstring).
BUGS: dict[str, Bug] = {
    "none": _none,
    "ignore-handedness": _ignore_handedness,
    "swap-uv": _swap_uv,
    "flip-green": _flip_green,
    "per-face": _per_face,
}
NAMES: tuple[str, ...] = tuple(BUGS)


def check(name: str, what: str = "--tangent-bug") -> str:
    """``name`` if it is a bug of :data:`BUGS`, else one :class:`InputError` naming ``what``."""
    if name not in BUGS:
        raise InputError(what, f"unknown tangent bug {name!r}; known: {', '.join(NAMES)}")
    return name


def apply(name: str, frames: np.ndarray, face: Callable[[], tuple] | None = None) -> np.ndarray:
    """Return ``frames`` with ``t, b, n`` as the bug ``name`` makes them.

    ``frames`` is ``(N, 12)`` float32: ``t, b, n, v`` per sample (:data:`hzval.scene.lookup.FRAME_FLOATS`);
    ``v`` (toward the camera, world) is unchanged. ``face()`` returns each sample's base triangle's frame
    ``(t, b, n)`` (only ``per-face`` calls it). ``none`` returns ``frames`` itself, untouched.
    """
    if check(name) == "none":
        return frames
    t, b, n = (frames[:, 3 * k : 3 * k + 3] for k in range(3))
    t, b, n = BUGS[name](t, b, n, face)
    return np.concatenate([t, b, n, frames[:, 9:12]], axis=1).astype(frames.dtype)


def face_frames_at(model, prim: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return the frame of the base triangles ``prim`` of ``model``.

    The result is ``(t, b, n)``, each ``(N, 3)`` float32 (:func:`hzval.geometry.tangents.face_frames`), with
    ``b = w cross(n, t)`` and the triangle's own ``w``.
    """
    fn, ft = tg.face_frames(model.positions, model.uvs, model.faces)
    prim = np.asarray(prim, np.int64)
    n, t, w = fn[prim], ft[prim, :3], ft[prim, 3]
    b = np.cross(n, t) * w[:, None]
    return tuple(a.astype(np.float32) for a in (t, b, n))
