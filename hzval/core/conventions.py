"""The conventions of hzval: axes, directions, height scale, boundaries, colour.

This module is the only place that defines them (docs/ARCHITECTURE.md,
"Conventions"); every other module asks it. Tests in
``tests/core/test_conventions.py`` pin each one.

Height map
    ``H[row, col]``, row 0 at the top of the image as displayed. PNG values are
    data, normalised to [0, 1] without sRGB decoding.

Tangent space (texel units)
    +x = increasing column (right on screen), +y = decreasing row (up on
    screen), +z = out of the surface. The centre of texel ``(row, col)`` sits
    at ``x = col + 0.5``, ``y = rows - row - 0.5``.

Height scale
    ``depth`` is the world height of ``H = 1`` in units of the image width, so
    a height in texel units is ``H * depth * cols``.

Directions
    Azimuth ``phi`` is measured counterclockwise from +x as seen on screen.
    A horizon map stores ``D`` directions (8, the default and the seed's, or
    16): channel ``k`` (0..D-1) is azimuth ``360 k / D`` degrees (``45 k``
    for 8); RGBA layer ``l`` holds channels ``4 l .. 4 l + 3``, so 8
    directions fill layers 0-1 and 16 directions layers 0-3.

Light
    ``L = (cos e cos phi, cos e sin phi, sin e)`` points *toward* the light.

Boundary
    ``wrap``: the texture tiles. ``open``: nothing exists outside the image.

Colour
    Renders are linear float. Albedo images are sRGB-encoded; previews are
    sRGB-encoded 8-bit. The transfer functions are colour-science's.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np

from hzval.core.errors import InputError

__all__ = [
    "Boundary",
    "BOUNDARIES",
    "CHANNEL_COUNT",
    "CHANNEL_AZIMUTHS_DEG",
    "CHANNELS_PER_LAYER",
    "DIRECTION_COUNTS",
    "channel_azimuth_deg",
    "channel_azimuths_deg",
    "channels_per_radian",
    "layer_count",
    "texel_centres",
    "bilinear_at",
    "is_drjit",
    "tangent_to_uv",
    "tangent_to_pixel_offset",
    "pixel_to_tangent_offset",
    "MAX_DEPTH",
    "MAX_DEPTH_OPEN",
    "check_depth",
    "height_scale",
    "heights_in_texels",
    "pad_heights",
    "height_gradient",
    "light_direction",
    "azimuth_of",
    "channel_layer",
    "channel_weights",
    "CUBE_FACES",
    "cube_texel_directions",
    "cube_lookup",
    "encode_signed_weight",
    "srgb_decode",
    "srgb_encode",
    "luminance_weights",
]

Boundary = Literal["wrap", "open"]
BOUNDARIES: tuple[str, ...] = ("wrap", "open")

#: Number of horizon channels of the default (seed) horizon map and their
#: azimuths in degrees.
CHANNEL_COUNT = 8
CHANNEL_AZIMUTHS_DEG = tuple(45.0 * k for k in range(CHANNEL_COUNT))
#: Channels per RGBA layer of the horizon map.
CHANNELS_PER_LAYER = 4
#: Numbers of stored horizon directions a bake may have
#: (:attr:`hzval.bake.maps.BakeParams.directions`): the seed's 8, or 16.
DIRECTION_COUNTS: tuple[int, ...] = (8, 16)


def channel_azimuth_deg(channel: int, directions: int = CHANNEL_COUNT) -> float:
    """Azimuth in degrees of horizon channel ``channel`` of a ``directions``-channel map: ``360 c / D``."""
    return 360.0 * int(channel) / int(directions)


def channel_azimuths_deg(directions: int = CHANNEL_COUNT) -> tuple[float, ...]:
    """Azimuths in degrees of all channels of a ``directions``-channel map, channel order."""
    return tuple(channel_azimuth_deg(c, directions) for c in range(int(directions)))


def channels_per_radian(directions: int = CHANNEL_COUNT) -> float:
    """``D / (2 pi)``: channel ``c`` of a ``D``-channel map sits at ``c * 2 pi / D`` radians.

    For 8 channels this is ``4 / pi`` exactly (a power-of-two scaling of
    ``1 / (2 pi)``)."""
    return int(directions) / (2.0 * math.pi)


def layer_count(directions: int = CHANNEL_COUNT) -> int:
    """RGBA layers that hold ``directions`` channels (``directions / 4``)."""
    if directions % CHANNELS_PER_LAYER:
        raise ValueError(f"the directions must fill whole RGBA layers, got {directions}")
    return int(directions) // CHANNELS_PER_LAYER


# --------------------------------------------------------------------------
# Axes and height scale
# --------------------------------------------------------------------------


def texel_centres(rows: int, cols: int) -> tuple[np.ndarray, np.ndarray]:
    """Tangent-space ``(x, y)`` of every texel centre, each of shape (rows, cols).

    Units are texels; ``x = col + 0.5`` and ``y = rows - row - 0.5``.
    """
    col = np.arange(cols, dtype=np.float64) + 0.5
    y = rows - np.arange(rows, dtype=np.float64) - 0.5
    return np.broadcast_to(col, (rows, cols)), np.broadcast_to(y[:, None], (rows, cols))


def bilinear_at(image: np.ndarray, x, y, boundary: str) -> np.ndarray:
    """``image`` (``(rows, cols)`` or ``(rows, cols, k)``) read bilinearly between texel centres
    (:func:`texel_centres`) at tangent-space points ``(x, y)`` in texels, float64 (NumPy): ``wrap``
    repeats the image, ``open`` clamps to its border. Returns ``(n,)`` or ``(n, k)``; at a texel
    centre, that texel exactly. The truth's vertex normals (:func:`hzval.geometry.tile.vertex_normals`) and a
    model's displacement (:func:`hzval.geometry.displace.bilinear`) read through it."""
    img = np.asarray(image, np.float64)
    rows, cols = img.shape[:2]
    fx = np.asarray(x, np.float64) - 0.5  # column coordinate of the centres
    fy = rows - np.asarray(y, np.float64) - 0.5  # row coordinate
    c0, r0 = np.floor(fx), np.floor(fy)
    a, b = fx - c0, fy - r0
    if img.ndim == 3:
        a, b = a[:, None], b[:, None]
    c0, r0 = c0.astype(np.int64), r0.astype(np.int64)

    def at(r, c):
        if boundary == "wrap":
            return img[r % rows, c % cols]
        return img[np.clip(r, 0, rows - 1), np.clip(c, 0, cols - 1)]

    return (1 - b) * ((1 - a) * at(r0, c0) + a * at(r0, c0 + 1)) + b * (
        (1 - a) * at(r0 + 1, c0) + a * at(r0 + 1, c0 + 1)
    )


