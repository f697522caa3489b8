"""LDR-FLIP in Dr.Jit float32, NVIDIA's C++ reference step for step, with the reference side reusable.

FLIP (Andersson et al., "FLIP: A Difference Evaluator for Alternating Images", HPG 2020) is the
per-pixel perceived difference, in [0, 1], between a reference and a test image at ``ppd`` pixels
per degree. This module follows the CPU path of NVlabs/flip's ``src/cpp/FLIP.h`` (``LDR_FLIP``),
called as ``flip-evaluator``'s Python wrapper calls it (``"LDR", inputsRGB=True``): the colour
pipeline (YCxCz filtered by the contrast sensitivity Gaussians, CIELAB, Hunt, HyAB) and the feature
pipeline (Gaussian first and second derivatives of the luminance), combined as
``colour_difference ** (1 - feature_difference)``. The per-pixel colour steps are
:mod:`hzval.metrics.flip_colour`'s.

Images are ``(H, W, 3)`` sRGB-encoded display values in [0, 1], rows y, columns x; borders clamp
to the edge; any size works. The reference's half of the work depends on it alone: a
:class:`FlipReference` holds it, and :func:`flip_error` compares test images with it. The kernels,
the blocking of the filter passes, the float32 details and the validation against
``flip-evaluator`` are in docs/flip.md.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from hzval.core import backend
from hzval.core.backend import dr, mi  # Dr.Jit loads at first use, once the LLVM is chosen
from hzval.metrics.flip_colour import (
    DEFAULT_PPD,
    GAUSS_A1,
    GAUSS_A2,
    GAUSS_B1,
    GAUSS_B2,
    PC,
    PI,
    PT,
    QC,
    QF,
    W,
    clamp_unit,
    f32,
    hunt,
    hyab,
    k32,
    linear_rgb_to_xyz,
    max_distance,
    powf,
    srgb_to_linear,
    xyz_to_cielab,
    xyz_to_linear_rgb,
    xyz_to_ycxcz,
    ycxcz_to_xyz,
)

__all__ = [
    "spatial_filter_radius",
    "Filters",
    "filters",
    "FlipReference",
    "flip_error",
    "separable_filter",
    "mean_error",
    "flip",
]


_PI_SQ = PI * PI


def _gaussian(x2, a, b):
    """``Gaussian(x2, a, b)``: the CSF Gaussian in the paper's form."""
    return a * np.sqrt(PI / b) * np.exp(-_PI_SQ * x2 / b)


def _gaussian_sqrt(x2, a, b):
    """``GaussianSqrt``: the square root of a CSF Gaussian's weight, for a separated sum of two."""
    return np.sqrt(a * np.sqrt(PI / b)) * np.exp(-_PI_SQ * x2 / b)


def spatial_filter_radius(ppd: float) -> int:
    """Return the spatial filter radius in pixels, as FLIP's ``calculateSpatialFilterRadius``.

    It is three standard deviations of the widest contrast sensitivity Gaussian.

    Parameters
    ----------
    ppd : float
        Pixels per degree of visual angle.

    Returns
    -------
    int
        The radius, ``ceil(3 sqrt(b_max / (2 pi^2)) ppd)``.
    """
    widest = max(*GAUSS_B1, *GAUSS_B2)
    return int(math.ceil(f32(3.0) * np.sqrt(widest / (f32(2.0) * _PI_SQ)) * f32(ppd)))


@dataclass(frozen=True)
class Filters:
    """FLIP's 1-D filters at one ``ppd``, with the colour remapping's ``cmax`` and ``pccmax``.

    The spatial ones are ``y``, ``cx``, ``cz1``, ``cz2`` of radius ``spatial_radius``; the feature ones ``g``,
    ``dg``, ``ddg`` of radius ``feature_radius``.
    """

    ppd: np.float32
    spatial_radius: int
    y: np.ndarray
    cx: np.ndarray
    cz1: np.ndarray
    cz2: np.ndarray
    feature_radius: int
    g: np.ndarray
    dg: np.ndarray
    ddg: np.ndarray
    cmax: np.float32
    pccmax: np.float32


