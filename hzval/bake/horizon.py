"""The seed horizon bake (Lengyel, GPU Zen 2, section 5.2; FGED2 ch. 7 ``ConstructHorizonMap``).

Every neighbour with ``0 < i^2 + j^2 < R^2`` that is higher than the centre raises the maximum
``tan^2 = dh^2 / r^2`` of each of the ``angles`` bins that its angular extent ``atan(0.7071 / r)``
covers around its direction ``atan2(j, i)``; ``sin = sqrt(t / (t + 1))`` per bin, and channel ``k``
averages the ``angles / D + 1`` bins centred on azimuth ``360 k / D`` degrees, ``D`` the stored
directions (8 as the seed; 16 takes ``angles`` a multiple of 32). Each channel so covers its own
``360 / D``-degree sector: the 16-direction channels are narrower, not just more.

Heights are in texel units (``H * depth * cols``), and ``(i, j)`` are tangent-space offsets (+y up
the image), so the bins follow hzval's azimuth convention rather than the seed's memory layout.
The offset-to-bins table is the same for every texel and is computed once (:func:`horizon_table`).
The seed's ``& (width - 1)`` wrap is replaced by a padded copy of the map, so any size works, and
``open`` pads with ``-inf``, which never occludes.

The bake is one Dr.Jit kernel. On the LLVM backend each lane is a texel of a padded row and each
neighbour a zero-copy shifted view of the padded map (contiguous vector loads instead of gathers);
on CUDA the same lanes gather from one copy. The unrolled kernel's compile time grows faster than
the offset count, so for large radii :func:`horizon_map` may take a looped kernel that reads the
table as data (:func:`choose_kernel`, a cost model fitted to ``benchmarks/bench_bake_radius.py``;
docs/ARCHITECTURE.md has the measured costs). The two agree bit for bit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hzval.core import conventions as cv
from hzval.core.backend import dr, mi  # Dr.Jit loads at first use, once the LLVM is chosen

__all__ = [
    "TEXEL_HALF_EXTENT",
    "OffsetGroup",
    "horizon_table",
    "KERNELS",
    "UNROLL_MAX_OFFSETS",
    "UNROLL_COMPILE_S",
    "UNROLL_COMPILE_POWER",
    "UNROLL_RUN_NS",
    "LOOP_RUN_NS",
    "choose_kernel",
    "kernel_for",
    "horizon_map",
]

#: Angular half-width factor of a texel seen from distance r: atan(0.7071 / r),
#: the seed's constant for a texel's half diagonal (sqrt(2)/2, rounded).
TEXEL_HALF_EXTENT = np.float32(0.7071)
#: The seed's ``two_pi`` as a float32 constant.
_TWO_PI_F32 = np.float32(6.2831855)


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
    """Return the seed's offset-to-bins table, grouped by the bins each offset covers.

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
    return [
        OffsetGroup(bins, tuple((i, j) for i, j, _ in v), tuple(r for _, _, r in v))
        for bins, v in groups.items()
    ]


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
    """Return the kernel form that :func:`horizon_map` uses by default (``kernel="auto"``).

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
    """Return the kernel form :func:`horizon_map` takes by default for a ``rows x cols`` map.

    It is :func:`choose_kernel` on its offset table and its lanes, the padded rows.
    """
    offsets = sum(len(g.offsets) for g in horizon_table(radius, angles))
    return choose_kernel(offsets, rows * (cols + 2 * (radius - 1)))


def horizon_map(
    h_texels: np.ndarray,
    radius: int = 16,
    angles: int = 32,
    boundary: str = "wrap",
    *,
    kernel: str = "auto",
    directions: int = cv.CHANNEL_COUNT,
    lift: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Seed horizon bake of heights in texel units.

    Returns ``(horizon, mean_cos, mean_cos2)``: the ``(rows, cols, D)`` channel
    sines (``D = directions``, 8 or 16; ``angles`` a multiple of ``2 D``;
    channel ``k`` the mean of the ``angles / D + 1`` bins centred on azimuth
    ``360 k / D`` degrees) and the two ``(rows, cols)`` ambient terms over
    all bins, float32. Runs on the current Mitsuba variant's Dr.Jit backend
    (:func:`hzval.core.backend.variant`). ``lift``: texels each texel's own height is raised by
    before it looks for its horizon (Valve's ``height2ssbump`` lifts its rays' origins by 0.55 texel,
    so that rises lower than that do not occlude); 0 leaves the kernels as they are.

    ``kernel`` chooses how the offset table (:func:`horizon_table`) becomes
    code; both forms compute the same float32 operations on the same values
    and agree bit for bit (``tests/bake/test_horizon.py``):

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
        max_tan = _max_tan_loop(mi.Float(flat), start, lanes, table, angles, shift_of, lift)
    else:
        max_tan = _max_tan_unrolled(flat, start, lanes, table, angles, shift_of, lift)
    channels, mean_cos, mean_cos2 = _channels(max_tan, angles, directions)
    dr.eval(*channels, mean_cos, mean_cos2)

    def image(v) -> np.ndarray:
        return np.asarray(v, dtype=np.float32).reshape(rows, pcols)[:, pad : pad + cols]

    horizon = np.stack([image(c) for c in channels], axis=-1)
    result = horizon, image(mean_cos).copy(), image(mean_cos2).copy()
    del flat  # the views above must not outlive it; they are evaluated by now
    return result


def _max_tan_unrolled(
    flat: np.ndarray, start: int, lanes: int, table, angles: int, shift_of, lift: float = 0.0
) -> list:
    """Return, per bin, the largest ``tan = dh / r`` of the offsets it covers.

    There is one block of code per offset group, neighbours read as zero-copy shifted views on the LLVM
    backend (contiguous loads) and gathered elsewhere. ``flat`` must outlive the kernel's evaluation.
    """
    if dr.backend_v(mi.Float) == dr.JitBackend.LLVM:

        def neighbour(shift: int):
            # zero-copy view: the kernel reads it with contiguous loads
            return mi.Float(flat[start + shift : start + shift + lanes])
    else:
        source = mi.Float(flat)
        lane = dr.arange(mi.Int32, lanes) + start

        def neighbour(shift: int):
            return dr.gather(mi.Float, source, mi.UInt32(lane + shift))

    h0 = neighbour(0) if lift == 0.0 else neighbour(0) + lift
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
    """Return the channels and the ambient terms' means from the bins' largest tangents.

    The result is ``(channels, mean_cos, mean_cos2)``: ``sin = sqrt(t^2 / (t^2 + 1))``, each channel the mean
    of the ``angles / D + 1`` bins centred on it, and the ambient terms' means over all bins.
    """
    cos2 = [dr.rcp(dr.fma(t, t, 1.0)) for t in max_tan]  # 1 / (1 + tan^2)
    sines = [t * dr.sqrt(c) for t, c in zip(max_tan, cos2)]  # sqrt(t^2 / (t^2 + 1))
    half = angles // (2 * directions)  # each channel: 2 half + 1 = angles / D + 1 bins
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


def _max_tan_loop(
    source, start: int, lanes: int, table: list[OffsetGroup], angles: int, shift_of, lift: float = 0.0
) -> list:
    """Return the ``angles`` per-bin maxima of ``tan`` (>= 0) by symbolic Dr.Jit loops over ``table``.

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
    pairs, group_first, group_end, bin_first, bin_end, bins = [], [], [], [], [], []
    for group in table:
        group_first.append(len(pairs))
        pairs += [(inv_r, shift_of(i, j)) for (i, j), inv_r in zip(group.offsets, group.inv_r)]
        group_end.append(len(pairs))
        bin_first.append(len(bins))
        bins += group.bins
        bin_end.append(len(bins))
    pairs_f = mi.Float(np.asarray(pairs, dtype=np.float32).ravel())
    g_first, g_end, b_first, b_end, bin_of = (
        mi.UInt32(np.asarray(a, dtype=np.uint32)) for a in (group_first, group_end, bin_first, bin_end, bins)
    )
    # opaque: the radius and the map's width change these, and must not change the kernel
    lane = dr.arange(mi.Int32, lanes) + dr.opaque(mi.Int32, start)
    h0 = dr.gather(mi.Float, source, mi.UInt32(lane))
    if lift != 0.0:
        h0 = h0 + lift
    n_groups = dr.opaque(mi.UInt32, len(table))

    def group_body(gi, best):
        def offset_body(o, g):
            inv_r, shift = dr.gather(mi.Vector2f, pairs_f, o)  # one 2-float packet
            t = (dr.gather(mi.Float, source, mi.UInt32(lane + mi.Int32(shift))) - h0) * inv_r
            return o + 1, dr.maximum(g, t)

        _, g = dr.while_loop(
            (dr.gather(mi.UInt32, g_first, gi), mi.Float(-np.inf)),
            lambda o, g: o < dr.gather(mi.UInt32, g_end, gi),
            offset_body,
        )

        def bin_body(k, best):
            b = dr.gather(mi.UInt32, bin_of, k)
            best[b] = dr.maximum(best[b], g)
            return k + 1, best

        _, best = dr.while_loop(
            (dr.gather(mi.UInt32, b_first, gi), best),
            lambda k, best: k < dr.gather(mi.UInt32, b_end, gi),
            bin_body,
        )
        return gi + 1, best

    _, best = dr.while_loop(
        (mi.UInt32(0), dr.alloc_local(mi.Float, angles, mi.Float(0.0))),
        lambda gi, best: gi < n_groups,
        group_body,
    )
    return [best[b] for b in range(angles)]
