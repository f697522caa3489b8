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

``BakeParams(directions=16)`` stores 16 directions instead of the seed's 8:
channel ``k`` toward azimuth ``22.5 k`` degrees
(:func:`hzval.core.conventions.channel_azimuth_deg`) averages the
``angles / 16 + 1`` bins centred on it (``angles`` a multiple of 32: with 32
bins, channel ``k`` is the mean of bins ``2k - 1, 2k, 2k + 1``). The rule is
the seed's, ``angles / D + 1`` bins for ``D`` directions, i.e. the bins
between the two neighbouring channels' centres, ends included: each channel
covers its own ``360 / D``-degree sector, so the 16-direction channels are
narrower, not just more. The bins, and so the ambient terms, do not change.

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

That kernel unrolls the offset table, and its LLVM compile time grows faster
than the offset count (radius 16: 0.5 s; 32: 4 s; 64: 100 s). For large
radii on maps that are not large, :func:`horizon_map` runs a looped kernel
instead (symbolic Dr.Jit loops over the table, read as data: the same small
kernel at every radius), which gathers its neighbours and is 3-10x slower to
run but compiles at once; the two agree bit for bit, and
:func:`choose_kernel` picks by a cost model fitted to
``benchmarks/bench_bake_radius.py``.

The ambient map holds two averages over the bins' horizon angles ``alpha``:
``mean_cos``, Lengyel's term (the seed's ``sum * kAngleCount`` means an
average), and ``mean_cos2``, the exact cosine-weighted unoccluded fraction of
the hemisphere for a horizon at ``alpha`` in every direction.

A second method, ``BakeParams(method="exact")`` (:func:`exact_horizon_map`),
computes the exact horizon of every texel toward each of the 8 channel
directions with unlimited radius, by line sweeps with a convex-hull stack
(Timonen and Westerholm 2010, "Scalable Height Field Self-Shadowing"), O(n)
per line. It ignores ``radius`` and ``angles``; ``bake.json`` records them as
``null`` for it.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from hzval.core import conventions as cv
from hzval.core.errors import InputError

__all__ = ["CUBE_SIZE", "TEXEL_HALF_EXTENT", "BAKE_BYTES_PER_TEXEL",
    "BAKE_BYTES_PER_TEXEL_PER_EXTRA_DIRECTION", "BakeParams", "METHODS", "Bake", "normals_only",
    "normal_map", "OffsetGroup", "horizon_table", "KERNELS", "UNROLL_MAX_OFFSETS",
    "UNROLL_COMPILE_S", "UNROLL_COMPILE_POWER", "UNROLL_RUN_NS", "LOOP_RUN_NS", "choose_kernel",
    "kernel_for", "horizon_map", "CHANNEL_STEPS", "SweepLines", "sweep_lines", "ambient_from_sines",
    "exact_horizon_map", "weight_cube", "estimate_bytes", "available_bytes", "check_fits",
    "METHOD_NOTES", "CONTENTS", "needs_horizon", "bake", "write_bake", "read_bake", "cached_bake"]

#: Edge length in texels of a face of the weight cube map (Lengyel: 16 x 16
#: is sufficient); the GPU path of :mod:`hzval.techniques.horizon` samples it.
CUBE_SIZE = 16

#: Angular half-width factor of a texel seen from distance r: atan(0.7071 / r),
#: the seed's constant for a texel's half diagonal (sqrt(2)/2, rounded).
TEXEL_HALF_EXTENT = np.float32(0.7071)
#: The seed's ``two_pi`` as a float32 constant.
_TWO_PI_F32 = np.float32(6.2831855)

#: Bytes of memory per texel that a bake needs at its peak (inputs, padded
#: copy, ten kernel outputs, their NumPy copies, normal map, 8-bit encodings),
#: measured with tracemalloc and rounded up, for 8 directions.
BAKE_BYTES_PER_TEXEL = 160
#: Bytes per texel that each direction beyond 8 adds (a kernel output, its
#: NumPy copy and stacked channel, its 8-bit encoding: 4 + 4 + 4 + 1, rounded
#: up; an estimate from the 8-direction figure, not measured separately).
BAKE_BYTES_PER_TEXEL_PER_EXTRA_DIRECTION = 16


@dataclass(frozen=True)
class BakeParams:
    """Parameters of a bake (``hzval bake``'s options).

    ``depth``: world height of ``H = 1`` in units of the image width.
    ``radius``: search radius in texels; neighbours with ``r < radius`` count.
    ``angles``: number of angular bins; a multiple of ``2 * directions``
    (each channel averages ``angles/directions + 1`` bins centred on its
    direction, module docstring).
    ``boundary``: ``wrap`` or ``open`` (:mod:`hzval.core.conventions`).
    ``method``: ``seed`` (the seed algorithm above, :func:`horizon_map`) or
    ``exact`` (exact horizons toward the 8 channel directions with unlimited
    radius, :func:`exact_horizon_map`; ``radius`` and ``angles`` are ignored
    and not validated, and :meth:`record` writes them as ``None``).
    ``directions``: stored horizon directions, 8 (the seed's) or 16
    (:data:`hzval.core.conventions.DIRECTION_COUNTS`); channel ``c`` looks toward
    azimuth ``360 c / directions`` degrees. ``exact`` supports 8 only: along
    the odd multiples of 22.5 degrees a ray from a texel centre meets no
    texel centres, so the exact sweeps would need interpolated heights
    (not implemented; :meth:`validate` says so).
    """

    depth: float = 0.05
    radius: int = 16
    angles: int = 32
    boundary: str = "wrap"
    method: str = "seed"
    directions: int = cv.CHANNEL_COUNT

    def validate(self) -> "BakeParams":
        cv.check_depth(self.depth, "--depth", self.boundary)
        if self.method not in METHODS:
            raise InputError("--method", f"unknown bake method {self.method!r}; available: {', '.join(METHODS)}")
        if (isinstance(self.directions, bool) or not isinstance(self.directions, (int, np.integer))
                or self.directions not in cv.DIRECTION_COUNTS):
            raise InputError("--directions", f"must be one of {', '.join(map(str, cv.DIRECTION_COUNTS))}, "
                                             f"got {self.directions}")
        if self.method == "exact" and self.directions != cv.CHANNEL_COUNT:
            raise InputError("--directions", f"the exact method stores {cv.CHANNEL_COUNT} directions only: along "
                                             "22.5-degree directions a ray meets no texel centres, and the exact "
                                             "sweeps do not interpolate heights; use --method seed")
        if self.method == "seed":
            if self.radius is None or int(self.radius) != self.radius or self.radius < 2:
                raise InputError("--radius", f"must be an integer of at least 2 texels, got {self.radius}")
            m = 2 * int(self.directions)
            if self.angles is None or int(self.angles) != self.angles or self.angles < m or self.angles % m:
                raise InputError("--angles", f"must be a multiple of {m} ({m}, {2 * m}, {3 * m}, ...) with "
                                             f"{self.directions} directions, got {self.angles}")
        if self.boundary not in cv.BOUNDARIES:
            raise InputError("--boundary", f"must be one of {', '.join(cv.BOUNDARIES)}, got {self.boundary!r}")
        return self

    def record(self) -> dict:
        """The parameters as ``bake.json`` records them (and the bake cache compares).

        The ``exact`` method has no search radius and no angular bins: it
        records ``radius`` and ``angles`` as ``None`` rather than values it
        did not use, so two exact bakes that differ only there share a cache.
        """
        d = asdict(self)
        if self.method == "exact":
            d.update(radius=None, angles=None)
        return d

    @classmethod
    def from_record(cls, record: dict) -> "BakeParams":
        """The inverse of :meth:`record` (``None`` entries take the defaults).

        A record without ``directions`` (written before it existed) is a
        bake of the seed's 8 directions."""
        return cls(**{k: v for k, v in record.items() if v is not None})

    @staticmethod
    def normalise_record(record: dict) -> dict:
        """``record`` as :meth:`record` writes it now: a missing ``directions`` is 8.

        The bake cache compares records, and a ``bake.json`` from before
        ``directions`` existed holds an 8-direction bake."""
        return {"directions": cv.CHANNEL_COUNT, **record}