def _spatial_filters(ppd: np.float32, radius: int):
    """``setSpatialFilters``: Y and Cx normalised each to sum 1, the two Cz halves together."""
    delta_x = f32(1.0) / ppd
    n = 2 * radius + 1
    y, cx, cz1, cz2 = (np.empty(n, f32) for _ in range(4))
    sums = [f32(0.0)] * 4
    for i in range(n):
        ix = f32(i - radius) * delta_x
        ix2 = ix * ix
        vals = (
            _gaussian(ix2, GAUSS_A1[0], GAUSS_B1[0]),
            _gaussian(ix2, GAUSS_A1[1], GAUSS_B1[1]),
            _gaussian_sqrt(ix2, GAUSS_A1[2], GAUSS_B1[2]),
            _gaussian_sqrt(ix2, GAUSS_A2[2], GAUSS_B2[2]),
        )
        for arr, k, v in zip((y, cx, cz1, cz2), range(4), vals):
            arr[i] = v
            sums[k] = f32(sums[k] + v)  # FLIP's float running sums
    norm_cz = f32(1.0) / np.sqrt(sums[2] * sums[2] + sums[3] * sums[3])
    return (y * (f32(1.0) / sums[0]), cx * (f32(1.0) / sums[1]), cz1 * norm_cz, cz2 * norm_cz)


def _feature_filters(ppd: np.float32):
    """Return FLIP's feature filters (``setFeatureFilter``): a Gaussian and its first two derivatives.

    The Gaussian sums to 1; the derivatives' positive weights sum to 1, their negative ones to -1.
    """
    sd = f32(0.5) * W * ppd
    radius = int(math.ceil(f32(3.0) * sd))
    n = 2 * radius + 1
    g, dg, ddg = np.empty(n, f32), np.empty(n, f32), np.empty(n, f32)
    g_sum = dg_pos = dg_neg = ddg_pos = ddg_neg = f32(0.0)
    for i in range(n):
        xx = f32(i - radius)
        gv = f32(np.exp(-(xx * xx) / (f32(2.0) * sd * sd)))
        g_sum = f32(g_sum + gv)
        d = -xx * gv
        if d > 0:
            dg_pos = f32(dg_pos + d)
        else:
            dg_neg = f32(dg_neg - d)
        dd = (xx * xx / (sd * sd) - f32(1.0)) * gv
        if dd > 0:
            ddg_pos = f32(ddg_pos + dd)
        else:
            ddg_neg = f32(ddg_neg - dd)
        g[i], dg[i], ddg[i] = gv, d, dd
    g = g / g_sum
    dg = np.where(dg > 0, dg / dg_pos, dg / dg_neg).astype(f32)
    ddg = np.where(ddg > 0, ddg / ddg_pos, ddg / ddg_neg).astype(f32)
    return radius, g, dg, ddg


@functools.lru_cache(maxsize=8)
def filters(ppd: float = DEFAULT_PPD) -> Filters:
    """FLIP's filters and colour constants at ``ppd`` pixels per degree, cached.

    Parameters
    ----------
    ppd : float
        Pixels per degree, as flip-evaluator takes it (a float); positive.

    Returns
    -------
    Filters
        The spatial and feature filters, read-only, and ``cmax``/``pccmax``.

    Raises
    ------
    ValueError
        For ``ppd <= 0``.
    """
    ppd = f32(ppd)
    if not ppd > 0:
        raise ValueError(f"pixels per degree must be positive, got {ppd}")
    rs = spatial_filter_radius(ppd)
    y, cx, cz1, cz2 = _spatial_filters(ppd, rs)
    rf, g, dg, ddg = _feature_filters(ppd)
    cmax = max_distance()
    for w in (y, cx, cz1, cz2, g, dg, ddg):
        w.setflags(write=False)
    return Filters(ppd, rs, y, cx, cz1, cz2, rf, g, dg, ddg, cmax, PC * cmax)


