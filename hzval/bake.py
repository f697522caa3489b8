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

A second method, ``BakeParams(method="exact")`` (:func:`exact_horizon_map`),
computes the exact horizon of every texel toward each of the 8 channel
directions with unlimited radius, by line sweeps with a convex-hull stack
(Timonen and Westerholm 2010, "Scalable Height Field Self-Shadowing"), O(n)
per line. It ignores ``radius`` and ``angles``; ``bake.json`` records them as
``null`` for it.
"""

from __future__ import annotations

import math
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
    ``method``: ``seed`` (the seed algorithm above, :func:`horizon_map`) or
    ``exact`` (exact horizons toward the 8 channel directions with unlimited
    radius, :func:`exact_horizon_map`; ``radius`` and ``angles`` are ignored
    and not validated, and :meth:`record` writes them as ``None``).
    """

    depth: float = 0.05
    radius: int = 16
    angles: int = 32
    boundary: str = "wrap"
    method: str = "seed"

    def validate(self) -> "BakeParams":
        if not np.isfinite(self.depth) or self.depth <= 0:
            raise InputError("--depth", f"must be a positive number of image widths, got {self.depth}")
        if self.method not in METHODS:
            raise InputError("--method", f"unknown bake method {self.method!r}; available: {', '.join(METHODS)}")
        if self.method == "seed":
            if self.radius is None or int(self.radius) != self.radius or self.radius < 2:
                raise InputError("--radius", f"must be an integer of at least 2 texels, got {self.radius}")
            if self.angles is None or int(self.angles) != self.angles or self.angles < 16 or self.angles % 16:
                raise InputError("--angles", f"must be a multiple of 16 (16, 32, 48, 64, ...), got {self.angles}")
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
        """The inverse of :meth:`record` (``None`` entries take the defaults)."""
        return cls(**{k: v for k, v in record.items() if v is not None})


#: Horizon bake methods (``BakeParams.method``, ``--method``).
METHODS: tuple[str, ...] = ("seed", "exact")


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
        dh = hc - hk
        d = ((cand - k) * lines.step).astype(np.float32)
        with np.errstate(over="ignore", invalid="ignore"):  # lanes without `has` read unset scratch
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
    """Peak memory in bytes that baking a ``rows x cols`` map needs (an estimate).

    The exact method pads nothing; its sweep scratch (8 bytes per sweep
    position, at most 2 per texel, reused across channels) is less than the
    seed's ten kernel outputs, so the seed's figure per texel bounds it.
    """
    pad = params.radius - 1 if params.method == "seed" else 0
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


#: What each method's horizon and ambient maps are, for ``bake.json``.
METHOD_NOTES: dict[str, str] = {
    "seed": "seed (Lengyel): max tan over neighbours with r < radius in `angles` bins; "
            "each channel the mean sine of its angles/8 + 1 nearest bins; ambient over the bins",
    "exact": "exact: horizon toward each channel's azimuth with unlimited radius (wrap: one period "
             "along the line, which is exact; open: to the edge), by line sweeps with a convex-hull "
             "stack (Timonen and Westerholm 2010); radius and angles unused (null); ambient over "
             "the 8 channel directions",
}


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
    if params.method == "exact":
        horizon, mean_cos, mean_cos2 = exact_horizon_map(h, params.boundary)
    else:
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
            "parameters": result.params.record(),
            "method": METHOD_NOTES[result.params.method],
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
    return Bake(BakeParams.from_record(record["parameters"]), horizon, normal, amb["mean_cos"], amb["mean_cos2"],
                dict(record["timings_s"]))


def cached_bake(height: np.ndarray, digest: str, params: BakeParams, folder: str | Path,
                input_info: dict) -> tuple[Bake, bool]:
    """Bake into ``folder``, or read the bake already there if it was made from the
    same input (``digest``) with the same parameters. Returns ``(bake, cached)``."""
    import json

    folder = Path(folder)
    try:
        record = json.loads((folder / "bake.json").read_text())
        if record["input"]["digest"] == digest and record["parameters"] == params.record():
            return read_bake(folder), True
    except (OSError, ValueError, KeyError, TypeError):
        pass   # no usable cache: bake anew
    result = bake(height, params)
    write_bake(result, folder, input_info=input_info)
    return result, False