def is_drjit(values) -> bool:
    """Whether ``values`` is a Dr.Jit array (a kernel's operand) rather than NumPy or Python values."""
    return not isinstance(values, (np.ndarray, np.generic, float, int, list, tuple))


def tangent_to_uv(x, y, rows: int, cols: int) -> tuple[np.ndarray, np.ndarray]:
    """Tangent-space points ``(x, y)`` in texels as texture coordinates ``(u, v)``, float32.

    ``u = x / cols`` runs right, ``v = (rows - y) / rows`` runs down the
    image (row 0 at ``v = 0``), as Dr.Jit's and Mitsuba's textures index a
    ``(rows, cols)`` array; texel ``(row, col)``'s centre is at ``u = (col +
    0.5) / cols``, ``v = (row + 0.5) / rows``. Computed in float64 and rounded once:
    NumPy values, or Dr.Jit arrays (``mi.Float64`` in a kernel: the same bits).
    """
    if is_drjit(x):
        import mitsuba as mi

        return mi.Float(mi.Float64(x) / cols), mi.Float((rows - mi.Float64(y)) / rows)
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    return (x / cols).astype(np.float32), ((rows - y) / rows).astype(np.float32)


def tangent_to_pixel_offset(dx: int, dy: int) -> tuple[int, int]:
    """A tangent-space offset ``(dx, dy)`` in texels as ``(drow, dcol)``."""
    return -dy, dx


