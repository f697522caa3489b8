"""Where a technique reads its textures, and how: the flat surface seen through the camera.

A real-time renderer draws the flat base mesh; each pixel's ray meets it at
one point, whose ``uv`` the shader reads its textures at, filtered as a GPU
filters them. The ``[lookup]`` settings (:class:`Lookup`) are the same for
every technique of a sweep, so that they all read the same view:

``plane``
    The base plane's height: ``bottom``, ``mean`` or ``top`` of the relief
    (texels). It matters only off the ``top`` view, where a ray meets the
    plane at another ``(x, y)`` than the surface: that offset is the
    *parallax error* the report measures.
``parallax``
    ``none``; ``offset``: offset mapping with offset limiting (Welsh 2004:
    ``p = p0 + d_xy (z0 - h(p0))``, the ray's run below the plane without its
    ``1 / -d_z``, which keeps grazing views bounded); ``occlusion``: parallax
    occlusion mapping's linear search of ``parallax_steps`` steps down the
    ray through the relief's height range, refined by the secant between
    the last two steps (Tatarchuk 2006; Brawley and Tatarchuk 2004). Heights
    are read bilinearly from level 0.
``filter``
    ``nearest`` and ``bilinear`` read level 0 (``bilinear`` is what every
    ``top`` number has always used); ``trilinear`` reads a mip chain at the
    level of detail of the pixel's footprint, OpenGL 4.6 section 8.14:
    ``lambda = log2(rho)``, ``rho = max(|dP/dcol|, |dP/drow|)`` in texels, the
    derivatives of the point seen on the plane (:meth:`hzval.scene.camera.View.footprints`,
    ray differentials), blended between ``floor(lambda)`` and the next level;
    ``anisotropic`` takes ``N = min(ceil(P_max / P_min), max_anisotropy)``
    trilinear taps along the footprint's major axis at ``lambda = log2(P_max
    / N)`` (EXT_texture_filter_anisotropic). The footprint is the pixel's,
    shared by its samples, as a GPU's derivatives are per 2x2 quad of pixels.
``mips``
    How each level is made from the one below: ``average`` of 2x2 texels
    (what engines do), or for the horizon map ``max`` (a conservative chain:
    a coarse texel's horizon is its highest); normals, albedo and ambient
    are always averaged (the shader renormalises normals). An odd size
    drops its last row or column.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from hzval.core import conventions as cv
from hzval.core.backend import dr, mi  # Dr.Jit loads at first use, once the LLVM is chosen
from hzval.core.errors import InputError
from hzval.scene.camera import sample_positions

__all__ = [
    "PLANES",
    "FILTERS",
    "MIPS",
    "PARALLAX",
    "Lookup",
    "plane_height",
    "Samples",
    "FRAME_FLOATS",
    "frame_of",
    "to_tangent",
    "forget",
    "samples_for",
    "from_points",
    "mip_chain",
    "Filtered",
    "interleaved",
    "aligned_empty",
    "aligned",
]

PLANES: tuple[str, ...] = ("bottom", "mean", "top")
FILTERS: tuple[str, ...] = ("nearest", "bilinear", "trilinear", "anisotropic")
MIPS: tuple[str, ...] = ("average", "max")
PARALLAX: tuple[str, ...] = ("none", "offset", "occlusion")


@dataclass(frozen=True)
class Lookup:
    """The ``[lookup]`` settings (module docstring)."""

    plane: str = "mean"
    filter: str = "bilinear"
    mips: str = "average"
    max_anisotropy: int = 8
    parallax: str = "none"
    parallax_steps: int = 32

    def validate(self, what: str) -> "Lookup":
        """Return this lookup if each setting is one it allows, else raise one line naming ``what``."""
        for name, allowed in (("plane", PLANES), ("filter", FILTERS), ("mips", MIPS), ("parallax", PARALLAX)):
            if getattr(self, name) not in allowed:
                raise InputError(
                    what, f"lookup.{name} must be one of {', '.join(allowed)}, got {getattr(self, name)!r}"
                )
        for name in ("max_anisotropy", "parallax_steps"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise InputError(what, f"lookup.{name} must be a positive integer, got {value!r}")
        return self

    @property
    def mipmapped(self) -> bool:
        """Return whether the filter reads a mip chain."""
        return self.filter in ("trilinear", "anisotropic")


def plane_height(lookup: Lookup, z_lo: float, z_hi: float, z_mean: float) -> float:
    """Return the base plane's height in texels."""
    return {"bottom": z_lo, "mean": z_mean, "top": z_hi}[lookup.plane]