#: Horizon bake methods (``BakeParams.method``, ``--method``).
METHODS: tuple[str, ...] = ("seed", "exact")


@dataclass
class Bake:
    """The textures of the technique, as float32 arrays indexed ``[row, col]``.

    ``horizon``: ``(rows, cols, D)`` sines of the horizon angle, channel ``k``
    toward azimuth ``360 k / D`` degrees (``D = params.directions``, 8 or 16). ``normal``: ``(rows, cols, 3)`` unit
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
    def directions(self) -> int:
        """Stored horizon directions (channels), 8 or 16 (a bake without a horizon map: the parameters')."""
        return int(self.horizon.shape[-1]) if self.horizon is not None else int(self.params.directions)

    @property
    def contents(self) -> tuple[str, ...]:
        """What the bake holds (:data:`CONTENTS`)."""
        return CONTENTS if self.horizon is not None else ("normal",)

    @property
    def layers(self) -> tuple[np.ndarray, ...]:
        """The ``D / 4`` RGBA layers: layer ``l`` holds channels ``4 l .. 4 l + 3``."""
        n = cv.CHANNELS_PER_LAYER
        return tuple(self.horizon[..., n * i:n * (i + 1)] for i in range(cv.layer_count(self.directions)))


def normals_only(height: np.ndarray, depth: float, boundary: str) -> "Bake":
    """A :class:`Bake` of the normal map alone (``horizon`` and the ambient maps ``None``):
    the unshadowed shading of a technique that reads no horizon map, built
    without the horizon bake's cost. ``height`` normalised, ``(rows, cols)``."""
    h = cv.heights_in_texels(height, depth)
    return Bake(params=BakeParams(depth=depth, boundary=boundary), horizon=None,
                normal=normal_map(h, boundary), mean_cos=None, mean_cos2=None)


# --------------------------------------------------------------------------
# Normal map
# --------------------------------------------------------------------------

def normal_map(h_texels: np.ndarray, boundary: str) -> np.ndarray:
    """Unit tangent-space normals ``normalize(-dh/dx, -dh/dy, 1)``, ``(rows, cols, 3)``.

    Central differences of heights in texel units (FGED2 ch. 7, with its
    listing's use-before-definition fixed, docs/ARCHITECTURE.md).
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


#: Horizon-bake kernel forms (:func:`horizon_map`'s ``kernel``).
KERNELS: tuple[str, ...] = ("auto", "unrolled", "loop")

#: Offset tables up to this size always take the unrolled kernel (radius 20,
#: 1,244 offsets, is the largest radius below it). The default radius 16 (792
#: offsets) compiles in 0.54 s and then runs 10x faster than the loop (512 x
#: 512: 0.040 s against 0.43 s; benchmarks/README.md); Dr.Jit caches the
#: compiled kernel on disk, so the compile is paid once per machine, not per
#: bake. On a first bake the loop is only about as fast (0.48 s against 0.59 s),
#: so below this size the unrolled kernel is the better choice overall.
UNROLL_MAX_OFFSETS = 1300

#: Cost model of a first bake (empty kernel cache) above
#: :data:`UNROLL_MAX_OFFSETS`, for ``kernel="auto"``; fitted to
#: ``benchmarks/bench_bake_radius.py --size 512`` on the 2-core AVX2 machine
#: of benchmarks/README.md. The unrolled kernel's LLVM compile time grows
#: faster than its offset count ``n``: 4.3 s at radius 32 (3,204 offsets),
#: 102 s at radius 64 (12,848), i.e. ``UNROLL_COMPILE_S * (n / 1000) **
#: UNROLL_COMPILE_POWER`` seconds through those two points. Run times are
#: nanoseconds per (offset x lane), a lane being a texel of a padded row:
#: measured 0.17-0.46 unrolled (contiguous vector loads), 1.2-1.9 for the
#: loop (it gathers every neighbour and table entry). The loop wins when the
#: compile outweighs the loop's slower run: for radius 32 below about
#: 1000 x 1000 texels, for radius 64 below about 2500 x 2500.
UNROLL_COMPILE_S = 0.296
UNROLL_COMPILE_POWER = 2.29
UNROLL_RUN_NS = 0.3
LOOP_RUN_NS = 1.5


def choose_kernel(offsets: int, lanes: int) -> str:
    """The kernel form that :func:`horizon_map` uses by default (``kernel="auto"``).

    ``offsets``: entries of the offset table (:func:`horizon_table`);
    ``lanes``: texels of the padded rows, ``rows * (cols + 2 (radius - 1))``.
    Tables up to :data:`UNROLL_MAX_OFFSETS` unroll; larger ones take the
    form whose first bake, compile included, the cost model above predicts
    to be faster. Once compiled, the unrolled kernel is loaded from Dr.Jit's
    disk cache and is always the faster one, but ``auto`` decides for a
    first bake: a large radius is rarely baked twice at one setting.
    """
    if offsets <= UNROLL_MAX_OFFSETS:
        return "unrolled"
    compile_s = UNROLL_COMPILE_S * (offsets / 1000.0) ** UNROLL_COMPILE_POWER
    unrolled_s = compile_s + UNROLL_RUN_NS * 1e-9 * offsets * lanes
    loop_s = LOOP_RUN_NS * 1e-9 * offsets * lanes
    return "loop" if loop_s < unrolled_s else "unrolled"


def kernel_for(rows: int, cols: int, radius: int, angles: int) -> str:
    """The kernel form :func:`horizon_map` takes by default for a ``rows x cols`` map
    (:func:`choose_kernel` on its offset table and its lanes, the padded rows)."""
    offsets = sum(len(g.offsets) for g in horizon_table(radius, angles))
    return choose_kernel(offsets, rows * (cols + 2 * (radius - 1)))


def horizon_map(h_texels: np.ndarray, radius: int = 16, angles: int = 32,
                boundary: str = "wrap", *, kernel: str = "auto",
                directions: int = cv.CHANNEL_COUNT) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Seed horizon bake of heights in texel units.

    Returns ``(horizon, mean_cos, mean_cos2)``: the ``(rows, cols, D)`` channel
    sines (``D = directions``, 8 or 16; ``angles`` a multiple of ``2 D``;
    channel ``k`` the mean of the ``angles / D + 1`` bins centred on azimuth
    ``360 k / D`` degrees) and the two ``(rows, cols)`` ambient terms over
    all bins, float32. Runs on the current Mitsuba variant's Dr.Jit backend
    (:func:`hzval.core.backend.variant`).

    ``kernel`` chooses how the offset table (:func:`horizon_table`) becomes
    code; both forms compute the same float32 operations on the same values
    and agree bit for bit (``tests/test_bake_radius.py``):

    ``unrolled``
        one block of code per offset, neighbours read as shifted views
        (module docstring). Fastest to run, but its compile time grows faster
        than the offset count (about ``radius^2``): 0.6 s at radius 16, 5 s
        at 32, 100 s at 64 (benchmarks/README.md).
    ``loop``
        a symbolic loop over the offset table (:func:`_max_tan_loop`): one
        small kernel whatever the radius (compiles in well under a second),
        but it gathers every neighbour and is about 10x slower to run.
    ``auto``
        :func:`choose_kernel`: unrolled up to :data:`UNROLL_MAX_OFFSETS`
        offsets (the default radius 16), else the faster first bake.
    """
    import drjit as dr
    import mitsuba as mi

    if kernel not in KERNELS:
        raise ValueError(f"unknown kernel form {kernel!r}; available: {', '.join(KERNELS)}")
    if directions not in cv.DIRECTION_COUNTS or angles % (2 * directions):
        raise ValueError(f"{directions} directions need a multiple of {2 * directions} bins, got {angles}")
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
    table = horizon_table(radius, angles)
    if kernel == "auto":
        kernel = kernel_for(rows, cols, radius, angles)

    def shift_of(i: int, j: int) -> int:
        drow, dcol = cv.tangent_to_pixel_offset(i, j)
        return drow * pcols + dcol

    if kernel == "loop":
        max_tan = _max_tan_loop(mi.Float(flat), start, lanes, table, angles, shift_of)
    else:
        max_tan = _max_tan_unrolled(flat, start, lanes, table, angles, shift_of)
    channels, mean_cos, mean_cos2 = _channels(max_tan, angles, directions)
    dr.eval(*channels, mean_cos, mean_cos2)

    def image(v) -> np.ndarray:
        return np.asarray(v, dtype=np.float32).reshape(rows, pcols)[:, pad:pad + cols]

    horizon = np.stack([image(c) for c in channels], axis=-1)
    result = horizon, image(mean_cos).copy(), image(mean_cos2).copy()
    del flat  # the views above must not outlive it; they are evaluated by now
    return result


def _max_tan_unrolled(flat: np.ndarray, start: int, lanes: int, table, angles: int, shift_of) -> list:
    """Per bin, the largest ``tan = dh / r`` of the offsets it covers: one block of code per
    offset group, neighbours read as zero-copy shifted views on the LLVM backend (contiguous
    loads) and gathered elsewhere. ``flat`` must outlive the kernel's evaluation."""
    import drjit as dr
    import mitsuba as mi

    if dr.backend_v(mi.Float) == dr.JitBackend.LLVM:
        def neighbour(shift: int):
            # zero-copy view: the kernel reads it with contiguous loads
            return mi.Float(flat[start + shift:start + shift + lanes])
    else:
        source = mi.Float(flat)
        lane = dr.arange(mi.Int32, lanes) + start

        def neighbour(shift: int):
            return dr.gather(mi.Float, source, mi.UInt32(lane + shift))

    h0 = neighbour(0)
    max_tan = [mi.Float(0.0) for _ in range(angles)]
    for group in table:
        # max over the group of tan = dh / r; clamped at 0 by the bins' start
        # value, which is the seed's "dh > 0" test
        g = None
        for (i, j), inv_r in zip(group.offsets, group.inv_r):
            t = (neighbour(shift_of(i, j)) - h0) * inv_r
            g = t if g is None else dr.maximum(g, t)
        for b in group.bins:
            max_tan[b] = dr.maximum(max_tan[b], g)
    return max_tan


def _channels(max_tan: list, angles: int, directions: int) -> tuple[list, object, object]:
    """``(channels, mean_cos, mean_cos2)`` from the bins' largest tangents: ``sin = sqrt(t^2 /
    (t^2 + 1))``, each channel the mean of the ``angles / D + 1`` bins centred on it, and the
    ambient terms' means over all bins."""
    import drjit as dr

    cos2 = [dr.rcp(dr.fma(t, t, 1.0)) for t in max_tan]     # 1 / (1 + tan^2)
    sines = [t * dr.sqrt(c) for t, c in zip(max_tan, cos2)]  # sqrt(t^2 / (t^2 + 1))
    half = angles // (2 * directions)   # each channel: 2 half + 1 = angles / D + 1 bins
    channels = []
    for k in range(directions):
        centre = k * angles // directions
        s = sines[(centre - half) % angles]
        for d in range(-half + 1, half + 1):
            s = s + sines[(centre + d) % angles]
        channels.append(s * (1.0 / (2 * half + 1)))
    mean_cos = sum(dr.sqrt(c) for c in cos2) * (1.0 / angles)
    mean_cos2 = sum(cos2) * (1.0 / angles)
    return channels, mean_cos, mean_cos2


def _max_tan_loop(source, start: int, lanes: int, table: list[OffsetGroup], angles: int, shift_of) -> list:
    """The ``angles`` per-bin maxima of ``tan`` (>= 0) by symbolic Dr.Jit loops over ``table``.

    ``source`` is the flat padded map (:func:`horizon_map`), lane ``l`` the
    texel at flat index ``start + l``, ``shift_of(i, j)`` the flat shift of
    tangent offset ``(i, j)``. The table travels as data, so the kernel's
    code does not depend on the radius or the map size (the bin count sets
    the size of its local array):

    * ``pairs``: ``(1/r, shift)`` of every offset as float32 pairs (one
      packet gather per offset; shifts are integers far below 2^24, exact
      in float32), ordered group by group;
    * per group: the first and one-past-last offset, and the range of its
      bin indices in ``bins``.

    An outer loop runs over the groups; an inner loop takes the group's
    maximum ``g`` of ``tan = (h_neighbour - h_0) / r`` (starting at -inf,
    the identity of max), and a third loop raises the group's bins to ``g``
    in a per-lane local array of ``angles`` floats (``dr.alloc_local``),
    which starts at 0: the seed's ``dh > 0`` test, as in the unrolled form.
    Every value is the same float32 ``(h_n - h_0) * (1/r)`` and max is exact
    and order-free, so the result equals the unrolled kernel's bit for bit.
    """
    import drjit as dr
    import mitsuba as mi

    pairs, group_first, group_end, bin_first, bin_end, bins = [], [], [], [], [], []
    for group in table:
        group_first.append(len(pairs))
        pairs += [(inv_r, shift_of(i, j)) for (i, j), inv_r in zip(group.offsets, group.inv_r)]
        group_end.append(len(pairs))
        bin_first.append(len(bins))
        bins += group.bins
        bin_end.append(len(bins))
    pairs_f = mi.Float(np.asarray(pairs, dtype=np.float32).ravel())
    g_first, g_end, b_first, b_end, bin_of = (mi.UInt32(np.asarray(a, dtype=np.uint32))
                                              for a in (group_first, group_end, bin_first, bin_end, bins))
    # opaque: the radius and the map's width change these, and must not change the kernel
    lane = dr.arange(mi.Int32, lanes) + dr.opaque(mi.Int32, start)
    h0 = dr.gather(mi.Float, source, mi.UInt32(lane))
    n_groups = dr.opaque(mi.UInt32, len(table))

    def group_body(gi, best):
        def offset_body(o, g):
            inv_r, shift = dr.gather(mi.Vector2f, pairs_f, o)     # one 2-float packet
            t = (dr.gather(mi.Float, source, mi.UInt32(lane + mi.Int32(shift))) - h0) * inv_r
            return o + 1, dr.maximum(g, t)

        _, g = dr.while_loop((dr.gather(mi.UInt32, g_first, gi), mi.Float(-np.inf)),
                             lambda o, g: o < dr.gather(mi.UInt32, g_end, gi), offset_body)

        def bin_body(k, best):
            b = dr.gather(mi.UInt32, bin_of, k)
            best[b] = dr.maximum(best[b], g)
            return k + 1, best

        _, best = dr.while_loop((dr.gather(mi.UInt32, b_first, gi), best),
                                lambda k, best: k < dr.gather(mi.UInt32, b_end, gi), bin_body)
        return gi + 1, best

    _, best = dr.while_loop((mi.UInt32(0), dr.alloc_local(mi.Float, angles, mi.Float(0.0))),
                            lambda gi, best: gi < n_groups, group_body)
    return [best[b] for b in range(angles)]


# --------------------------------------------------------------------------
# Exact horizon map: line sweeps with a convex-hull stack
# --------------------------------------------------------------------------

#: Tangent-space steps ``(dx, dy)`` from a texel centre to the next texel
#: centre toward each channel's azimuth ``45 k`` degrees (+y up the image).
CHANNEL_STEPS: tuple[tuple[int, int], ...] = (
    (1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1), (1, -1))


@dataclass(frozen=True)
class SweepLines:
    """The lines along which one channel's horizons are swept.

    A ray from a texel centre toward azimuth ``45 k`` degrees passes through
    texel centres only, one every ``step`` texels (1 along the axes,
    ``sqrt 2`` along the diagonals), so a line is a sequence of texels and no
    height is interpolated. Position ``i`` of a line is the texel
    ``near + i * (drow, dcol)``; the sweep visits the positions from
    ``count - 1`` down to 0, so that when it reaches a texel every texel
    ahead of it (toward the channel's azimuth) has been seen.

    ``wrap``: the lines are the cycles of ``texel -> texel + (drow, dcol)``
    on the torus (rows, columns, or, for the diagonals, ``gcd(rows, cols)``
    cycles of ``lcm(rows, cols)`` texels); ``length`` is the period and the
    sweep runs ``count = 2 length - 1`` positions, taken modulo the image, so
    that the first ``length`` positions each have a whole period ahead.
    ``open``: the lines run from an entry texel (whose predecessor is outside
    the image) to the edge; ``count = length``.

    All arrays have one entry per line, sorted by ``count``, longest first:
    ``near_row``, ``near_col`` (position 0), ``far_row``, ``far_col``
    (position ``count - 1``, reduced into the image), ``length``, ``count``
    (int64) and ``offset``, where the line's scratch starts (the running sum
    of ``count``).
    """

    drow: int
    dcol: int
    step: float
    near_row: np.ndarray
    near_col: np.ndarray
    far_row: np.ndarray
    far_col: np.ndarray
    length: np.ndarray
    count: np.ndarray
    offset: np.ndarray

    @property
    def total(self) -> int:
        """Scratch entries that a sweep of all lines needs (one per position)."""
        return int(self.count.sum())


def sweep_lines(rows: int, cols: int, channel: int, boundary: str) -> SweepLines:
    """The lines of channel ``channel`` (0..7) on a ``rows x cols`` map (:class:`SweepLines`)."""
    dx, dy = CHANNEL_STEPS[channel]
    drow, dcol = cv.tangent_to_pixel_offset(dx, dy)
    if boundary == "wrap":
        if drow == 0:        # along the rows
            r0, c0, period = np.arange(rows), np.zeros(rows, np.int64), cols
        elif dcol == 0:      # along the columns
            r0, c0, period = np.zeros(cols, np.int64), np.arange(cols), rows
        else:                # diagonal: texels (r0 + i drow, i dcol), r0 < gcd, are distinct cycles
            g = math.gcd(rows, cols)
            r0, c0, period = np.arange(g), np.zeros(g, np.int64), rows * cols // g
        length = np.full(r0.shape, period, np.int64)
        count = 2 * length - 1
    elif boundary == "open":
        rr, cc = np.mgrid[0:rows, 0:cols]
        pr, pc = rr - drow, cc - dcol
        entry = ~((pr >= 0) & (pr < rows) & (pc >= 0) & (pc < cols))
        r0, c0 = rr[entry].astype(np.int64), cc[entry].astype(np.int64)
        big = np.int64(rows + cols)

        def room(start, d, n):
            return np.full(start.shape, big) if d == 0 else (n - start if d > 0 else start + 1)

        length = np.minimum(room(r0, drow, rows), room(c0, dcol, cols))
        count = length.copy()
    else:
        raise ValueError(f"unknown boundary {boundary!r}")
    order = np.argsort(-count, kind="stable")
    r0, c0, length, count = r0[order], c0[order], length[order], count[order]
    offset = np.concatenate([[0], np.cumsum(count)[:-1]]).astype(np.int64)
    return SweepLines(drow, dcol, math.hypot(dx, dy), r0, c0,
                      (r0 + (count - 1) * drow) % rows, (c0 + (count - 1) * dcol) % cols,
                      length, count, offset)


def _sweep_numpy(h: np.ndarray, lines: SweepLines) -> np.ndarray:
    """One channel's exact horizon sines, ``(rows * cols,)`` float32, in NumPy.

    The same sweep as :func:`_sweep_drjit`, vectorised across lines: the
    Python loop runs over positions, and the stack walk is masked to the lines
    that still pop. Used where Dr.Jit's LLVM backend is missing; about 40x
    slower than the kernel at 512 x 512 on this 2-core machine
    (``benchmarks/bench_horizon_methods.py``).
    """
    rows, cols = h.shape
    flat = h.ravel()
    count, length = lines.count, lines.length
    n_lines, most = len(count), int(count.max())
    nxt_of = np.empty((n_lines, most), np.int32)   # the stack, as links: position -> next hull vertex
    h_at = np.empty((n_lines, most), np.float32)   # height at each position
    r, c = lines.far_row.copy(), lines.far_col.copy()
    out = np.zeros(rows * cols, np.float32)
    neg_count = -count
    for s in range(most):
        m = int(np.searchsorted(neg_count, -s, side="left"))  # lines with count > s (sorted)
        lane = np.arange(m)
        k = count[:m] - 1 - s
        texel = r[:m] * cols + c[:m]
        hk = flat[texel]
        has = k + 1 < count[:m]
        first = np.minimum(k + 1, count[:m] - 1)
        cand = k + 1
        hc = h_at[lane, first]
        nn = np.where(has, nxt_of[lane, first], -1)
        act = np.nonzero(nn >= 0)[0]
        while act.size:
            a_n = nn[act]
            hn = h_at[act, a_n]
            dk = (k[act]).astype(np.float32)
            pop = (hn - hk[act]) * (cand[act] - dk) >= (hc[act] - hk[act]) * (a_n - dk)
            act, a_n, hn = act[pop], a_n[pop], hn[pop]
            cand[act], hc[act] = a_n, hn
            nn[act] = nxt_of[act, a_n]
            act = act[nn[act] >= 0]
        nxt_of[lane, k] = np.where(has, cand, -1)
        h_at[lane, k] = hk
        d = ((cand - k) * lines.step).astype(np.float32)
        with np.errstate(over="ignore", invalid="ignore"):  # lanes without `has` read unset scratch
            dh = hc - hk
            sine = np.where(has & (dh > 0), dh / np.sqrt(dh * dh + d * d), np.float32(0))
        keep = k < length[:m]
        out[texel[keep]] = sine[keep]
        r[:m] = (r[:m] - lines.drow) % rows
        c[:m] = (c[:m] - lines.dcol) % cols
    return out


def _sweep_drjit(h, shape: tuple[int, int], lines: SweepLines, channel: int, out,
                 nxt_np: np.ndarray, h_np: np.ndarray) -> None:
    """Schedule one channel's sweep as a Dr.Jit LLVM kernel; it scatters into ``out``.

    ``h``: the heights (``drjit.llvm.Float``, row-major) of a map of
    ``shape = (rows, cols)``; ``out``: the
    ``rows * cols * 8`` interleaved sines; ``nxt_np``, ``h_np``: scratch of at
    least ``lines.total`` entries. One lane per line runs the sweep of
    :func:`exact_horizon_map` over its positions.

    The stack is the chain of links ``next[i]`` (the next hull vertex after
    position ``i``), written once per position and read at later positions of
    the same kernel. Dr.Jit does not let a kernel read what it scattered into
    the same array, so the scratch is a NumPy buffer that two Dr.Jit arrays
    map without copying (LLVM backend only): one is written, the other read.
    :func:`exact_horizon_map` checks afterwards that the writes landed there.
    """
    import drjit as dr
    from drjit.llvm import Float, Int32, UInt32

    rows, cols = shape
    total = lines.total
    nxt_w, nxt_r = Int32(nxt_np[:total]), Int32(nxt_np[:total])
    h_w, h_r = Float(h_np[:total]), Float(h_np[:total])
    offset = UInt32(lines.offset.astype(np.uint32))
    count = Int32(lines.count.astype(np.int32))
    length = Int32(lines.length.astype(np.int32))
    # opaque: one compiled kernel serves every channel and map size
    drow, dcol = dr.opaque(Int32, lines.drow), dr.opaque(Int32, lines.dcol)
    n_rows, n_cols = dr.opaque(Int32, rows), dr.opaque(Int32, cols)
    step = dr.opaque(Float, lines.step)
    channel_ = dr.opaque(UInt32, channel)

    def wrap(v, n):
        return dr.select(v < 0, v + n, dr.select(v >= n, v - n, v))

    def position(k, r, c):
        texel = UInt32(r * n_cols + c)
        hk = dr.gather(Float, h, texel)
        ahead = k + 1 < count
        first = offset + UInt32(dr.minimum(k + 1, count - 1))
        # candidate tangent point: the previous top of the stack, position k + 1
        cand = k + 1
        hc = dr.gather(Float, h_r, first, ahead)
        nxt = dr.select(ahead, dr.gather(Int32, nxt_r, first, ahead), -1)
        hn = dr.gather(Float, h_r, offset + UInt32(dr.maximum(nxt, 0)), nxt >= 0)

        def steeper(cand, hc, nxt, hn):
            # pop cand while the next hull vertex is seen at least as steeply
            # from k: (hn - hk) / (nxt - k) >= (hc - hk) / (cand - k)
            return (nxt >= 0) & ((hn - hk) * Float(cand - k) >= (hc - hk) * Float(nxt - k))

        def pop(cand, hc, nxt, hn):
            cand, hc = nxt, hn
            nxt = dr.gather(Int32, nxt_r, offset + UInt32(cand))
            hn = dr.gather(Float, h_r, offset + UInt32(dr.maximum(nxt, 0)), nxt >= 0)
            return cand, hc, nxt, hn

        cand, hc, nxt, hn = dr.while_loop((cand, hc, nxt, hn), steeper, pop)
        slot = offset + UInt32(k)
        dr.scatter(nxt_w, dr.select(ahead, cand, -1), slot)
        dr.scatter(h_w, hk, slot)
        dh = hc - hk
        d = Float(cand - k) * step
        sine = dr.select(ahead & (dh > 0), dh / dr.sqrt(dr.fma(dh, dh, d * d)), 0.0)
        dr.scatter(out, sine, texel * cv.CHANNEL_COUNT + channel_, k < length)
        return k - 1, wrap(r - drow, n_rows), wrap(c - dcol, n_cols)

    start = (count - 1, Int32(lines.far_row.astype(np.int32)), Int32(lines.far_col.astype(np.int32)))
    dr.while_loop(start, lambda k, r, c: k >= 0, position)
    dr.eval(out)


def _have_llvm() -> bool:
    try:
        import drjit as dr

        return bool(dr.has_backend(dr.JitBackend.LLVM))
    except Exception:  # noqa: BLE001 - any failure means: use NumPy
        return False


def ambient_from_sines(sines: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(mean_cos, mean_cos2)`` over the last axis of horizon sines, float32.

    The seed's definitions (module docstring) over the given directions:
    ``cos alpha = sqrt(1 - sin^2 alpha)``, averaged, and ``cos^2 alpha``,
    averaged. Float32, summed over the directions in order, as the Dr.Jit
    path of :func:`exact_horizon_map` does.
    """
    s = np.asarray(sines, dtype=np.float32)
    sum_cos = np.zeros(s.shape[:-1], np.float32)
    sum_cos2 = np.zeros(s.shape[:-1], np.float32)
    for k in range(s.shape[-1]):
        cos2 = np.maximum(np.float32(1.0) - s[..., k] * s[..., k], np.float32(0.0))
        sum_cos += np.sqrt(cos2)
        sum_cos2 += cos2
    scale = np.float32(1.0 / s.shape[-1])
    return sum_cos * scale, sum_cos2 * scale


def exact_horizon_map(h_texels: np.ndarray, boundary: str = "wrap", *,
                      engine: str = "auto") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact horizon bake of heights in texel units, unlimited radius.

    Returns ``(horizon, mean_cos, mean_cos2)`` like :func:`horizon_map`:
    channel ``k`` of ``horizon`` (``(rows, cols, 8)`` float32) is, for the
    ray from the texel centre ``p`` toward azimuth ``45 k`` degrees
    (direction ``d``, :data:`CHANNEL_STEPS`), the sine of the horizon angle

        ``max(0, max over t > 0 of sin(atan((h(p + t d) - h(p)) / t)))``

    where ``t`` is the distance in texels. Along these 8 directions the ray
    from a texel centre meets texel centres only, at ``t = i`` (axes) or
    ``t = i sqrt 2`` (diagonals), ``i = 1, 2, ...``, so ``h`` is read at
    texels and never interpolated; ``sin(atan(dh / t)) = dh / sqrt(dh^2 +
    t^2)``.

    How far the ray goes: ``open``: to the edge of the image (nothing is
    beyond it). ``wrap``: the line through ``p`` is periodic, with period
    ``L`` texels (the cycle of :func:`sweep_lines`; ``L = cols``, ``rows`` or
    ``lcm(rows, cols)``), and ``h(p + (i + L) d) = h(p + i d)``. A texel
    further than one period is the same height at a larger distance: if it
    is higher than ``p`` its slope is smaller than the same texel's one
    period nearer, and if not its slope is <= 0. So the maximum over
    ``i = 1 .. L`` is the maximum over all ``i > 0`` (``i = L`` is ``p``
    itself, slope 0): unlimited radius, exactly, after one period.

    Method (Timonen and Westerholm 2010, "Scalable Height Field
    Self-Shadowing", section 3): sweep each line against the direction, so
    that the texels ahead of ``p`` are the ones already swept. The steepest
    texel ahead of ``p`` is a vertex of the upper convex hull of the profile
    ahead (positions vs heights), and it is the vertex where the tangent from
    ``p`` touches that hull. Keep the hull as a stack; at ``p``, pop while the
    vertex below the top is seen at least as steeply from ``p`` as the top
    (the popped vertices lie under the segment from ``p`` to the tangent
    point, so they are on no later texel's hull either); the top is then the
    tangent point, and ``p`` is pushed. Each texel is pushed and popped at
    most once: O(n) per line. ``wrap`` sweeps ``2 L - 1`` positions, the
    first ``L - 1`` only to fill the stack with a period ahead.

    Slopes are compared without division, ``(h_b - h_p)(a - p) >= (h_a -
    h_p)(b - p)`` in float32; heights, sines and ambient terms are float32.

    The ambient terms use the 8 channel directions (:func:`ambient_from_sines`),
    not ``angles`` bins: other azimuths would put the ray between texel
    centres and need interpolated heights.

    ``engine``: ``drjit`` (one Dr.Jit LLVM kernel per channel, one lane per
    line), ``numpy`` (:func:`_sweep_numpy`), or ``auto`` (Dr.Jit when its LLVM
    backend is available, whatever the Mitsuba variant).
    """
    h = np.ascontiguousarray(h_texels, dtype=np.float32)
    rows, cols = h.shape
    if engine == "auto":
        engine = "drjit" if _have_llvm() else "numpy"
    all_lines = [sweep_lines(rows, cols, ch, boundary) for ch in range(cv.CHANNEL_COUNT)]
    if engine == "numpy":
        horizon = np.stack([_sweep_numpy(h, lines).reshape(rows, cols) for lines in all_lines], axis=-1)
        return (horizon, *ambient_from_sines(horizon))
    if engine == "drjit":
        return _exact_drjit(h, all_lines)
    raise ValueError(f"unknown engine {engine!r}")


def _exact_drjit(h: np.ndarray, all_lines: list[SweepLines]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`exact_horizon_map` on Dr.Jit's LLVM backend: one sweep kernel per
    channel into one interleaved buffer, then one kernel for the ambient terms
    (:func:`ambient_from_sines`'s formulas; 10x faster than NumPy's strided
    passes over the 8 channels at 2048 x 2048)."""
    import drjit as dr
    from drjit.llvm import Float, UInt32

    rows, cols = h.shape
    size = max(lines.total for lines in all_lines)
    nxt_np = np.empty(size, np.int32)
    h_np = np.empty(size, np.float32)
    heights = Float(h.ravel())
    out = dr.zeros(Float, rows * cols * cv.CHANNEL_COUNT)
    for ch, lines in enumerate(all_lines):
        # the scratch is reused: the kernels run in order on one stream
        h_np[lines.offset] = np.nan
        _sweep_drjit(heights, (rows, cols), lines, ch, out, nxt_np, h_np)
        dr.sync_thread()
        # every line wrote the height of its position 0 into its first slot
        if not np.array_equal(h_np[lines.offset], h[lines.near_row, lines.near_col]):
            raise RuntimeError("exact horizon bake: Dr.Jit did not write into the NumPy scratch buffer "
                               "(zero-copy mapping unavailable); use engine='numpy'")
    del nxt_np, h_np  # the kernels are done (synchronised above)
    first = dr.arange(UInt32, rows * cols) * cv.CHANNEL_COUNT
    sum_cos, sum_cos2 = Float(0.0), Float(0.0)
    for ch in range(cv.CHANNEL_COUNT):
        sine = dr.gather(Float, out, first + ch)
        cos2 = dr.maximum(1.0 - sine * sine, 0.0)
        sum_cos, sum_cos2 = sum_cos + dr.sqrt(cos2), sum_cos2 + cos2
    mean_cos, mean_cos2 = sum_cos * (1.0 / cv.CHANNEL_COUNT), sum_cos2 * (1.0 / cv.CHANNEL_COUNT)
    dr.eval(mean_cos, mean_cos2)
    # .numpy() views Dr.Jit's memory without a copy and keeps it alive (writable)
    horizon = np.asarray(out.numpy(), dtype=np.float32).reshape(rows, cols, cv.CHANNEL_COUNT)
    return (horizon, np.asarray(mean_cos.numpy(), np.float32).reshape(rows, cols),
            np.asarray(mean_cos2.numpy(), np.float32).reshape(rows, cols))


# --------------------------------------------------------------------------
# Weight cube map
# --------------------------------------------------------------------------

def weight_cube(size: int | None = None) -> np.ndarray:
    """The 8-bit channel-weight cube map, ``(6, size, size, 4)`` uint8, OpenGL face order.

    Component ``c`` of a texel holds the weight of channel ``c`` (positive)
    or of channel ``c + 4`` (negative: at most one of the two is non-zero),
    remapped from [-1, 1] to [0, 255] (Lengyel, eq. 5.3). The weights are the
    exact linear interpolation of :func:`hzval.core.conventions.channel_weights`
    at each texel's centre direction.
    """
    size = CUBE_SIZE if size is None else int(size)
    d = cv.cube_texel_directions(size)
    w = cv.channel_weights(d[..., 0], d[..., 1])
    n = cv.CHANNELS_PER_LAYER
    signed = w[..., :n] - w[..., n:]
    return cv.encode_signed_weight(signed)


# --------------------------------------------------------------------------
# The whole bake
# --------------------------------------------------------------------------

def estimate_bytes(rows: int, cols: int, params: BakeParams) -> int:
    """Peak memory in bytes that baking a ``rows x cols`` map needs (an estimate).

    The exact method pads nothing; its sweep scratch (8 bytes per sweep
    position, at most 2 per texel, reused across channels) is less than the
    seed's ten kernel outputs, so the seed's figure per texel bounds it.
    """
    pad = params.radius - 1 if params.method == "seed" else 0
    per_texel = BAKE_BYTES_PER_TEXEL + BAKE_BYTES_PER_TEXEL_PER_EXTRA_DIRECTION * (params.directions - cv.CHANNEL_COUNT)
    return per_texel * (rows + 2 * pad) * (cols + 2 * pad)


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


#: What each method's horizon and ambient maps are, for ``bake.json``.
METHOD_NOTES: dict[str, str] = {
    "seed": "seed (Lengyel): max tan over neighbours with r < radius in `angles` bins; "
            "each channel the mean sine of its angles/directions + 1 nearest bins; ambient over the bins",
    "exact": "exact: horizon toward each channel's azimuth with unlimited radius (wrap: one period "
             "along the line, which is exact; open: to the edge), by line sweeps with a convex-hull "
             "stack (Timonen and Westerholm 2010); radius and angles unused (null); ambient over "
             "the 8 channel directions",
}


#: What a bake can hold (:attr:`Bake.contents`): the normal map alone, or with the horizon map and the
#: ambient maps derived from it. Techniques declare which they read
#: (:meth:`hzval.techniques.registry.Technique.bake_needs`); a sweep bakes what its techniques need.
CONTENTS: tuple[str, ...] = ("normal", "horizon_map", "ambient")


def needs_horizon(needs) -> bool:
    """Whether bake needs ``needs`` (names of :data:`CONTENTS`, ``"height"`` aside) call for the horizon
    bake: the horizon map, and the ambient maps, which are made from its sines."""
    return bool({"horizon_map", "ambient"} & set(needs))


def bake(height: np.ndarray, params: BakeParams = BakeParams(), *, horizon: bool = True) -> Bake:
    """Bake a normalised height map ``H[row, col]`` into the technique's textures; ``horizon=False``:
    the normal map alone (:func:`normals_only`), without the horizon bake's cost."""
    from hzval.core import backend

    params.validate()
    if not horizon:
        t0 = time.perf_counter()
        only = normals_only(height, params.depth, params.boundary)
        return dataclasses.replace(only, params=params, timings={"normal_s": time.perf_counter() - t0})
    backend.variant()
    timings = {}
    t0 = time.perf_counter()
    h = cv.heights_in_texels(height, params.depth)
    normal = normal_map(h, params.boundary)
    t1 = time.perf_counter()
    timings["normal_s"] = t1 - t0
    if params.method == "exact":
        horizon, mean_cos, mean_cos2 = exact_horizon_map(h, params.boundary)
    else:
        horizon, mean_cos, mean_cos2 = horizon_map(h, params.radius, params.angles, params.boundary,
                                                   directions=params.directions)
    timings["horizon_s"] = time.perf_counter() - t1
    return Bake(params, horizon, normal, mean_cos, mean_cos2, timings)


def write_bake(result: Bake, out: str | Path, *, input_info: dict) -> list[Path]:
    """Write a bake's files into ``out`` (docs/ARCHITECTURE.md, ``hzval bake``), all or nothing.

    ``input_info`` describes the input (path, digest, source, shape) and goes
    into ``bake.json`` with the parameters, versions and timings. The
    horizon map goes into ``horizon0`` .. ``horizon{D/4 - 1}`` (``.exr`` and
    ``.png``), channels ``4 l .. 4 l + 3`` in layer ``l``; the weight cube
    map only for 8 directions (it holds Lengyel's 8 channel weights).
    """
    from hzval.core import backend
    from hzval.io import files

    t0 = time.perf_counter()
    layers = result.layers if result.horizon is not None else ()
    # the weight cube map holds Lengyel's 8 channel weights (2 RGBA layers):
    # a 16-direction map has no GPU cube path (hzval.techniques.horizon), so none is written
    full = result.horizon is not None
    cube = weight_cube() if full and result.directions == cv.CHANNEL_COUNT else None
    layers = layers if full else ()

    # Writing dominated a 2048x2048 bake: zlib runs at ~35 MB/s here, and
    # ZIP shrinks float32 horizon data by 8% and 8-bit layers by 12%. So bake
    # outputs are stored uncompressed (write time 2.8 s -> ~1.2 s), and the
    # files are written on a thread per core: the encoders release the GIL
    # (1.2 s -> 0.7 s at 2048 on 2 cores).
    jobs = []

    def exr(name, channels):
        jobs.append(lambda: files.write_exr(stage.path(name), channels, atomic=False, compression="none"))

    def png(name, make, *args):
        jobs.append(lambda: files.write_png(stage.path(name), make(*args), atomic=False, compress_level=0))

    with files.Staging(out) as stage:
        for i, layer in enumerate(layers):
            exr(f"horizon{i}.exr", {"RGBA": layer})
            png(f"horizon{i}.png", files.unit_to_u8, layer)
        exr("normal.exr", {"RGB": result.normal})
        png("normal.png", lambda n: files.unit_to_u8(0.5 + 0.5 * n), result.normal)
        if full:
            exr("ambient.exr", {"mean_cos": result.mean_cos, "mean_cos2": result.mean_cos2})
        if cube is not None:
            for i, face in enumerate(cv.CUBE_FACES):
                png(f"cube/{face}.png", np.asarray, cube[i])
        files.run_writers(jobs)
        timings = dict(result.timings, write_s=time.perf_counter() - t0)
        digests = {p.relative_to(stage.dir).as_posix(): files.file_digest(p)
                   for p in sorted(stage.dir.rglob("*")) if p.is_file()}
        files.write_json(stage.path("bake.json"), {
            "input": input_info,
            "contents": list(result.contents),
            "parameters": result.params.record() if full else _normal_record(result.params),
            **({"method": METHOD_NOTES[result.params.method]} if full else {}),
            "outputs": _output_notes(result.directions, full),
            "conventions": "docs/ARCHITECTURE.md: +x right, +y up the image, azimuth counterclockwise from +x; "
                           "heights in texel units are H * depth * cols",
            "timings_s": {k: round(v, 4) for k, v in timings.items()},
            "versions": backend.versions(),
            "files": digests,           # what cached_bake checks before it trusts the cache
        }, atomic=False)
        written = stage.commit()
    # a folder that held a bake with another number of directions keeps no
    # files of it that this bake.json does not describe (extra layers, a cube)
    stale = [f"horizon{i}.{ext}" for i in range(len(layers), cv.layer_count(max(cv.DIRECTION_COUNTS)))
             for ext in ("exr", "png")] + ([] if full else ["ambient.exr"])
    if cube is None:
        stale += [f"cube/{face}.png" for face in cv.CUBE_FACES]
    for name in stale:
        (Path(out) / name).unlink(missing_ok=True)
    if cube is None and (Path(out) / "cube").is_dir() and not any((Path(out) / "cube").iterdir()):
        (Path(out) / "cube").rmdir()
    return written


def _normal_record(params: BakeParams) -> dict:
    """``bake.json``'s parameters of a bake of the normal map alone: the horizon bake's are not its."""
    return {"depth": params.depth, "boundary": params.boundary}


def _output_notes(directions: int, full: bool = True) -> dict:
    """``bake.json``'s description of the files of a ``directions``-channel bake (``full``: with the
    horizon and ambient maps; else the normal map alone)."""
    n = cv.CHANNELS_PER_LAYER
    notes = {}
    if not full:
        return {"normal": "tangent-space unit normal (PNG: 0.5 + 0.5 n)"}
    for i in range(cv.layer_count(directions)):
        az = ", ".join(f"{cv.channel_azimuth_deg(c, directions):g}" for c in range(n * i, n * i + n))
        notes[f"horizon{i}"] = (f"channels {n * i}-{n * i + n - 1} (azimuth {az} deg) as RGBA"
                                + (": sine of the horizon angle" if i == 0 else ""))
    notes["normal"] = "tangent-space unit normal (PNG: 0.5 + 0.5 n)"
    notes["ambient"] = "mean_cos (Lengyel) and mean_cos2 (cosine-weighted unoccluded fraction)"
    if directions == cv.CHANNEL_COUNT:
        notes["cube"] = (f"channel weights, {CUBE_SIZE}x{CUBE_SIZE} per face, OpenGL face order, "
                         "8-bit (w + 1) * 127.5")
    else:
        notes["cube"] = (f"not written: the weight cube map holds {cv.CHANNEL_COUNT} channel weights; "
                         f"{directions} directions use the analytic weights")
    return notes


def read_bake(folder: str | Path) -> Bake:
    """Read a bake written by :func:`write_bake` back from its EXR files (exact float32).

    The number of horizon layers follows the recorded ``directions`` (8,
    i.e. ``horizon0``-``horizon1``, when ``bake.json`` predates it)."""
    import json

    from hzval.io import files

    folder = Path(folder)
    record = json.loads((folder / "bake.json").read_text())
    params = BakeParams.from_record(BakeParams.normalise_record(record["parameters"]))
    if "horizon_map" not in record.get("contents", CONTENTS):
        n = files.read_exr(folder / "normal.exr")
        return Bake(params, None, np.stack([n[c] for c in "RGB"], axis=-1), None, None,
                    dict(record["timings_s"]))
    layers = [files.read_exr(folder / f"horizon{i}.exr") for i in range(cv.layer_count(params.directions))]
    n, amb = files.read_exr(folder / "normal.exr"), files.read_exr(folder / "ambient.exr")
    horizon = np.stack([layer[c] for layer in layers for c in "RGBA"], axis=-1)
    normal = np.stack([n[c] for c in "RGB"], axis=-1)
    return Bake(params, horizon, normal, amb["mean_cos"], amb["mean_cos2"], dict(record["timings_s"]))


def cached_bake(height: np.ndarray, digest: str, params: BakeParams, folder: str | Path,
                input_info: dict, notices: list[str] | None = None, *, horizon: bool = True,
                write_to: str | Path | None = None) -> tuple[Bake, bool]:
    """Bake into ``folder``, or read the bake already there if it was made from the
    same input (``digest``) with the same parameters, holds what is asked for (``horizon``:
    the horizon and ambient maps, else the normal map alone) and its files are intact.
    Returns ``(bake, cached)``.

    Every file of the cache must still have the SHA-256 that ``bake.json``
    recorded when it was written (:func:`write_bake`): a truncated or
    corrupted file, or a cache from before digests were recorded, is baked
    anew, with one line saying why appended to ``notices``. ``write_to``: where a new bake is
    written (default ``folder``): a sweep stages it, so that a failed run leaves the old bake.
    """
    import json

    from hzval.io import files

    folder = Path(folder)
    try:
        record = json.loads((folder / "bake.json").read_text())
        held = record.get("contents", CONTENTS)
        if horizon:
            same = "horizon_map" in held and BakeParams.normalise_record(record["parameters"]) == params.record()
        else:           # any bake of the same surface holds its normal map
            same = {k: record["parameters"][k] for k in ("depth", "boundary")} == _normal_record(params)
        same = same and record["input"]["digest"] == digest
    except (OSError, ValueError, KeyError, TypeError):
        same = False   # no usable cache: bake anew
    if same:
        damaged = _damaged_file(folder, record.get("files"), files.file_digest)
        if damaged is None:
            return read_bake(folder), True
        if notices is not None:
            notices.append(f"{damaged}: the cached bake is damaged; baked it anew")
    result = bake(height, params, horizon=horizon)
    write_bake(result, folder if write_to is None else write_to, input_info=input_info)
    return result, False


def _damaged_file(folder: Path, digests, digest_of) -> str | None:
    """The first cache file whose digest differs from the record (or is missing); ``None`` if all
    agree. A record without digests names ``bake.json`` itself."""
    if not isinstance(digests, dict) or not digests:
        return str(folder / "bake.json") + " (no file digests)"
    for name, want in digests.items():
        path = folder / name
        try:
            if digest_of(path) != want:
                return str(path)
        except OSError:
            return str(path)
    return None
