"""Cube-map sampling as OpenGL defines it, in Dr.Jit: face selection and seamless bilinear filtering.

A GPU running Listing 5.1 reads the weight cube map with
``GL_TEXTURE_CUBE_MAP_SEAMLESS`` (ARB_seamless_cube_map, core in OpenGL 3.2;
always on in GL ES 3 and Vulkan). OpenGL 4.6, section 8.13.1 and 8.14.2:

Face selection (table 8.19)
    the major axis ``ma`` of the direction ``r`` picks the face (ties here go
    to x, then y, then z, as :func:`hzval.core.cube.cube_lookup`; the spec
    leaves ties to the implementation); ``s = (sc / |ma| + 1) / 2``, ``t =
    (tc / |ma| + 1) / 2``.
Bilinear filtering
    at ``u = s n - 1/2``, ``v = t n - 1/2`` in texels of the ``n x n`` face,
    the four texels ``i0 = floor(u)``, ``i0 + 1`` by ``j0 = floor(v)``,
    ``j0 + 1``, weighted by the fractions.
Seamless
    a texel that falls off the face (``i`` or ``j`` = -1 or ``n``) is read
    from the adjacent face "as if the faces were a cube": here the texel
    whose centre the extended face's texel centre projects onto (its
    direction, :data:`FACE_AXES`, looked up again; the projection moves a
    centre by less than half a texel along the edge, so it stays in the
    texel that the cube's edge adjacency gives). A texel off the face in
    both directions (a cube corner) has no unique neighbour: the spec
    recommends the average of the three texels that are there, which is
    what this does.

Without seamless filtering a GPU clamps to the face's edge texels
(:func:`bilinear` ``seamless=False``).
"""

from __future__ import annotations

from hzval.core.backend import dr, mi  # Dr.Jit loads at first use, once the LLVM is chosen

__all__ = ["FACE_AXES", "face_coordinates", "bilinear"]

#: Per face (OpenGL order +x, -x, +y, -y, +z, -z): the direction of face coordinates ``(sc, tc)``
#: as ``(major, s axis, t axis)``, each ``(component, sign)``: ``r = major + sc * s_axis + tc * t_axis``
#: (the inverse of table 8.19; :func:`hzval.core.cube.cube_texel_directions`).
FACE_AXES: tuple = (
    ((0, 1.0), (2, -1.0), (1, -1.0)),  # +x: sc = -rz, tc = -ry
    ((0, -1.0), (2, 1.0), (1, -1.0)),  # -x: sc = +rz, tc = -ry
    ((1, 1.0), (0, 1.0), (2, 1.0)),  # +y: sc = +rx, tc = +rz
    ((1, -1.0), (0, 1.0), (2, -1.0)),  # -y: sc = +rx, tc = -rz
    ((2, 1.0), (0, 1.0), (1, -1.0)),  # +z: sc = +rx, tc = -ry
    ((2, -1.0), (0, -1.0), (1, -1.0)),  # -z: sc = -rx, tc = -ry
)


def face_coordinates(x, y, z):
    """Return the cube-map face and face coordinates of directions (OpenGL 4.6, table 8.19).

    Parameters
    ----------
    x, y, z : drjit.Float
        The directions' components (need not be unit); ties of the major axis go to x, then y, then z.

    Returns
    -------
    face : drjit.UInt32
        0..5 in OpenGL order (:data:`hzval.core.cube.CUBE_FACES`).
    s, t : drjit.Float
        ``(sc / |ma| + 1) / 2`` and ``(tc / |ma| + 1) / 2``, in [0, 1].
    """
    ax, ay, az = dr.abs(x), dr.abs(y), dr.abs(z)
    use_x = (ax >= ay) & (ax >= az)
    use_y = ~use_x & (ay >= az)
    face = dr.select(
        use_x,
        dr.select(x >= 0, mi.UInt32(0), mi.UInt32(1)),
        dr.select(
            use_y,
            dr.select(y >= 0, mi.UInt32(2), mi.UInt32(3)),
            dr.select(z >= 0, mi.UInt32(4), mi.UInt32(5)),
        ),
    )
    ma = dr.select(use_x, ax, dr.select(use_y, ay, az))
    sc = dr.select(use_x, dr.select(x >= 0, -z, z), dr.select(use_y | (z >= 0), x, -x))
    tc = dr.select(use_y, dr.select(y >= 0, z, -z), -y)
    inv = dr.rcp(ma)
    return face, dr.fma(sc * inv, 0.5, 0.5), dr.fma(tc * inv, 0.5, 0.5)


