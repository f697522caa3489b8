"""The baker: height map -> normal map, horizon map, ambient map, weight cube map.

The horizon bake is the seed algorithm of Lengyel (GPU Zen 2, section 5.2;
FGED2 ch. 7 ``ConstructHorizonMap``), reproduced texel for texel up to float
rounding:

* every neighbour with ``0 < i^2 + j^2 < R^2`` that is higher than the centre
  raises the maximum ``tan^2 = dh^2 / r^2`` of each of the ``angles`` bins
  that its angular extent ``atan(0.7071 / r)`` covers around its direction
  ``atan2(j, i)``;
* ``sin = sqrt(t / (t + 1))`` per bin, and channel ``k`` averages the
  ``angles / 8 + 1`` bins centred on azimuth ``45 k`` degrees.

Heights are in texel units (``H * depth * cols``), and ``(i, j)`` are
tangent-space offsets (+y up the image), so the bins follow hzval's azimuth
convention rather than the seed's memory layout. The offset-to-bins table is
the same for every texel and is computed once (:func:`horizon_table`). The
seed's ``& (width - 1)`` wrap is replaced by a padded copy of the map, so any
size works, and ``open`` pads with ``-inf``, which never occludes.

The bake runs as one Dr.Jit kernel. On the LLVM (CPU) backend each lane is a
texel of a padded row and each neighbour is a zero-copy, shifted view of the
padded map, so the kernel reads memory with contiguous vector loads instead
of gathers (on AVX2 this was 6x faster); on CUDA, gathers are cheap and the
same lanes gather from one copy of the map.

The ambient map holds two averages over the bins' horizon angles ``alpha``:
``mean_cos``, Lengyel's term (the seed's ``sum * kAngleCount`` means an
average), and ``mean_cos2``, the exact cosine-weighted unoccluded fraction of
the hemisphere for a horizon at ``alpha`` in every direction.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from hzval import conventions as cv
from hzval.errors import InputError

#: Angular half-width factor of a texel seen from distance r: atan(0.7071 / r),
#: the seed's constant for a texel's half diagonal (sqrt(2)/2, rounded).
TEXEL_HALF_EXTENT = np.float32(0.7071)
#: The seed's ``two_pi`` as a float32 constant.
_TWO_PI_F32 = np.float32(6.2831855)

#: Bytes of memory per texel that a bake needs at its peak (inputs, padded
#: copy, ten kernel outputs, their NumPy copies, normal map, 8-bit encodings),
#: measured with tracemalloc and rounded up.
BAKE_BYTES_PER_TEXEL = 160


@dataclass(frozen=True)
class BakeParams:
    """Parameters of a bake (``hzval bake``'s options).

    ``depth``: world height of ``H = 1`` in units of the image width.
    ``radius``: search radius in texels; neighbours with ``r < radius`` count.
    ``angles``: number of angular bins; a multiple of 16 (each channel
    averages ``angles/8 + 1`` bins centred on its direction).
    ``boundary``: ``wrap`` or ``open`` (:mod:`hzval.conventions`).
    """

    depth: float = 0.05
    radius: int = 16
    angles: int = 32
    boundary: str = "wrap"
    method: str = "seed"

    def validate(self) -> "BakeParams":
        if not np.isfinite(self.depth) or self.depth <= 0:
            raise InputError("--depth", f"must be a positive number of image widths, got {self.depth}")
        if int(self.radius) != self.radius or self.radius < 2:
            raise InputError("--radius", f"must be an integer of at least 2 texels, got {self.radius}")
        if int(self.angles) != self.angles or self.angles < 16 or self.angles % 16:
            raise InputError("--angles", f"must be a multiple of 16 (16, 32, 48, 64, ...), got {self.angles}")
        if self.boundary not in cv.BOUNDARIES:
            raise InputError("--boundary", f"must be one of {', '.join(cv.BOUNDARIES)}, got {self.boundary!r}")
        if self.method != "seed":
            raise InputError("--method", f"unknown bake method {self.method!r}; available: seed")
        return self


@dataclass
class Bake:
    """The textures of the technique, as float32 arrays indexed ``[row, col]``.

    ``horizon``: ``(rows, cols, 8)`` sines of the horizon angle, channel ``k``
    toward azimuth ``45 k`` degrees. ``normal``: ``(rows, cols, 3)`` unit
    tangent-space normals. ``mean_cos``, ``mean_cos2``: ``(rows, cols)``
    ambient terms. ``timings``: seconds per stage.
    """

    params: BakeParams
    horizon: np.ndarray
    normal: np.ndarray
    mean_cos: np.ndarray
    mean_cos2: np.ndarray
    timings: dict[str, float] = field(default_factory=dict)

    @property
    def layers(self) -> tuple[np.ndarray, np.ndarray]:
        """The two RGBA layers: channels 0-3 and 4-7."""
        n = cv.CHANNELS_PER_LAYER
        return self.horizon[..., :n], self.horizon[..., n:]


# --------------------------------------------------------------------------
# Normal map
# --------------------------------------------------------------------------

def normal_map(h_texels: np.ndarray, boundary: str) -> np.ndarray:
    """Unit tangent-space normals ``normalize(-dh/dx, -dh/dy, 1)``, ``(rows, cols, 3)``.

    Central differences of heights in texel units (FGED2 ch. 7, with its
    listing's use-before-definition fixed, DESIGN.md).
    """
    gx, gy = cv.height_gradient(h_texels, boundary)
    n = np.stack([-gx, -gy, np.ones_like(gx)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return n.astype(np.float32)


# --------------------------------------------------------------------------
# Horizon map
# --------------------------------------------------------------------------

@dataclass(frozen=True)
class OffsetGroup:
    """Neighbour offsets that update the same set of bins.

    ``offsets``: tangent-space ``(i, j)`` in texels; ``inv_r``: ``1 / r`` of
    each; ``bins``: the bin indices (mod ``angles``) they all update.
    """

    bins: tuple[int, ...]
    offsets: tuple[tuple[int, int], ...]
    inv_r: tuple[float, ...]


def horizon_table(radius: int, angles: int) -> list[OffsetGroup]:
    """The seed's offset-to-bins table, grouped by the bins each offset covers.

    Computed in float32 exactly as the seed's C code does (``atan2f``,
    ``atanf``, ``floorf``/``ceilf`` of ``(direction -+ delta) * angles / 2pi``),
    so that every offset lands in the seed's bins.
    """
    k_index = np.float32(angles) / _TWO_PI_F32
    groups: dict[tuple[int, ...], list[tuple[int, int, float]]] = {}
    for j in range(-radius + 1, radius):
        for i in range(-radius + 1, radius):
            r2 = i * i + j * j
            if r2 == 0 or r2 >= radius * radius:
                continue
            direction = np.arctan2(np.float32(j), np.float32(i))
            delta = np.arctan(TEXEL_HALF_EXTENT / np.sqrt(np.float32(r2)))
            lo = int(np.floor((direction - delta) * k_index))
            hi = int(np.ceil((direction + delta) * k_index))
            bins = tuple(sorted({n % angles for n in range(lo, hi + 1)}))
            groups.setdefault(bins, []).append((i, j, 1.0 / np.sqrt(r2)))
    return [OffsetGroup(bins, tuple((i, j) for i, j, _ in v), tuple(r for _, _, r in v))
            for bins, v in groups.items()]


def horizon_map(h_texels: np.ndarray, radius: int = 16, angles: int = 32,
                boundary: str = "wrap") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Seed horizon bake of heights in texel units.

    Returns ``(horizon, mean_cos, mean_cos2)``: the ``(rows, cols, 8)`` channel
    sines and the two ``(rows, cols)`` ambient terms, float32. Runs on the
    current Mitsuba variant's Dr.Jit backend (:func:`hzval.backend.variant`).
    """
    import drjit as dr
    import mitsuba as mi

    h = np.asarray(h_texels, dtype=np.float32)
    rows, cols = h.shape
    pad = radius - 1
    padded = cv.pad_heights(h, pad, boundary).astype(np.float32)
    pcols = padded.shape[1]
    # One padded row is a lane row: lanes in the pad columns compute values
    # that are discarded. The flat buffer has `pad` extra floats at both
    # ends so that the shifted views of those lanes stay inside it.
    flat = np.concatenate([np.zeros(pad, np.float32), padded.ravel(), np.zeros(pad, np.float32)])
    start = pad + pad * pcols  # flat index of padded (row pad, col 0)
    lanes = rows * pcols

    if dr.backend_v(mi.Float) == dr.JitBackend.LLVM:
        def neighbour(shift: int):
            # zero-copy view: the kernel reads it with contiguous loads
            return mi.Float(flat[start + shift:start + shift + lanes])
    else:
        source = mi.Float(flat)
        lane = dr.arange(mi.Int32, lanes) + start

        def neighbour(shift: int):
            return dr.gather(mi.Float, source, mi.UInt32(lane + shift))

    def shift_of(i: int, j: int) -> int:
        drow, dcol = cv.tangent_to_pixel_offset(i, j)
        return drow * pcols + dcol

    h0 = neighbour(0)
    max_tan = [mi.Float(0.0) for _ in range(angles)]
    for group in horizon_table(radius, angles):
        # max over the group of tan = dh / r; clamped at 0 by the bins' start
        # value, which is the seed's "dh > 0" test
        g = None
        for (i, j), inv_r in zip(group.offsets, group.inv_r):
            t = (neighbour(shift_of(i, j)) - h0) * inv_r
            g = t if g is None else dr.maximum(g, t)
        for b in group.bins:
            max_tan[b] = dr.maximum(max_tan[b], g)

    cos2 = [dr.rcp(dr.fma(t, t, 1.0)) for t in max_tan]     # 1 / (1 + tan^2)
    sines = [t * dr.sqrt(c) for t, c in zip(max_tan, cos2)]  # sqrt(t^2 / (t^2 + 1))
    half = angles // 16
    channels = []
    for k in range(cv.CHANNEL_COUNT):
        centre = k * angles // cv.CHANNEL_COUNT
        s = sines[(centre - half) % angles]
        for d in range(-half + 1, half + 1):
            s = s + sines[(centre + d) % angles]
        channels.append(s * (1.0 / (2 * half + 1)))
    mean_cos = sum(dr.sqrt(c) for c in cos2) * (1.0 / angles)
    mean_cos2 = sum(cos2) * (1.0 / angles)
    outputs = channels + [mean_cos, mean_cos2]
    dr.eval(*outputs)

    def image(v) -> np.ndarray:
        return np.asarray(v, dtype=np.float32).reshape(rows, pcols)[:, pad:pad + cols]

    horizon = np.stack([image(c) for c in channels], axis=-1)
    result = horizon, image(mean_cos).copy(), image(mean_cos2).copy()
    del flat  # the views above must not outlive it; they are evaluated by now
    return result


# --------------------------------------------------------------------------
# Weight cube map
# --------------------------------------------------------------------------

def weight_cube(size: int = 16) -> np.ndarray:
    """The 8-bit channel-weight cube map, ``(6, size, size, 4)`` uint8, OpenGL face order.

    Component ``c`` of a texel holds the weight of channel ``c`` (positive)
    or of channel ``c + 4`` (negative: at most one of the two is non-zero),
    remapped from [-1, 1] to [0, 255] (Lengyel, eq. 5.3). The weights are the
    exact linear interpolation of :func:`hzval.conventions.channel_weights`
    at each texel's centre direction.
    """
    d = cv.cube_texel_directions(size)
    w = cv.channel_weights(d[..., 0], d[..., 1])
    n = cv.CHANNELS_PER_LAYER
    signed = w[..., :n] - w[..., n:]
    return cv.encode_signed_weight(signed)


# --------------------------------------------------------------------------
# The whole bake
# --------------------------------------------------------------------------

def estimate_bytes(rows: int, cols: int, params: BakeParams) -> int:
    """Peak memory in bytes that baking a ``rows x cols`` map needs (an estimate)."""
    pad = params.radius - 1
    return BAKE_BYTES_PER_TEXEL * (rows + 2 * pad) * (cols + 2 * pad)


def available_bytes() -> int:
    """Memory available to this process now (``MemAvailable``), in bytes."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    import os

    return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")


def check_fits(what: str, rows: int, cols: int, params: BakeParams) -> None:
    """Raise :class:`InputError` naming ``what`` if the bake would not fit in memory."""
    need, have = estimate_bytes(rows, cols, params), available_bytes()
    if need > have:
        raise InputError(what, f"a {cols}x{rows} bake needs about {need / 2**30:.1f} GiB of memory; "
                               f"{have / 2**30:.1f} GiB are available")


def bake(height: np.ndarray, params: BakeParams = BakeParams()) -> Bake:
    """Bake a normalised height map ``H[row, col]`` into the technique's textures."""
    from hzval import backend

    params.validate()
    backend.variant()
    timings = {}
    t0 = time.perf_counter()
    h = cv.heights_in_texels(height, params.depth)
    normal = normal_map(h, params.boundary)
    t1 = time.perf_counter()
    timings["normal_s"] = t1 - t0
    horizon, mean_cos, mean_cos2 = horizon_map(h, params.radius, params.angles, params.boundary)
    timings["horizon_s"] = time.perf_counter() - t1
    return Bake(params, horizon, normal, mean_cos, mean_cos2, timings)


def write_bake(result: Bake, out: str | Path, *, input_info: dict) -> list[Path]:
    """Write a bake's files into ``out`` (DESIGN.md, ``hzval bake``), all or nothing.

    ``input_info`` describes the input (path, digest, source, shape) and goes
    into ``bake.json`` with the parameters, versions and timings.
    """
    from hzval import backend, files

    t0 = time.perf_counter()
    layer0, layer1 = result.layers
    cube = weight_cube()

    # Writing dominated a 2048x2048 bake: zlib runs at ~35 MB/s here, and
    # ZIP shrinks float32 horizon data by 8% and 8-bit layers by 12%, while
    # neither encoder overlaps in threads. So bake outputs are stored
    # uncompressed: write time 2.8 s -> ~1.2 s.
    def exr(name, channels):
        files.write_exr(stage.path(name), channels, atomic=False, compression="none")

    def png(name, pixels):
        files.write_png(stage.path(name), pixels, atomic=False, compress_level=0)

    with files.Staging(out) as stage:
        exr("horizon0.exr", {"RGBA": layer0})
        exr("horizon1.exr", {"RGBA": layer1})
        png("horizon0.png", files.unit_to_u8(layer0))
        png("horizon1.png", files.unit_to_u8(layer1))
        exr("normal.exr", {"RGB": result.normal})
        png("normal.png", files.unit_to_u8(0.5 + 0.5 * result.normal))
        exr("ambient.exr", {"mean_cos": result.mean_cos, "mean_cos2": result.mean_cos2})
        for i, face in enumerate(cv.CUBE_FACES):
            png(f"cube/{face}.png", cube[i])
        timings = dict(result.timings, write_s=time.perf_counter() - t0)
        files.write_json(stage.path("bake.json"), {
            "input": input_info,
            "parameters": asdict(result.params),
            "outputs": {
                "horizon0": "channels 0-3 (azimuth 0, 45, 90, 135 deg) as RGBA: sine of the horizon angle",
                "horizon1": "channels 4-7 (azimuth 180, 225, 270, 315 deg) as RGBA",
                "normal": "tangent-space unit normal (PNG: 0.5 + 0.5 n)",
                "ambient": "mean_cos (Lengyel) and mean_cos2 (cosine-weighted unoccluded fraction)",
                "cube": "channel weights, 16x16 per face, OpenGL face order, 8-bit (w + 1) * 127.5",
            },
            "conventions": "DESIGN.md: +x right, +y up the image, azimuth counterclockwise from +x; "
                           "heights in texel units are H * depth * cols",
            "timings_s": {k: round(v, 4) for k, v in timings.items()},
            "versions": backend.versions(),
        }, atomic=False)
        return stage.commit()


def read_bake(folder: str | Path) -> Bake:
    """Read a bake written by :func:`write_bake` back from its EXR files (exact float32)."""
    import json

    from hzval import files

    folder = Path(folder)
    record = json.loads((folder / "bake.json").read_text())
    h0, h1 = files.read_exr(folder / "horizon0.exr"), files.read_exr(folder / "horizon1.exr")
    n, amb = files.read_exr(folder / "normal.exr"), files.read_exr(folder / "ambient.exr")
    horizon = np.stack([h0[c] for c in "RGBA"] + [h1[c] for c in "RGBA"], axis=-1)
    normal = np.stack([n[c] for c in "RGB"], axis=-1)
    return Bake(BakeParams(**record["parameters"]), horizon, normal, amb["mean_cos"], amb["mean_cos2"],
                dict(record["timings_s"]))


def cached_bake(height: np.ndarray, digest: str, params: BakeParams, folder: str | Path,
                input_info: dict) -> tuple[Bake, bool]:
    """Bake into ``folder``, or read the bake already there if it was made from the
    same input (``digest``) with the same parameters. Returns ``(bake, cached)``."""
    import json

    folder = Path(folder)
    try:
        record = json.loads((folder / "bake.json").read_text())
        if record["input"]["digest"] == digest and record["parameters"] == asdict(params):
            return read_bake(folder), True
    except (OSError, ValueError, KeyError, TypeError):
        pass   # no usable cache: bake anew
    result = bake(height, params)
    write_bake(result, folder, input_info=input_info)
    return result, False
