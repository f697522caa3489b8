"""The conventions of hzval: axes, directions, height scale, boundaries.

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
    sRGB-encoded 8-bit. The transfer functions are :mod:`hzval.core.srgb`'s.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np

from hzval.core.errors import InputError

__all__ = [
    "normal_map",
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
    "check_relief",
    "height_scale",
    "heights_in_texels",
    "pad_heights",
    "height_gradient",
    "light_direction",
    "azimuth_of",
    "channel_layer",
    "channel_weights",
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
    """Azimuth of a horizon channel: ``360 c / D`` degrees, counterclockwise from +x.

    Parameters
    ----------
    channel : int
        The channel ``c``, 0 to ``directions - 1``.
    directions : int
        ``D``, the map's number of stored directions (8 or 16).

    Returns
    -------
    float
        The azimuth in degrees.

    Examples
    --------
    >>> channel_azimuth_deg(3)
    135.0
    >>> channel_azimuth_deg(3, 16)
    67.5
    """
    return 360.0 * int(channel) / int(directions)


def channel_azimuths_deg(directions: int = CHANNEL_COUNT) -> tuple[float, ...]:
    """Azimuths of every channel of a ``D``-channel horizon map, in channel order.

    Parameters
    ----------
    directions : int
        ``D``, the map's number of stored directions.

    Returns
    -------
    tuple of float
        ``360 c / D`` degrees for ``c = 0 .. D - 1``.

    Examples
    --------
    >>> channel_azimuths_deg(8)
    (0.0, 45.0, 90.0, 135.0, 180.0, 225.0, 270.0, 315.0)
    """
    return tuple(channel_azimuth_deg(c, directions) for c in range(int(directions)))


def channels_per_radian(directions: int = CHANNEL_COUNT) -> float:
    """Channels per radian of azimuth, ``D / (2 pi)``: channel ``c`` sits at ``c 2 pi / D`` radians.

    Parameters
    ----------
    directions : int
        ``D``, the map's number of stored directions. For 8 the result is ``4 / pi`` exactly (a
        power-of-two scaling of ``1 / (2 pi)``).

    Returns
    -------
    float

    Examples
    --------
    >>> import math
    >>> channels_per_radian(8) == 4 / math.pi
    True
    """
    return int(directions) / (2.0 * math.pi)


def layer_count(directions: int = CHANNEL_COUNT) -> int:
    """RGBA layers that hold a horizon map's channels, four channels a layer.

    Parameters
    ----------
    directions : int
        ``D``, a multiple of 4.

    Returns
    -------
    int
        ``D / 4``.

    Raises
    ------
    ValueError
        If ``D`` does not fill whole layers.

    Examples
    --------
    >>> layer_count(8), layer_count(16)
    (2, 4)
    """
    if directions % CHANNELS_PER_LAYER:
        raise ValueError(f"the directions must fill whole RGBA layers, got {directions}")
    return int(directions) // CHANNELS_PER_LAYER


def texel_centres(rows: int, cols: int) -> tuple[np.ndarray, np.ndarray]:
    """Tangent-space coordinates of every texel centre.

    Parameters
    ----------
    rows, cols : int
        The height map's shape.

    Returns
    -------
    x, y : numpy.ndarray
        float64 arrays of shape ``(rows, cols)``, in texels: ``x = col + 0.5``, ``y = rows - row - 0.5``
        (+y up the image).

    Examples
    --------
    >>> x, y = texel_centres(2, 3)
    >>> x[0].tolist(), y[:, 0].tolist()
    ([0.5, 1.5, 2.5], [1.5, 0.5])
    """
    col = np.arange(cols, dtype=np.float64) + 0.5
    y = rows - np.arange(rows, dtype=np.float64) - 0.5
    return np.broadcast_to(col, (rows, cols)), np.broadcast_to(y[:, None], (rows, cols))


def bilinear_at(image: np.ndarray, x, y, boundary: str) -> np.ndarray:
    """Return an image read bilinearly between texel centres at tangent-space points (NumPy, float64).

    The truth's vertex normals (:func:`hzval.geometry.tile.vertex_normals`) and a model's displacement
    (:func:`hzval.geometry.displace.bilinear`) read through it.

    Parameters
    ----------
    image : numpy.ndarray
        ``(rows, cols)`` or ``(rows, cols, k)``, texel centres as :func:`texel_centres` places them.
    x, y : array_like
        Points in texels, tangent space, shape ``(n,)``.
    boundary : {"wrap", "open"}
        ``wrap`` repeats the image, ``open`` clamps to its border.

    Returns
    -------
    numpy.ndarray
        ``(n,)`` or ``(n, k)`` float64; at a texel centre, that texel exactly.

    Examples
    --------
    >>> import numpy as np
    >>> img = np.array([[0.0, 1.0], [2.0, 3.0]])
    >>> bilinear_at(img, np.array([1.0]), np.array([1.0]), "open").tolist()
    [1.5]
    """
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
    """Whether ``values`` is a Dr.Jit array (a kernel's operand) rather than NumPy or Python values.

    Parameters
    ----------
    values : object

    Returns
    -------
    bool

    Examples
    --------
    >>> is_drjit(1.0), is_drjit([1.0])
    (False, False)
    """
    return not isinstance(values, (np.ndarray, np.generic, float, int, list, tuple))


def tangent_to_uv(x, y, rows: int, cols: int) -> tuple[np.ndarray, np.ndarray]:
    """Tangent-space points as texture coordinates ``(u, v)``, float32.

    ``u = x / cols`` runs right, ``v = (rows - y) / rows`` runs down the image (row 0 at ``v = 0``), as
    Dr.Jit's and Mitsuba's textures index a ``(rows, cols)`` array; texel ``(row, col)``'s centre is at
    ``u = (col + 0.5) / cols``, ``v = (row + 0.5) / rows``. Computed in float64 and rounded once.

    Parameters
    ----------
    x, y : array_like or Dr.Jit array
        Points in texels. NumPy values, or Dr.Jit arrays (``mi.Float64`` in a kernel: the same bits).
    rows, cols : int
        The texture's shape.

    Returns
    -------
    u, v : numpy.ndarray or mitsuba.Float
        float32 texture coordinates.

    Examples
    --------
    >>> u, v = tangent_to_uv(0.5, 3.5, 4, 4)
    >>> float(u), float(v)
    (0.125, 0.125)
    """
    if is_drjit(x):
        # only on the Dr.Jit path: NumPy callers never load Dr.Jit
        import mitsuba as mi

        return mi.Float(mi.Float64(x) / cols), mi.Float((rows - mi.Float64(y)) / rows)
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    return (x / cols).astype(np.float32), ((rows - y) / rows).astype(np.float32)


def tangent_to_pixel_offset(dx: int, dy: int) -> tuple[int, int]:
    """Return a tangent-space offset as an offset in the image's rows and columns.

    Parameters
    ----------
    dx, dy : int
        Texels along +x (right) and +y (up).

    Returns
    -------
    tuple of int
        ``(drow, dcol) = (-dy, dx)``: +y is up, rows run down.

    Examples
    --------
    >>> tangent_to_pixel_offset(1, 2)
    (-2, 1)
    """
    return -dy, dx


def pixel_to_tangent_offset(drow: int, dcol: int) -> tuple[int, int]:
    """Return an offset in rows and columns as a tangent-space one; :func:`tangent_to_pixel_offset` inverted.

    Parameters
    ----------
    drow, dcol : int
        Rows down and columns right.

    Returns
    -------
    tuple of int
        ``(dx, dy) = (dcol, -drow)`` in texels.

    Examples
    --------
    >>> pixel_to_tangent_offset(*tangent_to_pixel_offset(3, -5))
    (3, -5)
    """
    return dcol, -drow


#: The deepest relief hzval renders on a ``wrap`` tile: ``depth`` (the world height of ``H = 1`` in
#: image widths) at most 10. The truth's shadow rays cross such a tile in hops of at most half a
#: tile, ``2 depth / tan(e)`` of them at elevation ``e`` (docs/reliability.md, "Bounds").
MAX_DEPTH = 10.0
#: The deepest relief of an ``open`` tile: no hops there, only float32's precision bounds it.
MAX_DEPTH_OPEN = 1000.0


def check_depth(depth, what: str = "--depth", boundary: str = "wrap") -> float:
    """Return a relief depth, checked against what the truth can render.

    Parameters
    ----------
    depth : float
        The world height of ``H = 1``, in image widths.
    what : str
        The flag or file key named in the error.
    boundary : {"wrap", "open"}
        ``open`` tiles allow :data:`MAX_DEPTH_OPEN`, ``wrap`` tiles :data:`MAX_DEPTH`.

    Returns
    -------
    float
        ``depth``.

    Raises
    ------
    hzval.core.errors.InputError
        One line naming ``what`` and why, when ``depth`` is not a number in ``(0, max]``.

    Examples
    --------
    >>> check_depth(0.05)
    0.05
    """
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


def check_relief(height: np.ndarray, depth: float, boundary: str = "wrap", what="height map") -> float:
    """Return the relief of a height map at ``depth``, checked against what the truth can render.

    :func:`check_depth` bounds ``depth``, the height of ``H = 1``; a map whose values run past
    [0, 1] (an EXR of heights in metres) stands taller by its range. The bound is the same
    (:data:`MAX_DEPTH` on a ``wrap`` tile, :data:`MAX_DEPTH_OPEN` on an ``open`` one), applied to
    ``depth * (max H - min H)``, so a map in [0, 1] passes wherever its depth does.

    Parameters
    ----------
    height : numpy.ndarray
        ``H[row, col]``, finite.
    depth : float
        The world height of ``H = 1``, in image widths.
    boundary : {"wrap", "open"}
    what : str or path-like
        The file named first in the error.

    Returns
    -------
    float
        The relief, in image widths.

    Raises
    ------
    hzval.core.errors.InputError
        One line naming ``what``, its height range and ``--depth``, when the relief is past the bound.

    Examples
    --------
    >>> import numpy as np
    >>> check_relief(np.array([[0.0, 0.5]]), 0.05)
    0.025
    >>> check_relief(np.array([[0.0, 1000.0]]), 0.05, what="dem.exr")
    Traceback (most recent call last):
    ...
    hzval.core.errors.InputError: dem.exr: heights run from 0 to 1000; at --depth 0.05 that is a relief of 50 image widths, above the 10 a wrap tile allows (scale the heights to [0, 1], or --depth 0.01 or less)
    """  # noqa: E501
    lo, hi = float(np.min(height)), float(np.max(height))
    relief = float(depth) * (hi - lo)
    top = MAX_DEPTH_OPEN if boundary == "open" else MAX_DEPTH
    if not relief <= top:  # NaN included
        tile = "an open tile" if boundary == "open" else f"a {boundary} tile"
        most = top / (hi - lo) if math.isfinite(hi - lo) and hi > lo else 0.0
        raise InputError(
            what,
            f"heights run from {lo:g} to {hi:g}; at --depth {depth:g} that is a relief of {relief:.3g} "
            f"image widths, above the {top:g} {tile} allows (scale the heights to [0, 1], or --depth "
            f"{_round_down(most)} or less)",
        )
    return relief


def _round_down(x: float) -> str:
    """``x`` rounded down to two significant digits, as a flag's value."""
    if x <= 0:
        return "0"
    step = 10.0 ** (math.floor(math.log10(x)) - 1)
    return f"{float(f'{math.floor(x / step + 1e-9) * step:.2g}'):g}"


def height_scale(depth: float, cols: int) -> float:
    """Return the factor from a normalised height ``H`` to texel units.

    Parameters
    ----------
    depth : float
        World height of ``H = 1``, in image widths.
    cols : int
        The height map's width in texels.

    Returns
    -------
    float
        ``depth * cols``.

    Examples
    --------
    >>> height_scale(0.05, 512)
    25.6
    """
    return float(depth) * int(cols)


def heights_in_texels(height: np.ndarray, depth: float) -> np.ndarray:
    """Return the heights every stage reads: ``H * depth * cols`` in texel units.

    Parameters
    ----------
    height : numpy.ndarray
        ``H[row, col]``, normalised to [0, 1].
    depth : float
        World height of ``H = 1``, in image widths.

    Returns
    -------
    numpy.ndarray
        float32, the shape of ``height``.

    Examples
    --------
    >>> import numpy as np
    >>> heights_in_texels(np.array([[0.0, 1.0]]), 0.5).tolist()
    [[0.0, 1.0]]
    """
    height = np.asarray(height, dtype=np.float32)
    return height * np.float32(height_scale(depth, height.shape[1]))


def pad_heights(h: np.ndarray, pad: int | tuple, boundary: str) -> np.ndarray:
    """Return a height map extended beyond its edges as the boundary prescribes.

    Parameters
    ----------
    h : numpy.ndarray
        Heights ``(rows, cols)``.
    pad : int or tuple
        Widths as :func:`numpy.pad` takes them.
    boundary : {"wrap", "open"}
        ``wrap`` repeats the tile (any size, also pads wider than the image); ``open`` fills with
        ``-inf``: nothing is there, nothing outside the image occludes, and ``-inf`` loses every ``max``.

    Returns
    -------
    numpy.ndarray

    Examples
    --------
    >>> import numpy as np
    >>> pad_heights(np.array([[1.0, 2.0]]), ((0, 0), (1, 1)), "wrap").tolist()
    [[2.0, 1.0, 2.0, 1.0]]
    """
    if boundary == "wrap":
        return np.pad(h, pad, mode="wrap")
    if boundary == "open":
        return np.pad(h, pad, mode="constant", constant_values=-np.inf)
    raise ValueError(f"unknown boundary {boundary!r}")


def height_gradient(h: np.ndarray, boundary: str) -> tuple[np.ndarray, np.ndarray]:
    """Tangent-space slopes of heights, by central differences.

    +y is *up* the image, so ``dh/dy`` at row ``r`` is ``(h[r-1] - h[r+1]) / 2``.

    Parameters
    ----------
    h : numpy.ndarray
        Heights ``(rows, cols)`` in texel units.
    boundary : {"wrap", "open"}
        ``wrap`` takes the neighbours across the edge; ``open`` uses one-sided differences at the border,
        and zero slope along an axis of length 1.

    Returns
    -------
    dhdx, dhdy : numpy.ndarray
        float32 slopes, the shape of ``h``.

    Examples
    --------
    >>> import numpy as np
    >>> gx, gy = height_gradient(np.array([[0.0, 1.0, 2.0, 3.0]]), "open")
    >>> gx.tolist(), bool((gy == 0).all())
    ([[1.0, 1.0, 1.0, 1.0]], True)
    """
    h = np.asarray(h, dtype=np.float32)

    def central(axis: int) -> np.ndarray:
        if h.shape[axis] == 1:
            return np.zeros_like(h)
        if boundary == "wrap":
            return (np.roll(h, -1, axis) - np.roll(h, 1, axis)) * np.float32(0.5)
        return np.gradient(h, axis=axis).astype(np.float32)

    return central(1), -central(0)


def normal_map(h_texels: np.ndarray, boundary: str) -> np.ndarray:
    """Return the unit tangent-space normals of a height field: ``normalize(-dh/dx, -dh/dy, 1)``.

    Central differences of heights in texel units (:func:`height_gradient`; FGED2 ch. 7, with its
    listing's use-before-definition fixed, docs/ARCHITECTURE.md). The bake stores them; the truth's
    smooth shading and the tile mesh's vertex normals read the same ones.

    Parameters
    ----------
    h_texels : numpy.ndarray
        Heights ``(rows, cols)`` in texel units.
    boundary : {"wrap", "open"}
        As :func:`height_gradient`.

    Returns
    -------
    numpy.ndarray
        float32 ``(rows, cols, 3)``, +x right, +y up the image, +z out of the surface.

    Examples
    --------
    >>> import numpy as np
    >>> n = normal_map(np.array([[0.0, 1.0, 2.0]]), "open")  # a 45-degree ramp rising to +x
    >>> [round(float(c), 4) for c in n[0, 1]]
    [-0.7071, 0.0, 0.7071]
    """
    gx, gy = height_gradient(h_texels, boundary)
    n = np.stack([-gx, -gy, np.ones_like(gx)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return n.astype(np.float32)


def light_direction(azimuth_deg: float, elevation_deg: float) -> np.ndarray:
    """Return the unit tangent-space vector toward a light: ``L = (cos e cos phi, cos e sin phi, sin e)``.

    Parameters
    ----------
    azimuth_deg : float
        ``phi``, degrees counterclockwise from +x as seen on screen.
    elevation_deg : float
        ``e``, degrees above the surface.

    Returns
    -------
    numpy.ndarray
        ``(3,)`` float64, pointing *toward* the light.

    Examples
    --------
    >>> light_direction(90.0, 0.0).round(12).tolist()
    [0.0, 1.0, 0.0]
    """
    phi = math.radians(azimuth_deg)
    e = math.radians(elevation_deg)
    return np.array([math.cos(e) * math.cos(phi), math.cos(e) * math.sin(phi), math.sin(e)])


def azimuth_of(x, y):
    """Return the azimuth of a tangent-space direction, on NumPy and Dr.Jit arrays alike.

    Parameters
    ----------
    x, y : array_like or Dr.Jit array
        The direction's tangent-space components.

    Returns
    -------
    array
        ``atan2(y, x)`` in radians, in (-pi, pi].

    Examples
    --------
    >>> import numpy as np
    >>> float(azimuth_of(0.0, 1.0)) == np.pi / 2
    True
    """
    try:
        # only on the Dr.Jit path: NumPy callers never load Dr.Jit
        import drjit as dr

        if dr.is_array_v(x) or dr.is_array_v(y):
            return dr.atan2(y, x)
    except ImportError:  # pragma: no cover - drjit is a dependency
        pass
    return np.arctan2(y, x)


def channel_layer(channel: int) -> tuple[int, int]:
    """Where a horizon channel is stored: its RGBA layer and component.

    Parameters
    ----------
    channel : int
        The channel, 0 to ``D - 1``.

    Returns
    -------
    tuple of int
        ``(layer, component) = divmod(channel, 4)``.

    Examples
    --------
    >>> channel_layer(5)
    (1, 1)
    """
    return divmod(int(channel), CHANNELS_PER_LAYER)


def channel_weights(lx, ly, directions: int = CHANNEL_COUNT) -> np.ndarray:
    """Exact weights of the horizon channels for a light direction (Lengyel, *Smooth Horizon Mapping*, 5.3).

    The horizon sine toward ``phi = atan2(ly, lx)`` is the linear interpolation between the two channels
    adjacent to ``phi``: a tent in ``360 / D``-degree steps. A light straight above (``lx = ly = 0``)
    takes ``phi = 0``: its elevation is 90 degrees, above every horizon, so the choice does not matter.

    Parameters
    ----------
    lx, ly : array_like
        The light's tangent-space x and y (any scale).
    directions : int
        ``D``, the map's number of stored directions.

    Returns
    -------
    numpy.ndarray
        float64 ``(..., D)``; each row sums to 1.

    Examples
    --------
    >>> channel_weights(1.0, 1.0).tolist()
    [0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    >>> import numpy as np
    >>> w = channel_weights(np.cos(np.radians(22.5)), np.sin(np.radians(22.5)))
    >>> np.round(w[:2], 12).tolist()
    [0.5, 0.5]
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