def _texel_direction(face, sc, tc):
    """Return the direction of face coordinates ``(sc, tc)`` of ``face``.

    The coordinates are in [-1, 1] (or beyond); the faces are :data:`FACE_AXES`.
    """
    comps = []
    for axis in range(3):
        value = mi.Float(0.0)
        for f, ((m, ms), (s, ss), (_t, ts)) in enumerate(FACE_AXES):
            here = ms if m == axis else (ss * sc if s == axis else ts * tc)
            value = dr.select(face == f, here, value)
        comps.append(value)
    return comps


def _texel(cube, n: int, face, i, j, seamless: bool):
    """Return the texel ``(i, j)`` of ``face`` as a ``mi.Vector4f`` gathered from ``cube``.

    ``(i, j)`` is column, row (Int32, possibly one off the face); ``cube`` is ``(6, n, n, 4)`` float32
    flattened. The texel is read on the adjacent face (seamless) or is the clamped edge texel.
    """
    if seamless:
        sc = (mi.Float(i) + 0.5) * (2.0 / n) - 1.0
        tc = (mi.Float(j) + 0.5) * (2.0 / n) - 1.0
        face, s, t = face_coordinates(*_texel_direction(face, sc, tc))
        i, j = mi.Int32(dr.floor(s * n)), mi.Int32(dr.floor(t * n))
    i, j = dr.clip(i, 0, n - 1), dr.clip(j, 0, n - 1)
    index = (face * n + mi.UInt32(j)) * n + mi.UInt32(i)
    return dr.gather(mi.Vector4f, cube, index)


def bilinear(cube, n: int, d, seamless: bool = True):
    """Return the bilinearly filtered texel of a cube map toward directions, as a GPU samples it.

    Parameters
    ----------
    cube : mitsuba.Float
        The map, ``(6, n, n, 4)`` float32 flattened.
    n : int
        The side of a face, in texels.
    d : mitsuba.Vector3f
        Directions (tangent space).
    seamless : bool
        Filter across face edges with the neighbouring face's texels (``GL_TEXTURE_CUBE_MAP_SEAMLESS``,
        the module docstring); ``False`` clamps to the face.

    Returns
    -------
    mitsuba.Vector4f
        The filtered RGBA.
    """
    face, s, t = face_coordinates(d.x, d.y, d.z)
    u, v = dr.fma(s, float(n), -0.5), dr.fma(t, float(n), -0.5)
    fu, fv = dr.floor(u), dr.floor(v)
    a, b = u - fu, v - fv
    i0, j0 = mi.Int32(fu), mi.Int32(fv)
    t00 = _texel(cube, n, face, i0, j0, seamless)
    t10 = _texel(cube, n, face, i0 + 1, j0, seamless)
    t01 = _texel(cube, n, face, i0, j0 + 1, seamless)
    t11 = _texel(cube, n, face, i0 + 1, j0 + 1, seamless)
    if seamless:
        # a corner of the cube: the fourth texel is the mean of the three that are there
        def off(k):
            return (k < 0) | (k >= n)

        corner = off(i0) | off(i0 + 1), off(j0) | off(j0 + 1)
        at_corner = corner[0] & corner[1]
        third = 1.0 / 3.0
        t00 = dr.select(at_corner & off(i0) & off(j0), (t10 + t01 + t11) * third, t00)
        t10 = dr.select(at_corner & off(i0 + 1) & off(j0), (t00 + t01 + t11) * third, t10)
        t01 = dr.select(at_corner & off(i0) & off(j0 + 1), (t00 + t10 + t11) * third, t01)
        t11 = dr.select(at_corner & off(i0 + 1) & off(j0 + 1), (t00 + t10 + t01) * third, t11)
    return dr.lerp(dr.lerp(t00, t10, a), dr.lerp(t01, t11, a), b)
