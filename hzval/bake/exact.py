"""The exact horizon map: line sweeps with a convex-hull stack.

The exact horizon of every texel toward each of the 8 channel directions, with unlimited radius,
by sweeping each line of texel centres with a convex-hull stack (Timonen and Westerholm 2010,
"Scalable Height Field Self-Shadowing"), O(n) per line. ``BakeParams(method="exact")`` bakes with
it; it has no radius and no angular bins. The ambient terms are the seed's averages over the
directions (:func:`ambient_from_sines`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hzval.core import conventions as cv
from hzval.core.backend import dr  # Dr.Jit loads at first use, once the LLVM is chosen

__all__ = ["CHANNEL_STEPS", "SweepLines", "sweep_lines", "ambient_from_sines", "exact_horizon_map"]

#: Tangent-space steps ``(dx, dy)`` from a texel centre to the next texel
#: centre toward each channel's azimuth ``45 k`` degrees (+y up the image).
CHANNEL_STEPS: tuple[tuple[int, int], ...] = (
    (1, 0),
    (1, 1),
    (0, 1),
    (-1, 1),
    (-1, 0),
    (-1, -1),
    (0, -1),
    (1, -1),
)


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
    """Return the lines of channel ``channel`` (0..7) on a ``rows x cols`` map (:class:`SweepLines`)."""
    dx, dy = CHANNEL_STEPS[channel]
    drow, dcol = cv.tangent_to_pixel_offset(dx, dy)
    if boundary == "wrap":
        if drow == 0:  # along the rows
            r0, c0, period = np.arange(rows), np.zeros(rows, np.int64), cols
        elif dcol == 0:  # along the columns
            r0, c0, period = np.zeros(cols, np.int64), np.arange(cols), rows
        else:  # diagonal: texels (r0 + i drow, i dcol), r0 < gcd, are distinct cycles
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
    return SweepLines(
        drow,
        dcol,
        math.hypot(dx, dy),
        r0,
        c0,
        (r0 + (count - 1) * drow) % rows,
        (c0 + (count - 1) * dcol) % cols,
        length,
        count,
        offset,
    )


def _sweep_numpy(h: np.ndarray, lines: SweepLines) -> np.ndarray:
    """One channel's exact horizon sines, ``(rows * cols,)`` float32, in NumPy.

    The same sweep as :func:`_sweep_drjit`, vectorised across lines: the
    Python loop runs over positions, and the stack walk is masked to the lines
    that still pop. Used where Dr.Jit's LLVM backend is missing; far slower than the kernel
    (``benchmarks/bench_horizon_methods.py`` measures both).
    """
    rows, cols = h.shape
    flat = h.ravel()
    count, length = lines.count, lines.length
    n_lines, most = len(count), int(count.max())
    nxt_of = np.empty((n_lines, most), np.int32)  # the stack, as links: position -> next hull vertex
    h_at = np.empty((n_lines, most), np.float32)  # height at each position
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


def _sweep_drjit(
    h, shape: tuple[int, int], lines: SweepLines, channel: int, out, nxt_np: np.ndarray, h_np: np.ndarray
) -> None:
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
    # the LLVM backend's types: this kernel maps NumPy memory, which only LLVM can
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
        # whether Dr.Jit loads at all decides the path
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


def exact_horizon_map(
    h_texels: np.ndarray, boundary: str = "wrap", *, engine: str = "auto"
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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
    """Compute :func:`exact_horizon_map` on Dr.Jit's LLVM backend.

    It runs one sweep kernel per channel into one interleaved buffer, then one kernel for the ambient terms
    (:func:`ambient_from_sines`'s formulas; 10x faster than NumPy's strided passes over the 8 channels at 2048
    x 2048).
    """
    # the LLVM backend's types: this kernel maps NumPy memory, which only LLVM can
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
            raise RuntimeError(
                "exact horizon bake: Dr.Jit did not write into the NumPy scratch buffer "
                "(zero-copy mapping unavailable); use engine='numpy'"
            )
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
    return (
        horizon,
        np.asarray(mean_cos.numpy(), np.float32).reshape(rows, cols),
        np.asarray(mean_cos2.numpy(), np.float32).reshape(rows, cols),
    )