@dataclass
class Samples:
    """Where each sample of a sweep's image reads its textures.

    ``x``, ``y``: tangent-space texels, float32 ``(pixels * spp,)``, pixel-major
    (``wrap``: inside the tile); ``footprint``: per pixel ``(dx/dcol, dy/dcol,
    dx/drow, dy/drow)`` texels, float32 ``(pixels, 4)``, or ``None`` where no
    filter needs it; ``plane_z``: the base plane's height, texels (:func:`plane_height`);
    ``source``: ``"camera"`` or ``"truth"`` (the truth's own hit points: perfect parallax).

    On a model (:mod:`hzval.truth.model`) each sample also has its own tangent frame: ``frames``,
    float32 ``(pixels * spp, 12)``, the world's unit tangent ``t`` (along +u), bitangent ``b`` (along
    +v), normal ``n`` of the base mesh at the sample, then ``v`` toward the camera
    (:mod:`hzval.geometry.tangents`), so that a technique carries the world's light into the sample's tangent
    space, ``L_t = (t.L, b.L, n.L)``; ``macro(L)``: the base mesh's own visibility of the world
    direction ``L`` per sample (``mi.Float``, 0 or 1), the engine's shadow map, which every
    technique's factor is multiplied by. Both ``None`` on the plane, whose frame is the world's.
    """

    x: np.ndarray
    y: np.ndarray
    rows: int
    cols: int
    spp: int
    footprint: np.ndarray | None = None
    plane_z: float = 0.0
    source: str = "camera"
    frames: np.ndarray | None = None
    macro: object = None
    _uv: object = dataclasses.field(default=None, repr=False)
    _frames: object = dataclasses.field(default=None, repr=False)

    def uv(self):
        """Return the positions as texture coordinates interleaved ``u0, v0, u1, ...`` in one ``mi.Float``.

        The ``mi.Float`` is aligned (:func:`interleaved`), made once and shared by every technique.
        """
        if self._uv is None:
            rows, cols = self.rows, self.cols
            self._uv = interleaved(self.x, self.y, lambda a, b: cv.tangent_to_uv(a, b, rows, cols))
        return self._uv

    def frame_array(self):
        """Return :attr:`frames` as one aligned flat ``mi.Float`` (12 floats a sample).

        It is made once and shared by every technique; ``None`` on the plane.
        """
        if self.frames is None:
            return None
        if self._frames is None:
            # only on the Dr.Jit path: NumPy callers never load Dr.Jit
            import mitsuba as mi

            self._frames = mi.Float(aligned(np.ascontiguousarray(self.frames, np.float32).ravel()))
        return self._frames


#: Floats a sample's frame takes in :attr:`Samples.frames`: ``t``, ``b``, ``n``, ``v``.
FRAME_FLOATS = 12