def pixel_to_tangent_offset(drow: int, dcol: int) -> tuple[int, int]:
    """A pixel offset ``(drow, dcol)`` as a tangent-space ``(dx, dy)`` in texels."""
    return dcol, -drow


#: The deepest relief hzval renders: ``depth`` (the world height of ``H = 1`` in image widths) at
#: most 10, a relief ten times as tall as the tile is wide. Why: the truth's shadow rays over a
#: ``wrap`` tile are traced in hops of at most half a tile (:mod:`hzval.truth.plane`, "Boundaries"), so a
#: ray leaving the lowest point at elevation ``e`` needs ``2 depth / tan(e)`` hops: 113 at depth 10
#: and 10 degrees, 10^9 at the 10^8 the audit tried (it did not end in 600 s). Measured at the
#: bound: 256 x 256, 4 spp, a light at 2 degrees, 4.8 s a frame of the truth (0.05 s at the
#: bricks' 0.05). Far past it the relief in texels (``depth * cols``, float32) outgrows the
#: precision of a camera ray's hit (the audit's 1e30: "a camera ray missed"). Depth 5 is a
#: supported case (issue 16); the built-in materials use 0.02-0.12. An ``open`` tile has no hops (a
#: ray leaves it once it has crossed it), so its bound is only the precision's: a spike 1000 texels
#: tall on a 16-texel terrain (depth 62.5) is one of the hard cases (tests/hard/test_geometry.py).
MAX_DEPTH = 10.0
#: The deepest relief of an ``open`` tile (module comment above).
MAX_DEPTH_OPEN = 1000.0


def check_depth(depth, what: str = "--depth", boundary: str = "wrap") -> float:
    """``depth`` if it is a number in ``(0, MAX_DEPTH]`` (``open``: ``MAX_DEPTH_OPEN``), else one line
    naming ``what`` and why."""
    if isinstance(depth, bool) or not isinstance(depth, (int, float, np.integer, np.floating)):
        raise InputError(what, f"must be a number of image widths, got {depth!r}")
    top = MAX_DEPTH_OPEN if boundary == "open" else MAX_DEPTH
    if not math.isfinite(depth) or not 0 < depth <= top:
        why = (
            "the relief against the tile; deeper, the truth's shadow rays would cross a wrap tile in ever "
            "more hops"
            if boundary != "open"
            else "deeper, the relief outgrows float32's precision"
        )
        tile = "an open tile" if boundary == "open" else f"a {boundary} tile"
        raise InputError(what, f"must be in (0, {top:g}] image widths for {tile} ({why}), got {depth:g}")
    return float(depth)


def height_scale(depth: float, cols: int) -> float:
    """Factor from a normalised height ``H`` to texel units: ``depth * cols``."""
    return float(depth) * int(cols)


def heights_in_texels(height: np.ndarray, depth: float) -> np.ndarray:
    """``H * depth * cols`` as float32: the heights that every stage reads."""
    height = np.asarray(height, dtype=np.float32)
    return height * np.float32(height_scale(depth, height.shape[1]))


def pad_heights(h: np.ndarray, pad: int | tuple, boundary: str) -> np.ndarray:
    """Extend a height map beyond its edges as the boundary prescribes.

    ``wrap`` repeats the tile (any size, also pads wider than the image);
    ``open`` fills with ``-inf``: nothing is there, so nothing outside the
    image can occlude, and ``-inf`` loses every ``max``.
    """
    if boundary == "wrap":
        return np.pad(h, pad, mode="wrap")
    if boundary == "open":
        return np.pad(h, pad, mode="constant", constant_values=-np.inf)
    raise ValueError(f"unknown boundary {boundary!r}")