# -- the pipeline, in Dr.Jit ------------------------------------------------------------------------


#: The pixels one lane of a filter pass computes: eight of a row in the x pass, eight of a column in
#: the y pass. Their taps overlap, so a lane reads the inputs of all eight once (the x pass the
#: ``2q + 1`` packets of eight floats around them, the y pass the ``8 + 2r`` rows they need) instead
#: of ``2r + 1`` per pixel: the same arithmetic in the same order, a fraction of the memory reads.
BLOCK = 8


class _Grid:
    """The index arithmetic of FLIP's two passes over an ``h x w`` image, in blocks of :data:`BLOCK`.

    - **Padded planes** (what the colour conversion writes and the x pass reads): the image with its
      edges repeated, ``pad`` rows above and at least ``pad`` below (up to a whole number of row
      blocks) and ``BLOCK * q`` columns left and right: FLIP's ``Min(Max(0, x + ix), w - 1)``, made
      once instead of per tap. Row-major, ``stride`` floats a row (a multiple of :data:`BLOCK`).
    - **x pass**: lane ``(row, b)`` of ``rows * nb`` reads packets ``b`` to ``b + 2q`` of its padded
      row and computes columns ``BLOCK b + k``, ``k < BLOCK``; its results are stored row-major,
      ``wb = BLOCK nb`` floats a row (one packet store each).
    - **y pass**: lane ``(c, x)`` of ``hc * wb`` reads rows ``BLOCK c + m`` of column ``x`` of those
      results and computes rows ``BLOCK c + k``: one array per ``k`` (the *blocked* layout, which
      :meth:`image` turns back into an ``h x w`` image).

    Pixels past the image's last row or column (to whole blocks) are computed from repeated edges
    and cut off by :meth:`image`. The sizes are opaque, so one compiled kernel serves every size.
    """

    def __init__(self, h: int, w: int, pad: int):
        B = BLOCK
        self.h, self.w, self.pad = h, w, pad
        self.q, self.nb, self.hc = -(-pad // B), -(-w // B), -(-h // B)
        self.rows, self.wb = B * self.hc + 2 * pad, B * self.nb
        self.stride = B * (self.nb + 2 * self.q)

    @staticmethod
    def _quotient(a, n):
        """Return ``a // n`` of non-negative Int32 arrays, as the truncated float64 quotient.

        It is exact (a quotient within ``1 / n`` of the next integer is at least ``2^-32`` from it relatively,
        far above float64's rounding) and a SIMD division, where LLVM turns an integer division by a value
        that is not a constant into one scalar division a lane (``benchmarks/bench_flip.py`` measures the
        difference).
        """
        return mi.Int32(mi.Float64(a) / mi.Float64(n))

    def _opaque(self, n: int):
        # a size as a kernel input, not a literal: one compiled kernel serves every size

        return dr.opaque(mi.Int32, n)

    def source(self):
        """For each element of a padded plane, the index of the image pixel it repeats."""
        j = dr.arange(mi.Int32, self.rows * self.stride)
        S, W, H = self._opaque(self.stride), self._opaque(self.w), self._opaque(self.h)
        row = self._quotient(j, S)
        col = j - row * S
        y = dr.clip(row - self.pad, 0, H - 1)
        return y * W + dr.clip(col - BLOCK * self.q, 0, W - 1)

    def x_window(self, plane) -> list:
        """Return, for each x-pass lane, the ``BLOCK (2q + 1)`` values of its padded row.

        They start at column ``BLOCK (b - q)`` of the image and are read as ``2q + 1`` packet loads.
        """
        lanes = self.rows * self.nb
        lane = dr.arange(mi.Int32, lanes)
        nb = self._opaque(self.nb)
        row = self._quotient(lane, nb)
        first = row * self._opaque(self.nb + 2 * self.q) + (lane - row * nb)  # packets in a padded row
        values = []
        for j in range(2 * self.q + 1):
            packet = dr.gather(mi.ArrayXf, plane, mi.UInt32(first + j), shape=(BLOCK, lanes))
            values.extend(packet[k] for k in range(BLOCK))
        return values

    def x_store(self, outputs: list):
        """Return the x pass's ``BLOCK`` outputs of each lane, stored row-major (``wb`` a row)."""
        lanes = self.rows * self.nb
        target = dr.empty(mi.Float, lanes * BLOCK)  # every element is stored: no fill first
        dr.scatter(target, mi.ArrayXf(*outputs), dr.arange(mi.UInt32, lanes))
        return target

    def y_window(self, plane, first: int, count: int) -> dict:
        """Return, for each y-pass lane, rows ``BLOCK c + m`` of its column of an x-pass result.

        The rows go by ``m`` from ``first`` (padded rows) for ``count`` rows.
        """
        lane = dr.arange(mi.Int32, self.hc * self.wb)
        WB = self._opaque(self.wb)
        c = self._quotient(lane, WB)
        base = c * (BLOCK * WB) + (lane - c * WB)
        rows = range(first, first + count)
        return {m: dr.gather(mi.Float, plane, mi.UInt32(base + m * WB)) for m in rows}

    def image(self, blocked: list) -> np.ndarray:
        """Return an ``h x w`` float32 image of a quantity in the blocked layout (one array per ``k``)."""
        a = np.stack([np.asarray(v, dtype=f32).reshape(self.hc, self.wb) for v in blocked], axis=1)
        return a.reshape(BLOCK * self.hc, self.wb)[: self.h, : self.w]


def _taps(values, weights, first):
    """Return ``sum_i weights[i] values[first + i]``, summed in float32 in FLIP's order.

    ``i`` runs from 0 to ``2r``. It is one output of FLIP's 1-D passes, which are correlations (the filter
    index runs with the image's).
    """
    acc = None
    for i, w in enumerate(weights):
        term = values[first + i] * float(w)
        acc = term if acc is None else acc + term
    return acc


def _x_pass(grid: _Grid, planes, weights) -> list:
    """Return FLIP's x-direction passes, each filter's correlation along the rows.

    One per filter of each ``(plane, filters)`` of ``planes`` and ``weights``, each a row-major array of the
    padded rows (:class:`_Grid`).
    """
    out = []
    for plane, filters_of in zip(planes, weights):
        window = grid.x_window(plane)
        r = (len(filters_of[0]) - 1) // 2
        for w in filters_of:
            out.append(grid.x_store([_taps(window, w, BLOCK * grid.q - r + k) for k in range(BLOCK)]))
    return out


def _y_pass(grid: _Grid, planes, weights) -> list:
    """Return FLIP's y-direction passes over the x-pass results, each filter's correlation along columns.

    One per filter of each ``(plane, filters)``, in the blocked layout (a list of :data:`BLOCK` arrays).
    """
    out = []
    for plane, filters_of in zip(planes, weights):
        r = (len(filters_of[0]) - 1) // 2
        window = grid.y_window(plane, grid.pad - r, BLOCK + 2 * r)
        for w in filters_of:
            out.append([_taps(window, w, grid.pad - r + k) for k in range(BLOCK)])
    return out


def separable_filter(plane: np.ndarray, along_x: np.ndarray, along_y: np.ndarray) -> np.ndarray:
    """One plane through FLIP's two passes, as :class:`FlipReference` filters its planes.

    Parameters
    ----------
    plane : numpy.ndarray
        ``(H, W)`` values, computed in float32.
    along_x, along_y : numpy.ndarray
        Odd-length filters, centred: the correlation along the rows with ``along_x``, then along the
        columns with ``along_y``, edges clamped, each output summed in float32 tap by tap.

    Returns
    -------
    numpy.ndarray
        ``(H, W)`` float32.
    """
    backend.variant()
    a = np.ascontiguousarray(plane, dtype=f32)
    if a.ndim != 2 or a.size == 0 or len(along_x) % 2 == 0 or len(along_y) % 2 == 0:
        raise ValueError(f"need a non-empty (H, W) plane and odd-length filters, got {a.shape}")
    grid = _Grid(*a.shape, (max(len(along_x), len(along_y)) - 1) // 2)
    padded = dr.gather(mi.Float, mi.Float(a.ravel()), mi.UInt32(grid.source()))
    (x,) = _x_pass(grid, (padded,), ((along_x,),))
    dr.eval(x)
    (y,) = _y_pass(grid, (x,), ((along_y,),))
    dr.eval(y)
    return grid.image(y)


def _flat_image(img: np.ndarray):
    """Return an ``(H, W, 3)`` image as one flat Dr.Jit array, as FLIP's Python wrapper takes it.

    A float64 image stays as it is (Dr.Jit maps NumPy memory without a copy; the kernel casts it to float32 as
    NumPy casts, to nearest); any other becomes float32.
    """
    if img.dtype == np.float64 and img.flags.c_contiguous:
        return mi.Float64(img.ravel())
    return mi.Float(np.ascontiguousarray(img, dtype=f32).ravel())


def _image_planes(flat, grid: _Grid, grey: bool):
    """Gather R, G and B of a :func:`_flat_image` as float32 Dr.Jit arrays over the padded planes.

    The padded planes are :meth:`_Grid.source`'s. They are gathered because a gather, unlike a strided load,
    compiles one kernel for every alignment. ``grey``: R, G and B are bitwise equal, and R is gathered for all
    three, so that what is computed from them is computed once (Dr.Jit merges equal expressions of equal
    variables) and is the same bit for bit.
    """
    i = mi.UInt32(grid.source() * 3)
    kind = mi.Float64 if isinstance(flat, mi.Float64) else mi.Float
    planes = tuple(mi.Float(dr.gather(kind, flat, i + c)) for c in range(1 if grey else 3))
    return planes * 3 if grey else planes


def _side(flat, h: int, w: int, ppd: float, grey: bool) -> tuple:
    """Evaluate one image's FLIP quantities: filtered, Hunt-adjusted Lab and edge and point magnitudes.

    The Lab is ``L``, ``A``, ``B``, and each quantity is in the blocked layout of :class:`_Grid` (a list of
    :data:`BLOCK` arrays). ``flat``: :func:`_flat_image` of the ``h x w`` image; ``grey``: whether its
    channels are bitwise equal (:func:`_image_planes`). Three kernels: to YCxCz, the x-direction passes, and
    the y-direction passes with all that follows them.
    """
    f = filters(ppd)
    g = _Grid(h, w, max(f.spatial_radius, f.feature_radius))
    r, gr, b = (clamp_unit(srgb_to_linear(c)) for c in _image_planes(flat, g, grey))
    yy, cx, cz = xyz_to_ycxcz(*linear_rgb_to_xyz(r, gr, b))
    yn = yy * k32(f32(1.0) / f32(116.0)) + k32(f32(16.0) / f32(116.0))  # oneOver116, sixteenOver116
    dr.eval(yy, cx, cz, yn)
    # Y, Cx, Cz (first Gaussian), Cz (second); d/dx, d2/dx2 and the Gaussian of (Y + 16) / 116
    x_pass = _x_pass(g, (yy, cx, cz, yn), ((f.y,), (f.cx,), (f.cz1, f.cz2), (f.dg, f.ddg, f.g)))
    dr.eval(x_pass)
    sp0, sp1, sp2, sp3, ft0, ft1, ft2 = x_pass
    # the y-direction passes, and what follows them, for each of a lane's pixels
    yy, cx, cz1, cz2 = _y_pass(g, (sp0, sp1, sp2, sp3), ((f.y,), (f.cx,), (f.cz1,), (f.cz2,)))
    dx, ddx, dy, ddy = _y_pass(g, (ft0, ft1, ft2), ((f.g,), (f.g,), (f.dg, f.ddg)))
    out = ([], [], [], [], [])
    for k in range(BLOCK):
        r, gr, b = (clamp_unit(c) for c in xyz_to_linear_rgb(*ycxcz_to_xyz(yy[k], cx[k], cz1[k] + cz2[k])))
        L, a, b = xyz_to_cielab(*linear_rgb_to_xyz(r, gr, b))
        for quantity, v in zip(
            out,
            (
                L,
                hunt(L, a),
                hunt(L, b),
                dr.sqrt(dx[k] * dx[k] + dy[k] * dy[k]),
                dr.sqrt(ddx[k] * ddx[k] + ddy[k] * ddy[k]),
            ),
        ):
            quantity.append(v)
    # evaluated apart from the error: in one kernel with it, CUDA's compiler may round them
    # otherwise (FLIP of an image against itself was 6e-7 there, not 0)
    dr.eval(out)
    return out


def _error(ref: tuple, flat, h: int, w: int, ppd: float, grey: bool) -> list:
    """Return the per-pixel FLIP of ``flat`` against a reference's :func:`_side`, evaluated.

    ``flat`` is a :func:`_flat_image` and ``grey`` as :func:`_side` takes it. The result is in the blocked
    layout of :class:`_Grid`.
    """
    f = filters(ppd)
    t = _side(flat, h, w, ppd, grey)
    # remap to [0, 1]: [0, pccmax) to [0, pt), the rest to [pt, 1]
    pccmax, above = k32(f.pccmax), k32(f.cmax - f.pccmax)
    nf = k32(f32(1.0) / np.sqrt(f32(2.0)))
    err = []
    for k in range(BLOCK):
        (rl, ra, rb, re, rp), (tl, ta, tb, te, tp) = ([q[k] for q in side] for side in (ref, t))
        cd = powf(hyab(rl, ra, rb, tl, ta, tb), k32(QC))
        cd = dr.select(
            cd < pccmax,
            cd * k32(PT / f.pccmax),
            k32(PT) + ((cd - pccmax) / above) * k32(f32(1.0) - PT),
        )
        fd = powf(nf * dr.maximum(dr.abs(re - te), dr.abs(rp - tp)), k32(QF))
        err.append(powf(cd, 1.0 - fd))
    dr.eval(err)
    return err


#: The recordings :func:`_frozen` keeps, the most recently used first: one for each image shape,
#: pixels per degree, input type and greyness, and on the LLVM backend for each alignment of the NumPy memory
#: it maps (64-byte aligned or not: a large image is, a small one may be either).
FROZEN_SHAPES = 8


@functools.cache
def _frozen(fn):
    """Return ``fn`` (:func:`_side` or :func:`_error`) frozen with ``drjit.freeze`` (Dr.Jit 1.2 or later).

    Its kernels are recorded at the first call for a shape and launched again at the next ones without tracing
    the Python that made them, which at 512 x 512 was a third of FLIP's time. The sizes are Python arguments,
    so that each shape gets its own recording (a recording holds the sizes it was made with). Dr.Jit's warning
    after ten recordings is for a loop that records on every call; a process that scores many shapes records
    once for each, as it should.
    """
    return dr.freeze(fn, limit=FROZEN_SHAPES, warn_after=2**30)


def _check_image(img, name: str) -> np.ndarray:
    a = np.asarray(img)
    if a.ndim != 3 or a.shape[2] != 3:
        raise ValueError(f"the {name} image must be (H, W, 3), got shape {a.shape}")
    if a.shape[0] == 0 or a.shape[1] == 0:
        raise ValueError(f"the {name} image is empty ({a.shape[0]} x {a.shape[1]})")
    return a


class FlipReference:
    """The reference image's half of LDR-FLIP, computed once for any number of test images.

    ``reference_display``: ``(H, W, 3)`` sRGB-encoded display values in [0, 1];
    ``ppd``: pixels per degree (FLIP's default, 67.02, unless given); ``grey``: its channels are
    bitwise equal, as the caller has checked (:func:`flip_error`).
    ``L``, ``A``, ``B``: its spatially filtered, clamped, Hunt-adjusted CIELAB
    (``L``, ``0.01 L a``, ``0.01 L b``); ``edge``, ``point``: the magnitudes of its
    first- and second-derivative feature responses; each float32 Dr.Jit arrays of
    the current variant in the blocked layout of the passes (``grid``, a ``_Grid``: one
    array per row of a block; ``grid.image`` makes one an image).
    """

    def __init__(self, reference_display: np.ndarray, ppd: float = DEFAULT_PPD, *, grey: bool = False):

        backend.variant()
        disp = _check_image(reference_display, "reference")
        self.filters, self.ppd = filters(ppd), float(f32(ppd))
        self.shape = h, w = disp.shape[:2]
        f = self.filters
        self.grid = _Grid(h, w, max(f.spatial_radius, f.feature_radius))
        flat = _flat_image(disp)
        self.L, self.A, self.B, self.edge, self.point = _frozen(_side)(flat, h, w, self.ppd, bool(grey))


def flip_error(
    ref: FlipReference, test_display: np.ndarray, *, grey: bool = False
) -> tuple[np.ndarray, float]:
    """LDR-FLIP (Andersson et al. 2020) of a test image against a kept reference.

    The colour difference (HyAB of the filtered, Hunt-adjusted Lab values, to the power ``QC`` and
    remapped to [0, 1]) raised to ``1 - feature difference`` (edges and points, to ``QF``).

    Parameters
    ----------
    ref : FlipReference
        The reference's filtered values.
    test_display : numpy.ndarray
        ``(H, W, 3)`` sRGB display values in [0, 1].
    grey : bool, optional
        Its channels are bitwise equal, as the caller has checked (:func:`hzval.io.codecs.is_grey`):
        its colour is then converted once, not three times, the same map either way.

    Returns
    -------
    error : numpy.ndarray
        ``(H, W)`` float32 in [0, 1].
    mean : float
        :func:`mean_error` of it.

    Raises
    ------
    ValueError
        For images of different sizes.
    """
    disp = _check_image(test_display, "test")
    if disp.shape[:2] != ref.shape:
        raise ValueError(
            f"reference and test image resolutions differ: {ref.shape[0]} x {ref.shape[1]} "
            f"against {disp.shape[0]} x {disp.shape[1]}"
        )
    quantities = (ref.L, ref.A, ref.B, ref.edge, ref.point)
    err = ref.grid.image(_frozen(_error)(quantities, _flat_image(disp), *ref.shape, ref.ppd, bool(grey)))
    return err, mean_error(err)


def mean_error(err: np.ndarray) -> float:
    """FLIP's mean of an error map: a float32 running sum, row by row, over the pixel count.

    Parameters
    ----------
    err : numpy.ndarray
        An error map.

    Returns
    -------
    float
        The mean, as flip-evaluator computes it (float32 rounding included).
    """
    total = np.cumsum(np.asarray(err, f32).ravel(), dtype=f32)[-1]
    return float(total / f32(err.size))


def flip(
    reference_display: np.ndarray, test_display: np.ndarray, ppd: float = DEFAULT_PPD
) -> tuple[np.ndarray, float]:
    """LDR-FLIP of two display images: ``flip_error(FlipReference(reference_display, ppd), test_display)``.

    Parameters
    ----------
    reference_display, test_display : numpy.ndarray
        ``(H, W, 3)`` sRGB display values in [0, 1].
    ppd : float
        Pixels per degree (default :data:`DEFAULT_PPD`).

    Returns
    -------
    error : numpy.ndarray
        ``(H, W)`` float32 in [0, 1].
    mean : float
        Its mean.
    """
    return flip_error(FlipReference(reference_display, ppd), test_display)