def frame_of(frames, index):
    """``(t, b, n, v)`` of the samples ``index`` (``mi.UInt32``) from :meth:`Samples.frame_array`."""
    # a Vector3f gather reads floats 3 i .. 3 i + 2: a sample's four vectors are i = 4 index + k
    return tuple(dr.gather(mi.Vector3f, frames, index * (FRAME_FLOATS // 3) + k) for k in range(4))


def to_tangent(frame, d):
    """Return the world direction ``d`` in a sample's tangent space: ``(t.d, b.d, n.d)``.

    The frame ``(t, b, n)`` is :func:`hzval.geometry.tangents.orthonormal`'s (FGED2's TBN product).
    """
    t, b, n = frame[:3]
    return mi.Vector3f(dr.dot(t, d), dr.dot(b, d), dr.dot(n, d))


_CACHE: dict = {}


def forget() -> None:
    """Drop the shared :class:`Samples` of :func:`samples_for` (the techniques keep what they use)."""
    _CACHE.clear()


def samples_for(scene, rows: int, cols: int, height: np.ndarray | None = None) -> Samples:
    """Return the scene's :class:`Samples`, made once for every technique of a sweep.

    ``top`` without a mip filter needs no height map (``height`` may be
    ``None``): its samples are :func:`hzval.scene.camera.sample_positions`. Other
    views meet the base plane (:func:`plane_height`), take the parallax
    mapping the lookup asks for, and wrap into the tile.
    """
    cam, lk = scene.camera, scene.lookup
    mat = scene.material
    key = (
        rows,
        cols,
        cam,
        lk,
        scene.spp,
        scene.seed,
        mat.depth,
        mat.boundary,
        # the top view's samples and footprints do not depend on the heights
        None if height is None or cam.kind == "top" else hash(np.asarray(height, np.float32).tobytes()),
    )
    if key in _CACHE:
        return _CACHE[key]
    _CACHE.clear()
    if cam.kind != "top" and height is None:
        raise InputError(
            "camera", f"a {cam.kind} view needs the height map to place the techniques' base plane"
        )
    h = None if height is None else cv.heights_in_texels(height, mat.depth)
    z = (0.0, 0.0, 0.0) if h is None else (float(h.min()), float(h.max()), float(h.mean()))
    view = cam.view(rows, cols, z[:2])
    z0 = plane_height(lk, *z)
    if cam.kind == "top":
        x, y = sample_positions(rows, cols, cam, scene.spp, scene.seed)
    else:
        x, y = _view_positions(scene, h, view, z0)
    footprint = view.footprints(z0) if lk.mipmapped else None
    out = Samples(x, y, rows, cols, int(scene.spp), footprint, z0)
    _CACHE[key] = out
    return out


def from_points(x: np.ndarray, y: np.ndarray, like: Samples, source: str = "truth") -> Samples:
    """:class:`Samples` at given points (the truth's hits), with ``like``'s footprints."""
    return Samples(
        np.asarray(x, np.float32),
        np.asarray(y, np.float32),
        like.rows,
        like.cols,
        like.spp,
        like.footprint,
        like.plane_z,
        source,
    )


#: Pixels per chunk of the plane and parallax computations.
_CHUNK_PIXELS = 1 << 16


def _view_positions(scene, h: np.ndarray, view, z0: float) -> tuple[np.ndarray, np.ndarray]:
    """Return where the camera's rays (``view``) meet the base plane ``z = z0``, in float32 texels.

    The positions include the parallax mapping.
    """
    lk = scene.lookup
    rows, cols = h.shape
    z_lo, z_hi = view.z_lo, view.z_hi
    H, W = view.shape
    spp = int(scene.spp)
    xs = np.empty(H * W * spp, np.float32)
    ys = np.empty_like(xs)
    height_tex = height_texture(h, scene.material.boundary) if lk.parallax != "none" else None
    for a in range(0, H * W, _CHUNK_PIXELS):
        b = min(H * W, a + _CHUNK_PIXELS)
        o, d = view.rays(spp, scene.seed, a, b)
        xy, _ = view.plane_points(o, d, z0)
        if height_tex is not None:
            xy = parallax_lookup(lk, height_tex, xy, d, z0, z_lo, z_hi)
        if scene.material.boundary == "wrap":
            xy[:, 0] %= cols
            xy[:, 1] %= rows
        xs[a * spp : b * spp], ys[a * spp : b * spp] = xy[:, 0], xy[:, 1]
    return xs, ys


def height_texture(h: np.ndarray, boundary: str):

    wrap = dr.WrapMode.Repeat if boundary == "wrap" else dr.WrapMode.Clamp
    return mi.Texture2f(
        mi.TensorXf(np.ascontiguousarray(h[..., None], np.float32)),
        use_accel=False,
        migrate=False,
        filter_mode=dr.FilterMode.Linear,
        wrap_mode=wrap,
    )


def parallax_lookup(
    lk: Lookup, tex, xy: np.ndarray, d: np.ndarray, z0: float, z_lo: float, z_hi: float
) -> np.ndarray:
    """Return the plane points ``xy`` moved by the parallax mapping ``lk.parallax`` along the rays ``d``.

    The ray through ``p0 = xy`` at the plane is at ``p(z) = p0 + d_xy (z0 - z) / -d_z`` at
    height ``z``. ``offset``: ``p0 + d_xy (z0 - h(p0))`` (offset limiting); ``occlusion``: the
    first of ``z_i = z_hi - i (z_hi - z_lo) / N`` where the ray is below the surface, refined
    by the secant through the last two steps' heights above it.
    """
    rows, cols = tex.shape[0], tex.shape[1]
    px, py = mi.Float(xy[:, 0].astype(np.float32)), mi.Float(xy[:, 1].astype(np.float32))
    dx, dy = mi.Float(d[:, 0].astype(np.float32)), mi.Float(d[:, 1].astype(np.float32))
    run = 1.0 / dr.maximum(-mi.Float(d[:, 2].astype(np.float32)), 1e-6)  # texels across per texel down

    def height(x, y):
        return tex.eval(mi.Point2f(x / cols, (rows - y) / rows))[0]

    if lk.parallax == "offset":
        dz = z0 - height(px, py)
        qx, qy = px + dx * dz, py + dy * dz
    else:
        n = lk.parallax_steps
        step = (z_hi - z_lo) / n
        found = mi.Bool(False)
        z_prev, a_prev = mi.Float(z_hi), mi.Float(0.0)
        qz = mi.Float(z_hi)
        for i in range(n + 1):
            z = mi.Float(z_hi - i * step)
            t = (z0 - z) * run
            a = z - height(px + dx * t, py + dy * t)  # the ray's height above the surface
            now = ~found & (a <= 0.0)
            s = dr.select(a_prev - a > 0.0, a_prev / (a_prev - a), 0.0) if i else mi.Float(0.0)
            qz = dr.select(now, z_prev + s * (z - z_prev), qz)
            found |= now
            z_prev, a_prev = z, a
        t = (z0 - qz) * run
        qx, qy = px + dx * t, py + dy * t
    dr.eval(qx, qy)
    return np.stack([np.asarray(qx, np.float64), np.asarray(qy, np.float64)], axis=-1)


# --------------------------------------------------------------------------
# Filtering: textures read as a GPU reads them
# --------------------------------------------------------------------------


def mip_chain(
    data: np.ndarray, max_channels: slice | None = None, *, stored: slice | None = None, quantise=None
) -> list[np.ndarray]:
    """Levels 0..

    of ``data`` ``(rows, cols, C)`` float32 down to 1x1: each the 2x2 average of the one below
    (``max_channels``: those channels by the 2x2 maximum); an odd size drops its last row or column.

    ``quantise`` (with ``stored``, the channels it applies to): what the texture's storage makes
    of a level, e.g. :meth:`hzval.io.storage.Storage.roundtrip`. A GPU's chain of an RGBA8 texture
    is RGBA8 (``glGenerateMipmap`` filters the stored level below and stores the result in the
    texture's format), so each level is quantised before the next is made from it; a float chain
    of an 8-bit map is 0.016-0.027 in F from the GPU's at lambda 1-2 (docs/gpu-pipeline.md).
    """

    def halve(a: np.ndarray, axis: int) -> tuple[np.ndarray, np.ndarray]:
        m = a.shape[axis] // 2
        if m == 0:
            return a, a
        return np.take(a, np.arange(0, 2 * m, 2), axis), np.take(a, np.arange(1, 2 * m, 2), axis)

    levels = [np.asarray(data, np.float32)]
    while levels[-1].shape[0] > 1 or levels[-1].shape[1] > 1:
        a = levels[-1].astype(np.float64)
        top, bottom = halve(a, 0)
        quads = [q for half in (top, bottom) for q in halve(half, 1)]
        out = sum(quads) / 4.0
        if max_channels is not None:
            out[..., max_channels] = np.maximum.reduce([q[..., max_channels] for q in quads])
        out = out.astype(np.float32)
        if quantise is not None:
            out[..., stored] = quantise(out[..., stored])
        levels.append(out)
    return levels


class Filtered:
    """A ``(rows, cols, C)`` texture read at ``uv`` as the lookup's filter reads it (module docstring).

    ``wrap``: ``"wrap"`` repeats, ``"open"`` clamps to the edge. ``quantise``: applied to the
    ``max_channels`` of every mip level (:func:`mip_chain`). ``samples``: the
    :class:`Samples` whose footprints set the level of detail of a mip filter.
    :meth:`eval` takes the lanes' texture coordinates and their pixel indices.
    """

    def __init__(
        self,
        data: np.ndarray,
        boundary: str,
        lookup: Lookup,
        samples: Samples | None = None,
        *,
        max_channels: slice | None = None,
        aligned=None,
        quantise=None,
    ):

        self.lookup = lookup
        wrap = dr.WrapMode.Repeat if boundary == "wrap" else dr.WrapMode.Clamp
        prep = aligned if aligned is not None else (lambda a: np.ascontiguousarray(a, np.float32))
        mode = dr.FilterMode.Nearest if lookup.filter == "nearest" else dr.FilterMode.Linear
        chain = (
            mip_chain(
                data, max_channels if lookup.mips == "max" else None, stored=max_channels, quantise=quantise
            )
            if lookup.mipmapped
            else [data]
        )
        self.levels = [
            mi.Texture2f(
                mi.TensorXf(prep(a)), use_accel=False, migrate=False, filter_mode=mode, wrap_mode=wrap
            )
            for a in chain
        ]
        self.rows, self.cols = data.shape[0], data.shape[1]
        self._footprint = None
        if lookup.mipmapped:
            if samples is None or samples.footprint is None:
                raise ValueError("a mip filter needs the samples' footprints")
            self._set_footprint(samples.footprint)

    def _set_footprint(self, fp: np.ndarray) -> None:
        """Upload the per-pixel footprints on the device, and the range of levels and taps they need."""
        fp = np.nan_to_num(np.asarray(fp, np.float64), nan=1.0)
        lc, lr = np.hypot(fp[:, 0], fp[:, 1]), np.hypot(fp[:, 2], fp[:, 3])
        taps = 1
        if self.lookup.filter == "anisotropic":
            big, small = np.maximum(lc, lr), np.maximum(np.minimum(lc, lr), 1e-12)
            n = np.minimum(np.ceil(big / small), self.lookup.max_anisotropy)
            lam = np.log2(np.maximum(big / n, 1e-12))
            taps = int(n.max())
        else:
            lam = np.log2(np.maximum(np.maximum(lc, lr), 1e-12))
        top = len(self.levels) - 1
        lam = np.clip(lam, 0.0, top)
        self.level_range = (int(np.floor(lam.min())), min(top, int(np.ceil(lam.max()))))
        self.taps = taps
        self._footprint = mi.Float(np.ascontiguousarray(fp.astype(np.float32)).ravel())

    def eval(self, uv, pixel=None) -> list:
        """Return the filtered channels at ``uv`` (``mi.Point2f``) for lanes of the pixels ``pixel``."""
        if self._footprint is None or pixel is None:
            return self.levels[0].eval(uv)

        fp = dr.gather(mi.Vector4f, self._footprint, pixel)
        lc, lr = dr.norm(mi.Vector2f(fp.x, fp.y)), dr.norm(mi.Vector2f(fp.z, fp.w))
        top = float(len(self.levels) - 1)
        if self.lookup.filter == "anisotropic":
            col_major = lc >= lr
            big, small = dr.maximum(lc, lr), dr.maximum(dr.minimum(lc, lr), 1e-12)
            n = dr.minimum(dr.ceil(big / small), float(self.lookup.max_anisotropy))
            lam = dr.clip(dr.log2(dr.maximum(big / n, 1e-12)), 0.0, top)
            # the major axis in uv: texels to u = x / cols, v = (rows - y) / rows
            ax = dr.select(col_major, fp.x, fp.z) / self.cols
            ay = -dr.select(col_major, fp.y, fp.w) / self.rows
            total = None
            for i in range(self.taps):
                on = mi.Float(i) < n
                off = (mi.Float(i) + 0.5) / n - 0.5
                vals = self._trilinear(mi.Point2f(dr.fma(ax, off, uv.x), dr.fma(ay, off, uv.y)), lam, on)
                vals = [dr.select(on, v, 0.0) for v in vals]
                total = vals if total is None else [t + v for t, v in zip(total, vals)]
            return [t / n for t in total]
        lam = dr.clip(dr.log2(dr.maximum(dr.maximum(lc, lr), 1e-12)), 0.0, top)
        return self._trilinear(uv, lam, mi.Bool(True))

    def _trilinear(self, uv, lam, active) -> list:
        """Return the levels either side of ``lam`` blended linearly.

        The blend is a tent of weights over the levels the image's footprints reach.
        """
        total = None
        lo, hi = self.level_range
        for level in range(lo, hi + 1):
            w = dr.maximum(1.0 - dr.abs(lam - level), 0.0) if hi > lo else 1.0
            vals = self.levels[level].eval(uv, active & (w > 0.0)) if hi > lo else self.levels[level].eval(uv)
            vals = [v * w for v in vals] if hi > lo else list(vals)
            total = vals if total is None else [t + v for t, v in zip(total, vals)]
        return total


# --------------------------------------------------------------------------
# Sample positions and textures in Dr.Jit's memory
# --------------------------------------------------------------------------

#: Samples per chunk of :func:`interleaved`.
_CHUNK = 1 << 22


def interleaved(x: np.ndarray, y: np.ndarray, convert=None):
    """Return a float32 ``mi.Float`` of ``convert(x, y)`` interleaved pair by pair.

    ``convert`` defaults to ``(x, y)``. The array is made in Dr.Jit kernels on every core, :data:`_CHUNK`
    samples at a time so that no full-size temporary is made (the output alone: 2.1 GB at 4096 x 4096 x 16).
    ``convert`` takes and returns ``mi.Float`` arrays (e.g. :func:`hzval.core.conventions.tangent_to_uv`).
    Each value is a gather from a copy of its chunk (a contiguous load from mapped NumPy memory would compile
    one kernel per alignment); the result is Dr.Jit's own, aligned, memory.
    """
    n = int(np.size(x))
    out = dr.empty(mi.Float, 2 * n)
    for a in range(0, n, _CHUNK):
        b = min(n, a + _CHUNK)
        j = dr.arange(mi.UInt32, 2 * (b - a))
        i = j >> 1
        first = dr.gather(mi.Float, mi.Float(np.ascontiguousarray(x[a:b], np.float32)), i)
        second = dr.gather(mi.Float, mi.Float(np.ascontiguousarray(y[a:b], np.float32)), i)
        if convert is not None:
            first, second = convert(first, second)
        # the chunk's offset is opaque: one kernel for every chunk
        dr.scatter(out, dr.select((j & 1) == 1, second, first), j + dr.opaque(mi.UInt32, 2 * a))
        dr.eval(out)
    return out


def aligned_empty(size: int, alignment: int = 64) -> np.ndarray:
    """Return an uninitialised float32 array of ``size`` that starts on an ``alignment``-byte boundary."""
    buf = np.empty(size + alignment // 4, dtype=np.float32)
    start = (-buf.ctypes.data % alignment) // 4
    return buf[start : start + size]


def aligned(a, alignment: int = 64) -> np.ndarray:
    """Return a C-contiguous float32 copy of ``a`` that starts on an ``alignment``-byte boundary.

    On the LLVM backend Dr.Jit maps NumPy memory without copying it, and it
    reads a texel's channels as one packet (vector loads) only from aligned
    memory; from NumPy's 16-byte-aligned buffers it fell back to one scalar
    gather per channel and lane: 2-4x slower frames, varying from run to run
    with where NumPy's allocation happened to land. (CUDA copies anyway.)
    """
    a = np.asarray(a, dtype=np.float32)
    out = aligned_empty(a.size, alignment).reshape(a.shape)
    out[...] = a
    return out