def height_gradient(h: np.ndarray, boundary: str) -> tuple[np.ndarray, np.ndarray]:
    """Tangent-space slopes ``(dh/dx, dh/dy)`` of heights ``h`` by central differences.

    ``h`` and the slopes are in texel units. +y is *up* the image, so
    ``dh/dy`` at row ``r`` is ``(h[r-1] - h[r+1]) / 2``. ``wrap`` takes the
    neighbours across the edge; ``open`` uses one-sided differences at the
    border (there is no neighbour), and zero slope along an axis of length 1.
    """
    h = np.asarray(h, dtype=np.float32)

    def central(axis: int) -> np.ndarray:
        if h.shape[axis] == 1:
            return np.zeros_like(h)
        if boundary == "wrap":
            return (np.roll(h, -1, axis) - np.roll(h, 1, axis)) * np.float32(0.5)
        return np.gradient(h, axis=axis).astype(np.float32)

    return central(1), -central(0)


# --------------------------------------------------------------------------
# Directions
# --------------------------------------------------------------------------


def light_direction(azimuth_deg: float, elevation_deg: float) -> np.ndarray:
    """Unit tangent-space vector toward a light at ``(azimuth, elevation)``.

    ``L = (cos e cos phi, cos e sin phi, sin e)``, angles in degrees.
    """
    phi = math.radians(azimuth_deg)
    e = math.radians(elevation_deg)
    return np.array([math.cos(e) * math.cos(phi), math.cos(e) * math.sin(phi), math.sin(e)])


def azimuth_of(x, y):
    """Azimuth in radians, in (-pi, pi], of the tangent-space direction ``(x, y)``.

    Works on NumPy and Dr.Jit arrays alike.
    """
    try:
        import drjit as dr

        if dr.is_array_v(x) or dr.is_array_v(y):
            return dr.atan2(y, x)
    except ImportError:  # pragma: no cover - drjit is a dependency
        pass
    return np.arctan2(y, x)


def channel_layer(channel: int) -> tuple[int, int]:
    """``(layer, component)`` that store horizon channel ``channel`` (0..D-1)."""
    return divmod(int(channel), CHANNELS_PER_LAYER)


def channel_weights(lx, ly, directions: int = CHANNEL_COUNT) -> np.ndarray:
    """Exact weights of the ``directions`` horizon channels for a light direction ``(lx, ly)``.

    The horizon sine toward azimuth ``phi`` is the linear interpolation
    between the two channels adjacent to ``phi = atan2(ly, lx)`` (Lengyel,
    section 5.3, for 8; the same tent in ``360 / D``-degree steps for ``D``
    channels); the weights sum to 1. Returns shape ``(..., directions)``. A
    light straight above (``lx = ly = 0``) takes ``phi = 0``: its elevation
    is 90 degrees, above every horizon, so the choice does not matter.
    """
    n = int(directions)
    phi = np.arctan2(np.asarray(ly, dtype=np.float64), np.asarray(lx, dtype=np.float64))
    # divided by the spacing 2 pi / n rather than times channels_per_radian(n):
    # 2 pi / 8 is pi / 4 exactly, so 8 channels keep their original arithmetic
    t = np.mod(phi / (2.0 * np.pi / n), n)
    lo = np.floor(t).astype(np.int64) % n
    frac = t - np.floor(t)
    hi = (lo + 1) % n
    w = np.zeros(np.shape(t) + (n,))
    np.put_along_axis(w, lo[..., None], (1.0 - frac)[..., None], axis=-1)
    # add, not put: when frac == 0, hi's weight is 0 and must not clobber lo
    w_hi = np.take_along_axis(w, hi[..., None], axis=-1) + frac[..., None]
    np.put_along_axis(w, hi[..., None], w_hi, axis=-1)
    return w


