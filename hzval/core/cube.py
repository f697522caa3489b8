"""The weight cube map's layout and encoding (Lengyel, section 5.3).

It covers the OpenGL face order, each texel's centre direction, the face and texel a direction reads, and a
signed weight as 8 bits.
"""

from __future__ import annotations

import numpy as np

__all__ = ["CUBE_FACES", "cube_texel_directions", "cube_lookup", "encode_signed_weight"]

#: Cube faces in OpenGL order (GL_TEXTURE_CUBE_MAP_POSITIVE_X + i).
CUBE_FACES: tuple[str, ...] = ("posx", "negx", "posy", "negy", "posz", "negz")


def cube_texel_directions(size: int) -> np.ndarray:
    """Return the unnormalised direction through the centre of every texel of a cube map.

    The face layout is the OpenGL specification's (4.6, table 8.19): a direction ``r`` with major axis
    ``ma`` is looked up at ``s = (sc / |ma| + 1) / 2`` (column) and ``t = (tc / |ma| + 1) / 2`` (row, row 0
    first in memory). The cube is indexed with tangent-space vectors, so its x, y, z are tangent space's.
    The seed generators use two other layouts (docs/ARCHITECTURE.md); this one is the GPU's.

    Parameters
    ----------
    size : int
        Texels along a face's edge.

    Returns
    -------
    numpy.ndarray
        ``(6, size, size, 3)`` float64, indexed ``[face, row, col]``, faces in :data:`CUBE_FACES` order.

    Examples
    --------
    >>> cube_texel_directions(1)[:, 0, 0].tolist()[0]
    [1.0, -0.0, -0.0]
    """
    c = (np.arange(size) + 0.5) / size * 2.0 - 1.0
    tc, sc = np.meshgrid(c, c, indexing="ij")  # tc varies along rows
    one = np.ones_like(sc)
    faces = [
        (one, -tc, -sc),  # +x: sc = -rz, tc = -ry
        (-one, -tc, sc),  # -x: sc = +rz, tc = -ry
        (sc, one, tc),  # +y: sc = +rx, tc = +rz
        (sc, -one, -tc),  # -y: sc = +rx, tc = -rz
        (sc, -tc, one),  # +z: sc = +rx, tc = -ry
        (-sc, -tc, -one),  # -z: sc = -rx, tc = -ry
    ]
    return np.stack([np.stack(f, axis=-1) for f in faces])


def cube_lookup(direction: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return the face and face coordinates of directions; the inverse of :func:`cube_texel_directions`.

    Parameters
    ----------
    direction : array_like
        ``(..., 3)`` tangent-space directions (any length). Ties between axes go to x, then y, then z.

    Returns
    -------
    face : numpy.ndarray
        Face indices, :data:`CUBE_FACES` order (OpenGL table 8.19).
    s, t : numpy.ndarray
        Face coordinates in [0, 1], column and row.

    Examples
    --------
    >>> import numpy as np
    >>> face, s, t = cube_lookup(np.array([0.0, 0.0, 1.0]))
    >>> int(face), float(s), float(t)
    (4, 0.5, 0.5)
    """
    d = np.asarray(direction, dtype=np.float64)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    ax, ay, az = np.abs(x), np.abs(y), np.abs(z)
    use_x = (ax >= ay) & (ax >= az)
    use_y = ~use_x & (ay >= az)
    face = np.where(
        use_x, np.where(x >= 0, 0, 1), np.where(use_y, np.where(y >= 0, 2, 3), np.where(z >= 0, 4, 5))
    )
    ma = np.where(use_x, ax, np.where(use_y, ay, az))
    sc = np.choose(face, [-z, z, x, x, x, -x])
    tc = np.choose(face, [-y, -y, z, -z, -y, -y])
    return face, (sc / ma + 1.0) * 0.5, (tc / ma + 1.0) * 0.5


def encode_signed_weight(w: np.ndarray) -> np.ndarray:
    """Weights in [-1, 1] stored as 8-bit values: ``round((w + 1) 127.5)`` (Lengyel's remap).

    A zero weight (127.5) cannot be stored exactly and rounds (half to even) to 128, which decodes to
    ``2 * 128 / 255 - 1 = 1/255``.

    Parameters
    ----------
    w : array_like
        Weights in [-1, 1]; values outside are clamped.

    Returns
    -------
    numpy.ndarray
        uint8.

    Examples
    --------
    >>> encode_signed_weight([-1.0, 0.0, 1.0]).tolist()
    [0, 128, 255]
    """
    return np.clip(np.round((np.asarray(w, dtype=np.float64) + 1.0) * 127.5), 0, 255).astype(np.uint8)
