"""The camera: the one place that knows the view (docs/ARCHITECTURE.md, "Views").

The truth and every technique ask it for their primary rays; nothing else
knows where the eye is. Units are the tangent-space texels of
:mod:`hzval.core.conventions` (+x right, +y up the image, +z out of the surface,
heights ``H * depth * cols``); angles in degrees.

Kinds (:data:`KINDS`)
    ``top``: today's view, the default: orthographic, straight down over the
    whole tile, ``supersampling`` pixels per texel; pixel ``(row, col)``
    sees ``x = (col + j_u) / ss``, ``y = rows - (row + j_v) / ss`` for the
    jitter ``j`` of its sample (:func:`pixel_jitter`), exactly as before the
    other kinds existed, so its numbers are unchanged.
    ``orthographic``: parallel rays from the direction ``w = (cos e cos a,
    cos e sin a, sin e)`` (view elevation ``e``, view azimuth ``a`` in the
    light's convention: the direction from the surface toward the camera),
    a film of ``film_size`` texels (default the tile's ``[cols, rows]``).
    ``perspective``: a pinhole at ``distance`` tile widths from the target
    along ``w``, horizontal field of view ``fov_deg``.

Placement (:class:`View`)
    Every kind looks at the tile's centre ``target = (cols / 2, rows / 2,
    z_mid)``, ``z_mid`` the middle of the relief; ``up`` is ``+z``, or for a
    view straight down (``e = 90``) ``-(cos a, sin a, 0)``, which for ``top``
    (``a = -90``) is ``+y``. An orthographic eye sits far enough along ``w``
    that the whole film is above the relief.

Pixel mapping (``metrics.json``'s ``camera`` record, :meth:`View.record`)
    Pixel ``(row, col)`` of a ``cols x rows`` image, row 0 at the top; a
    sample at jitter ``(j_u, j_v)`` in the pixel (0.5, 0.5 its centre) has
    ``u = 2 (col + j_u) / cols - 1``, ``v = 1 - 2 (row + j_v) / rows``. With
    ``f = normalize(target - eye)``, ``r = normalize(f x up)``, ``t = r x f``:
    perspective rays leave ``eye`` along ``normalize(f + u tan(fov/2) r + v
    tan(fov/2) (rows/cols) t)``; orthographic rays (``top`` too) leave ``eye +
    u (w/2) r + v (h/2) t`` along ``f``.

Samples within a pixel are stratified jitters (:func:`pixel_jitter`), one
PCG64 stream indexed by the sample's place in the whole image, so a band of
pixels gets bit for bit the rays of the whole image.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from hzval.core.backend import host_pool
from hzval.core.errors import InputError

__all__ = [
    "KINDS",
    "Camera",
    "view_axes",
    "View",
    "pixel_jitter",
    "stream",
    "sample_positions",
    "forget_sample_positions",
    "SAMPLE_CHUNK_PIXELS",
]

#: The camera kinds (module docstring).
KINDS: tuple[str, ...] = ("top", "orthographic", "perspective")


@dataclass(frozen=True)
class Camera:
    """What a scene's ``[camera]`` says (module docstring for each setting).

    ``supersampling`` is the ``top`` view's pixels per texel along each axis
    (each pixel covers ``1 / supersampling`` texels and is sampled at
    ``spp`` positions); the other kinds' default resolution is the ``top``
    view's, ``resolution`` ``(cols, rows)`` pixels otherwise. Image scores
    (FLIP above all, whose viewing distance is in pixels) depend on the
    pixel size, so compare them only at one setting.
    """

    kind: str = "top"
    supersampling: int = 1
    elevation_deg: float = 45.0
    azimuth_deg: float = -90.0
    fov_deg: float = 40.0
    distance: float = 1.5
    resolution: tuple[int, int] | None = None
    film_size: tuple[float, float] | None = None

    def validate(self, what: str) -> "Camera":
        """``self``, or an :class:`InputError` naming ``what`` (the scene file) and the bad setting."""
        if self.kind not in KINDS:
            raise InputError(what, f"camera.kind must be one of {', '.join(KINDS)}, got {self.kind!r}")
        for name in ("elevation_deg", "azimuth_deg", "fov_deg", "distance"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise InputError(what, f"camera.{name} must be a finite number, got {value!r}")
        if (
            isinstance(self.supersampling, bool)
            or int(self.supersampling) != self.supersampling
            or self.supersampling < 1
        ):
            raise InputError(
                what, f"camera.supersampling must be a positive integer, got {self.supersampling!r}"
            )
        if self.kind == "top":
            return self
        if not 0 < self.elevation_deg <= 90:
            raise InputError(what, f"camera.elevation_deg must be in (0, 90], got {self.elevation_deg}")
        if self.kind == "perspective":
            if not 0 < self.fov_deg < 170:
                raise InputError(what, f"camera.fov_deg must be in (0, 170), got {self.fov_deg}")
            if not self.distance > 0:
                raise InputError(what, f"camera.distance must be positive (tile widths), got {self.distance}")
        for name, value, kind in (("resolution", self.resolution, int), ("film_size", self.film_size, float)):
            if value is None:
                continue
            if (
                len(value) != 2
                or any(
                    isinstance(c, bool) or not isinstance(c, (int, float)) or not math.isfinite(c) or c <= 0
                    for c in value
                )
                or (kind is int and any(int(c) != c for c in value))
            ):
                raise InputError(
                    what,
                    f"camera.{name} must be two positive {'integers' if kind is int else 'numbers'} "
                    f"[width, height], got {value!r}",
                )
        return self

    def image_shape(self, rows: int, cols: int) -> tuple[int, int]:
        """``(H, W)`` pixels of a render of a ``rows x cols`` height map."""
        if self.kind == "top" or self.resolution is None:
            return rows * self.supersampling, cols * self.supersampling
        return int(self.resolution[1]), int(self.resolution[0])

    def toward_eye(self) -> tuple[float, float, float] | None:
        """Return the unit direction from the surface toward an orthographic camera (``top``: ``+z``).

        ``None`` for a perspective one, whose direction differs per pixel.
        """
        if self.kind == "top":
            return (0.0, 0.0, 1.0)
        if self.kind == "perspective":
            return None
        e, a = math.radians(self.elevation_deg), math.radians(self.azimuth_deg)
        return (math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e))

    def view(self, rows: int, cols: int, z_range: tuple[float, float] = (0.0, 0.0)) -> "View":
        """Where the camera is over a ``rows x cols`` tile whose heights span ``z_range`` texels."""
        H, W = self.image_shape(rows, cols)
        z_lo, z_hi = float(z_range[0]), float(z_range[1])
        if self.kind == "top":
            return View(
                "top",
                (cols / 2.0, rows / 2.0, 1.0e6),
                (cols / 2.0, rows / 2.0, 0.0),
                (0.0, 1.0, 0.0),
                None,
                (float(cols), float(rows)),
                (W, H),
                rows,
                cols,
                z_lo,
                z_hi,
                self.supersampling,
            )
        e = math.radians(self.elevation_deg)
        w, up = view_axes(self.elevation_deg, self.azimuth_deg)
        target = np.array([cols / 2.0, rows / 2.0, (z_lo + z_hi) / 2.0])
        if self.kind == "perspective":
            eye = target + self.distance * cols * w
            return View(
                "perspective",
                tuple(eye),
                tuple(target),
                up,
                float(self.fov_deg),
                None,
                (W, H),
                rows,
                cols,
                z_lo,
                z_hi,
                1,
            )
        film = (
            tuple(float(c) for c in self.film_size)
            if self.film_size is not None
            else (float(cols), float(rows))
        )
        # far enough along w that the film's lowest edge is above the relief, with room to spare
        reach = 0.5 * math.hypot(*film) + (z_hi - z_lo) + 1.0
        eye = target + (reach / max(math.sin(e), 1e-6) + reach) * w
        return View(
            "orthographic", tuple(eye), tuple(target), up, None, film, (W, H), rows, cols, z_lo, z_hi, 1
        )


def view_axes(elevation_deg: float, azimuth_deg: float) -> tuple[np.ndarray, tuple]:
    """Return ``(w, up)``, a camera's unit direction from the surface and its up vector.

    The camera is at ``elevation_deg`` and ``azimuth_deg`` (the light's convention), ``w = (cos e cos a, cos e
    sin a, sin e)``; the up vector is ``+z``, or for a view straight down ``-(cos a, sin a, 0)`` (module
    docstring).
    """
    e, a = math.radians(elevation_deg), math.radians(azimuth_deg)
    w = np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])
    up = (0.0, 0.0, 1.0) if elevation_deg < 90.0 - 1e-9 else (-math.cos(a), -math.sin(a), 0.0)
    return w, up


@dataclass(frozen=True)
class View:
    """A camera placed over one tile: its rays, their footprints, and its ``metrics.json`` record.

    ``eye``, ``target``, ``up``: texels; ``fov_deg`` (perspective) or
    ``film_size`` ``(w, h)`` texels (orthographic, top); ``resolution``
    ``(cols, rows)`` pixels; the tile's ``rows``, ``cols`` and heights
    ``z_lo..z_hi`` texels.
    """

    kind: str
    eye: tuple
    target: tuple
    up: tuple
    fov_deg: float | None
    film_size: tuple | None
    resolution: tuple
    rows: int
    cols: int
    z_lo: float
    z_hi: float
    supersampling: int = 1

    @property
    def shape(self) -> tuple[int, int]:
        """Return the image's ``(rows, cols)``."""
        return int(self.resolution[1]), int(self.resolution[0])

    def record(self) -> dict:
        """``metrics.json``'s ``camera``: ``{kind, eye, target, up, fov_deg, film_size, resolution}``."""
        return {
            "kind": self.kind,
            "eye": [float(c) for c in self.eye],
            "target": [float(c) for c in self.target],
            "up": [float(c) for c in self.up],
            "fov_deg": self.fov_deg,
            "film_size": None if self.film_size is None else [float(c) for c in self.film_size],
            "resolution": [int(c) for c in self.resolution],
        }

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(f, r, t)``: forward, right and the film's up, unit vectors (module docstring)."""
        f = np.asarray(self.target, float) - np.asarray(self.eye, float)
        f /= np.linalg.norm(f)
        r = np.cross(f, np.asarray(self.up, float))
        r /= np.linalg.norm(r)
        return f, r, np.cross(r, f)

    def rays_at(self, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return the rays' origins and unit directions at film coordinates ``u, v`` in [-1, 1].

        Both are ``(n, 3)`` float64.
        """
        f, r, t = self.basis()
        eye = np.asarray(self.eye, float)
        u, v = np.asarray(u, float)[:, None], np.asarray(v, float)[:, None]
        if self.kind == "perspective":
            W, H = self.resolution
            tan = math.tan(math.radians(self.fov_deg) / 2.0)
            d = f + u * tan * r + v * (tan * H / W) * t
            d /= np.linalg.norm(d, axis=1, keepdims=True)
            return np.broadcast_to(eye, d.shape).copy(), d
        w, h = self.film_size
        o = eye + u * (w / 2.0) * r + v * (h / 2.0) * t
        return o, np.broadcast_to(f, o.shape).copy()

    def film_coordinates(self, pixels: np.ndarray, ju: np.ndarray, jv: np.ndarray):
        """Return ``(u, v)`` of the samples at jitters ``ju, jv`` in the pixels ``pixels``.

        The jitters are ``(n, spp)``; ``pixels`` are flat indices.
        """
        W, H = self.resolution
        prow, pcol = np.divmod(np.asarray(pixels), W)
        u = 2.0 * (pcol[:, None] + ju) / W - 1.0
        v = 1.0 - 2.0 * (prow[:, None] + jv) / H
        return u.ravel(), v.ravel()

    def rays(self, spp: int, seed: int, first: int, stop: int) -> tuple[np.ndarray, np.ndarray]:
        """Return the camera rays of the samples of the pixels ``first <= p < stop``.

        They are origins and unit directions, float64 ``(n, 3)``, sample ``s`` of pixel ``p`` at row ``(p -
        first) * spp + s``.
        """
        ju, jv = pixel_jitter(self.shape, spp, seed, first, stop)
        return self.rays_at(*self.film_coordinates(np.arange(first, stop), ju, jv))

    def plane_points(self, o: np.ndarray, d: np.ndarray, z0: float) -> tuple[np.ndarray, np.ndarray]:
        """Return where the rays ``o + t d`` meet the plane ``z = z0``.

        The result is ``(xy (n, 2) float64, hit (n,) bool)``; a ray that does not descend (``d.z >= 0``)
        misses, and its point is the tile's centre.
        """
        dz = d[:, 2]
        hit = dz < -1e-12
        t = np.where(hit, (z0 - o[:, 2]) / np.where(hit, dz, -1.0), 0.0)
        xy = o[:, :2] + t[:, None] * d[:, :2]
        xy[~hit] = (self.cols / 2.0, self.rows / 2.0)
        return xy, hit

    def footprints(self, z0: float | None = None, points=None, period=None) -> np.ndarray:
        """Return per pixel how far the point seen on the plane ``z = z0`` moves to the next pixel.

        The result is ``(H * W, 4)`` float32 ``(dx/dcol, dy/dcol, dx/drow, dy/drow)`` in texels (the ray
        differentials of the pixel centres, differenced half a pixel either side), NaN where the pixel's
        centre ray misses the plane. ``points(o, d) -> (xy, hit)`` replaces the plane (a model's surface,
        :mod:`hzval.truth.model`); ``period`` ``(cols, rows)``: differences taken the short way across a
        wrapping tile.
        """
        points = points or (lambda o, d: self.plane_points(o, d, z0))
        W, H = self.resolution
        pixels = np.arange(H * W)
        half = np.full((H * W, 1), 0.5)
        out = np.empty((H * W, 4), np.float64)
        for k, (du, dv) in enumerate(((0.5, 0.0), (0.0, 0.5))):
            ends = []
            for sign in (1.0, -1.0):
                u, v = self.film_coordinates(pixels, half + sign * du, half + sign * dv)
                xy, hit = points(*self.rays_at(u, v))
                xy[~hit] = np.nan
                ends.append(xy)
            diff = ends[0] - ends[1]
            if period is not None:
                size = np.asarray(period, float)
                diff = (diff + size / 2) % size - size / 2
            out[:, 2 * k : 2 * k + 2] = diff
        return out.astype(np.float32)


def pixel_jitter(
    shape: tuple[int, int], spp: int, seed: int, a: int, b: int
) -> tuple[np.ndarray, np.ndarray]:
    """Return where in its pixel each sample of the pixels ``a <= p < b`` lies.

    The result is ``(ju, jv)``, ``(b - a, spp)`` float64 in [0, 1).

    One PCG64 stream, all ``u`` then all ``v`` of the whole image, one double
    each; a band starts its own copy at its offset (``PCG64.advance``), so
    bands are bit for bit the whole image's. ``spp = n * n`` gives one
    jittered sample per cell of an ``n x n`` grid over the pixel, other
    counts are uniform.
    """
    height, width = shape
    total = height * width * spp
    u = stream([seed, 0x5A3F], a * spp).random((b - a, spp))
    v = stream([seed, 0x5A3F], total + a * spp).random((b - a, spp))
    n = int(round(math.sqrt(spp)))
    if n * n == spp:
        # ((cell % n) + u) / n, in place (the same operations, half the memory traffic)
        cell = np.arange(spp)
        u += (cell % n)[None, :]
        u /= n
        v += (cell // n)[None, :]
        v /= n
    return u, v


def stream(entropy, offset: int) -> np.random.Generator:
    """Return ``np.random.default_rng(entropy)`` advanced by ``offset`` doubles.

    PCG64 draws one 64-bit word per double of ``random``.
    """
    bits = np.random.PCG64(np.random.SeedSequence(entropy))
    bits.advance(offset)
    return np.random.Generator(bits)


# --------------------------------------------------------------------------
# Where each pixel of the top view is sampled
# --------------------------------------------------------------------------


def sample_positions(
    rows: int, cols: int, camera: Camera, spp: int, seed: int, pixels: tuple[int, int] | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Return the tangent-space ``(x, y)`` of every sample of the ``top`` view.

    They are float32 arrays of shape ``(pixels * spp,)``.

    Sample ``s`` of pixel ``p = prow * width + pcol`` is at index ``p * spp + s``,
    at the jitter of :func:`hzval.scene.camera.pixel_jitter` in its pixel. Both
    renderers use these positions, so no error comes from sampling alone.
    Jittered points almost never land on a texel centre, where the mesh has
    a vertex and shadow rays self-intersect (docs/ARCHITECTURE.md, "Known pitfalls").
    Other views' samples are where their camera rays meet the surface (the
    truth) or the technique's plane (:mod:`hzval.scene.lookup`).

    ``pixels``: ``(first, stop)``, only the samples of the pixels ``first <= p < stop`` (a band
    of rows for a renderer that works in bands), bit for bit those of the whole image; bands and
    the whole image alike are made in chunks of :data:`SAMPLE_CHUNK_PIXELS` pixels on a thread
    per core, in bounded memory.
    """
    if camera.kind != "top":
        raise ValueError(
            f"sample_positions is the top view's; a {camera.kind} camera's samples come from its rays"
        )
    height, width = camera.image_shape(rows, cols)
    if pixels is None or tuple(pixels) == (0, height * width):
        return _all_positions(rows, cols, camera, spp, seed)
    return _positions(rows, cols, camera, spp, seed, int(pixels[0]), int(pixels[1]))


@functools.lru_cache(maxsize=1)
def _all_positions(rows: int, cols: int, camera: Camera, spp: int, seed: int):
    """Return the whole image's positions, made once for the truth and every technique of a sweep.

    They are read-only, since the truth and the techniques share them.
    """
    height, width = camera.image_shape(rows, cols)
    xs, ys = _positions(rows, cols, camera, spp, seed, 0, height * width)
    xs.flags.writeable = ys.flags.writeable = False
    return xs, ys


def forget_sample_positions() -> None:
    """Drop the whole image's shared positions (:func:`sample_positions`).

    A sweep's set-up is done with them once the truth and every technique hold what they need (2.1 GB at 4096
    x 4096).
    """
    _all_positions.cache_clear()


def _positions(rows: int, cols: int, camera: Camera, spp: int, seed: int, first: int, stop: int):
    """:func:`sample_positions` of the pixels ``first <= p < stop``."""
    height, width = camera.image_shape(rows, cols)
    if not 0 <= first <= stop <= height * width:
        raise ValueError(f"pixels {first}..{stop} outside the image's {height * width}")
    xs = np.empty((stop - first) * spp, np.float32)
    ys = np.empty_like(xs)
    bounds = list(range(first, stop, SAMPLE_CHUNK_PIXELS)) + [stop]

    def chunk(a: int, b: int) -> None:
        x, y = _jittered_chunk(rows, cols, camera, spp, seed, a, b)
        xs[(a - first) * spp : (b - first) * spp], ys[(a - first) * spp : (b - first) * spp] = x, y

    list(host_pool().map(chunk, bounds[:-1], bounds[1:]))
    return xs, ys


#: Pixels per chunk of :func:`sample_positions` (16 spp: 64 MB of float64 jitters in flight per thread).
SAMPLE_CHUNK_PIXELS = 1 << 18


def _jittered_chunk(rows: int, cols: int, camera: Camera, spp: int, seed: int, a: int, b: int):
    """:func:`sample_positions` of the pixels ``a <= p < b``."""
    ss = camera.supersampling
    height, width = camera.image_shape(rows, cols)
    u, v = pixel_jitter((height, width), spp, seed, a, b)
    prow, pcol = np.divmod(np.arange(a, b), width)
    # pixel (prow, pcol) covers x in [pcol, pcol + 1) / ss, and y downward from the top:
    # x = (pcol + u) / ss and y = rows - (prow + v) / ss, in place in float64, then rounded once
    u += pcol[:, None]
    u /= ss
    v += prow[:, None]
    v /= ss
    np.subtract(rows, v, out=v)
    return u.astype(np.float32).ravel(), v.astype(np.float32).ravel()