# --------------------------------------------------------------------------
# The weight cube map (OpenGL face layout)
# --------------------------------------------------------------------------

#: Cube faces in OpenGL order (GL_TEXTURE_CUBE_MAP_POSITIVE_X + i).
CUBE_FACES: tuple[str, ...] = ("posx", "negx", "posy", "negy", "posz", "negz")


def cube_texel_directions(size: int) -> np.ndarray:
    """Unnormalised direction through the centre of every cube-map texel.

    Shape ``(6, size, size, 3)``, indexed ``[face, row, col]``, with the face
    layout of the OpenGL specification (4.6, table 8.19): a direction ``r``
    with major axis ``ma`` is looked up at ``s = (sc/|ma| + 1)/2`` (column)
    and ``t = (tc/|ma| + 1)/2`` (row, row 0 first in memory). The cube is
    indexed with tangent-space vectors, so its x, y, z are tangent space's.
    The seed generators use two different layouts (docs/ARCHITECTURE.md); this one is
    the GPU's.
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
    """Face index and face coordinates ``(s, t)`` in [0, 1] of directions ``(..., 3)``.

    The inverse of :func:`cube_texel_directions` (OpenGL table 8.19). Ties
    between axes go to x, then y, then z.
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
    """Store weights in [-1, 1] as 8-bit values, ``round((w + 1) * 127.5)``.

    Lengyel remaps [-1, 1] to [0, 255]; a zero weight (127.5) cannot be stored
    exactly and rounds (half to even) to 128, which decodes to a weight of
    ``2 * 128 / 255 - 1 = 1/255`` on layer 0.
    """
    return np.clip(np.round((np.asarray(w, dtype=np.float64) + 1.0) * 127.5), 0, 255).astype(np.uint8)


# --------------------------------------------------------------------------
# Colour
# --------------------------------------------------------------------------


def srgb_decode(values: np.ndarray) -> np.ndarray:
    """sRGB-encoded values in [0, 1] to linear (IEC 61966-2-1, via colour-science)."""
    import colour

    return np.asarray(colour.cctf_decoding(np.asarray(values, dtype=np.float64), function="sRGB"))


def srgb_encode(values):
    """Linear values to sRGB-encoded values (IEC 61966-2-1), negatives as 0.

    NumPy values (or anything array-like) go through colour-science's
    ``cctf_encoding(function="sRGB")``. A Dr.Jit array (``mi.Float64``: the
    comparison's display values, :func:`hzval.metrics.compare.display`) is encoded in a
    kernel by the formula colour-science's ``eotf_inverse_sRGB`` evaluates,
    ``12.92 L`` at or below ``L = 0.0031308``, else ``1.055 L^(1/2.4) - 0.055``:
    within 4e-16 of it in float64 (Dr.Jit's ``pow`` is not NumPy's), 25x faster on
    12M values on this 2-core machine (``tests/metrics/test_compare.py``).
    """
    if is_drjit(values):
        import drjit as dr

        v = dr.maximum(values, 0.0)
        return dr.select(v <= 0.0031308, v * 12.92, 1.055 * dr.power(v, 1 / 2.4) - 0.055)
    import colour

    v = np.clip(np.asarray(values, dtype=np.float64), 0.0, None)
    return np.asarray(colour.cctf_encoding(v, function="sRGB"))


def luminance_weights() -> np.ndarray:
    """Weights of R, G, B in the luminance Y of the sRGB / Rec. 709 primaries.

    Taken from colour-science's sRGB RGB-to-XYZ matrix (its Y row), so that
    RGB height maps are reduced as ``Y = w . rgb`` on their data values.
    """
    import colour

    return np.asarray(colour.RGB_COLOURSPACES["sRGB"].matrix_RGB_to_XYZ[1], dtype=np.float64)
