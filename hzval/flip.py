"""LDR-FLIP in NumPy float32, NVIDIA's C++ reference step for step, with the reference side reusable.

FLIP (Andersson, Nilsson, Akenine-Moller, Oskarsson, Astrom and Fairchild,
"FLIP: A Difference Evaluator for Alternating Images", Proc. ACM Comput.
Graph. Interact. Tech. (HPG 2020) 3(2), 15) is the per-pixel perceived
difference, in [0, 1], between a reference and a test image flipped back and
forth at ``ppd`` pixels per degree of visual angle. This module follows the
CPU path of NVlabs/flip's ``src/cpp/FLIP.h`` (``LDR_FLIP``:
``setSpatialFilters``, ``setFeatureFilter``, ``calculateSpatialFilterRadius``,
``computeColorDifference``, ``computeFeatureDifferenceAndFinalError`` and the
``color3`` conversions), called as ``flip-evaluator``'s Python wrapper calls it
with ``"LDR", inputsRGB=True`` (``src/nanobindFLIP.cpp``):

1. sRGB-encoded inputs are decoded to linear RGB (``sRGBToLinearRGB``, before
   any clamping), clamped to [0, 1] (``evaluate``'s ``clamp``) and taken to
   YCxCz (``LinearRGBToXYZ``, ``XYZToYCxCz``, D65);
2. colour pipeline: Y and Cx are filtered with one Gaussian each, Cz with the
   sum of two, all separably (NVlabs/flip's ``misc/separatedConvolutions.pdf``:
   the two-Gaussian Cz filter is the sum of two separable passes with
   ``GaussianSqrt`` weights, normalised together); the result goes back to
   linear RGB, is clamped to [0, 1], goes to CIELAB, gets the Hunt adjustment
   (``a, b *= 0.01 L``), and the HyAB distance ``|dL| + |(da, db)|`` raised to
   :data:`QC` is remapped to [0, 1] against ``cmax`` (``computeMaxDistance``,
   green against blue) with :data:`PC` and :data:`PT`;
3. feature pipeline: the luminance ``(Y + 16) / 116`` of the unfiltered YCxCz is
   filtered with the first and second derivatives of a Gaussian of standard
   deviation ``0.5 * W * ppd`` (separably: derivative along one axis, the
   Gaussian along the other); edge and point magnitudes are the lengths of the
   (x, y) responses, and the feature difference is
   ``(max(|edge_r - edge_t|, |point_r - point_t|) / sqrt 2) ** QF``;
4. the error is ``colour_difference ** (1 - feature_difference)``.

Borders are clamped to the edge (FLIP's ``Min(Max(0, x + ix), w - 1)``): the
x-direction passes are ``scipy.ndimage.correlate1d(mode="nearest")``, the
y-direction ones a float32 sum, in FLIP's tap order, of row-shifted slices of
an edge-padded plane (:func:`_correlate_rows`): 24 ms against 85-115 ms for
``correlate1d`` along the first axis (2048 x 2048 float32, 21 taps, one core).
Both are correlations, the filter index running with the image index, as
FLIP's loops have it. Every per-pixel step is float32 with FLIP's constants
and expression order (``powf`` where FLIP has it, ``x / 12.92`` and not
``x * (1 / 12.92)``, NaN clamped to 0 as its ``Max`` macro does); ``correlate1d``
sums in float64 where FLIP sums in float32, and NumPy's ``pow``/``exp`` are
not glibc's, so the values differ from the C++ by float32 rounding. The mean
is FLIP's too: a float32 running sum over the map in row-major order, divided
by the pixel count (``FLIP::evaluate``), which at 2048 x 2048 differs from the
float64 mean of the same map by about 1e-6.

Validated against ``flip-evaluator`` (NVlabs/flip's nanobind build, 1.7) by
``tests/test_flip.py``: the means agree to 4e-6 on noise, gradients,
constant, tiny (1 x 1 to 5 x 40), non-square and shaded-bricks images, and to
1.3e-5 on a hard black-white edge; per pixel, to 5e-6 on all but the renders
(3e-4) and the hard edge (1.5e-3). The larger ones are in flat regions near a
difference, where the two images' filtered colours agree to float32
rounding: FLIP's error there is that rounding (``|dLab| ** 0.7``) raised to
``1 - feature_difference``, in either implementation (summing the x passes in
float32 in FLIP's order too took the hard edge to 4e-7, not the renders, and
cost 1.6x the x passes). ``benchmarks/bench_compare.py`` compares the two at
512-2048 pixels (the README there has its figures).

Images are ``(H, W, 3)`` sRGB-encoded display values, nominally in [0, 1]
(any float dtype; computed in float32); rows are y (row 0 first, as FLIP's
``y``), columns x. Any size works, 1 x 1 included: the filters are wider than
such an image and clamp to its edge, as FLIP's do.

The reference's half of the work (its filtered, Hunt-adjusted Lab and its
edge and point magnitudes) depends on the reference alone: a
:class:`FlipReference` holds it, and :func:`flip_error` compares any number of
test images with it at the cost of the test side only. The work runs on
:func:`hzval.backend.host_pool` in row blocks, one per core (NumPy and SciPy
release the GIL): first each block's colour conversion and x passes, then,
once the planes are edge-padded, each block's y passes and the per-pixel rest,
:data:`CHUNK_ROWS` rows at a time so that a step's planes stay in cache. The
values do not depend on the blocks.
"""

from __future__ import annotations

import functools
import math
import threading
from dataclasses import dataclass

import numpy as np

f32 = np.float32

#: FLIP's constants (``FLIPConstants`` in FLIP.h): the colour-difference exponent ``qc``,
QC = f32(0.7)
#: the fraction ``pc`` of ``cmax`` below which colour differences are compressed,
PC = f32(0.4)
#: the error ``pt`` those differences map to at most,
PT = f32(0.95)
#: the feature filter's width ``w`` in degrees (its standard deviation is ``0.5 w ppd`` pixels),
W = f32(0.082)
#: and the feature-difference exponent ``qf``.
QF = f32(0.5)

#: The contrast sensitivity functions' Gaussians (``GaussianConstants`` in FLIP.h, the paper's
#: Table 1) for Y, Cx and Cz: ``a1 sqrt(pi / b1) exp(-pi^2 x^2 / b1) + a2 sqrt(pi / b2) exp(-pi^2 x^2 / b2)``.
GAUSS_A1 = (f32(1.0), f32(1.0), f32(34.1))
GAUSS_B1 = (f32(0.0047), f32(0.0053), f32(0.04))
GAUSS_A2 = (f32(0.0), f32(0.0), f32(13.5))
GAUSS_B2 = (f32(1.0e-5), f32(1.0e-5), f32(0.025))

#: FLIP's pi (``FLIP::PI``, as a float).
PI = f32(3.14159265358979)

#: FLIP's default viewing condition: 0.7 m from a 3840-pixel, 0.7 m wide monitor
#: (``calculatePPD(0.7, 3840, 0.7)`` = 67.02 pixels per degree).
DEFAULT_PPD = f32(0.7) * (f32(3840.0) / f32(0.7)) * (PI / f32(180.0))

_ILLUMINANT = (f32(0.950428545), f32(1.0), f32(1.088900371))        # DEFAULT_ILLUMINANT (D65)
_INV_ILLUMINANT = (f32(1.052156925), f32(1.0), f32(0.918357670))    # INV_DEFAULT_ILLUMINANT

_RGB_TO_XYZ = ((f32(10135552.0) / f32(24577794.0), f32(8788810.0) / f32(24577794.0), f32(4435075.0) / f32(24577794.0)),
               (f32(2613072.0) / f32(12288897.0), f32(8788810.0) / f32(12288897.0), f32(887015.0) / f32(12288897.0)),
               (f32(1425312.0) / f32(73733382.0), f32(8788810.0) / f32(73733382.0), f32(70074185.0) / f32(73733382.0)))
_XYZ_TO_RGB = ((f32(3.241003275), f32(-1.537398934), f32(-0.498615861)),
               (f32(-0.969224334), f32(1.875930071), f32(0.041554224)),
               (f32(0.055639423), f32(-0.204011202), f32(1.057148933)))

#: Rows per step inside a block: the planes of a step stay in the core's cache.
CHUNK_ROWS = 32

#: Images of at least this many rows run in row blocks on a thread per core.
PARALLEL_MIN_ROWS = 64


# -- FLIP.h's color3 conversions, on planes ------------------------------------------------------

def _clamp(v: np.ndarray) -> np.ndarray:
    """``Min(Max(v, 0), 1)``: NaN becomes 0, as FLIP's macros make it."""
    return np.fmin(np.fmax(v, f32(0.0)), f32(1.0))


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """``color3::sRGBToLinearRGB`` of float32 values."""
    with np.errstate(invalid="ignore"):
        return np.where(c <= f32(0.04045), c / f32(12.92), np.power((c + f32(0.055)) / f32(1.055), f32(2.4)))


def _mat(m, x, y, z):
    return (m[0][0] * x + m[0][1] * y + m[0][2] * z,
            m[1][0] * x + m[1][1] * y + m[1][2] * z,
            m[2][0] * x + m[2][1] * y + m[2][2] * z)


def linear_rgb_to_xyz(r, g, b):
    """``color3::LinearRGBToXYZ`` (D65)."""
    return _mat(_RGB_TO_XYZ, r, g, b)


def xyz_to_linear_rgb(x, y, z):
    """``color3::XYZToLinearRGB`` (D65)."""
    return _mat(_XYZ_TO_RGB, x, y, z)


def xyz_to_ycxcz(x, y, z):
    """``color3::XYZToYCxCz``."""
    x, y, z = x * _INV_ILLUMINANT[0], y * _INV_ILLUMINANT[1], z * _INV_ILLUMINANT[2]
    return f32(116.0) * y - f32(16.0), f32(500.0) * (x - y), f32(200.0) * (y - z)


def ycxcz_to_xyz(yy, cx, cz):
    """``color3::YCxCzToXYZ``."""
    y = (yy + f32(16.0)) / f32(116.0)
    cx, cz = cx / f32(500.0), cz / f32(200.0)
    return (y + cx) * _ILLUMINANT[0], y * _ILLUMINANT[1], (y - cz) * _ILLUMINANT[2]


_DELTA = f32(6.0) / f32(29.0)
_DELTA_CUBE = _DELTA * (_DELTA * _DELTA)
_LAB_FACTOR = f32(1.0) / (f32(3.0) * (_DELTA * _DELTA))
_LAB_TERM = f32(4.0) / f32(29.0)
_THIRD = f32(1.0) / f32(3.0)


def _lab_f(t):
    return np.where(t > _DELTA_CUBE, np.power(t, _THIRD), _LAB_FACTOR * t + _LAB_TERM)


def xyz_to_cielab(x, y, z):
    """``color3::XYZToCIELab`` (D65; ``powf(t, 1.0f / 3.0f)`` as FLIP has it, not ``cbrtf``)."""
    fx, fy, fz = _lab_f(x * _INV_ILLUMINANT[0]), _lab_f(y * _INV_ILLUMINANT[1]), _lab_f(z * _INV_ILLUMINANT[2])
    return f32(116.0) * fy - f32(16.0), f32(500.0) * (fx - fy), f32(200.0) * (fy - fz)


def hunt(luminance, chrominance):
    """``color3::Hunt``: the Hunt effect's adjustment of a chrominance."""
    return f32(0.01) * luminance * chrominance


def hyab(l1, a1, b1, l2, a2, b2):
    """``color3::HyAB``: city-block in L, Euclidean in (a, b)."""
    da, db = a1 - a2, b1 - b2
    return np.abs(l1 - l2) + np.sqrt(da * da + db * db)


def max_distance() -> np.float32:
    """``color3::computeMaxDistance(qc)``: the Hunt-adjusted HyAB of green against blue, to the ``QC``."""
    green = xyz_to_cielab(*linear_rgb_to_xyz(f32(0.0), f32(1.0), f32(0.0)))
    blue = xyz_to_cielab(*linear_rgb_to_xyz(f32(0.0), f32(0.0), f32(1.0)))
    g = (green[0], hunt(green[0], green[1]), hunt(green[0], green[2]))
    b = (blue[0], hunt(blue[0], blue[1]), hunt(blue[0], blue[2]))
    return f32(np.power(f32(hyab(*g, *b)), QC))


# -- the filters -----------------------------------------------------------------------------------

_PI_SQ = PI * PI


def _gaussian(x2, a, b):
    """``Gaussian(x2, a, b)``: the CSF Gaussian in the paper's form."""
    return a * np.sqrt(PI / b) * np.exp(-_PI_SQ * x2 / b)


def _gaussian_sqrt(x2, a, b):
    """``GaussianSqrt``: the square root of a CSF Gaussian's weight, for a separated sum of two."""
    return np.sqrt(a * np.sqrt(PI / b)) * np.exp(-_PI_SQ * x2 / b)


def spatial_filter_radius(ppd: float) -> int:
    """``calculateSpatialFilterRadius``: three standard deviations of the widest CSF Gaussian."""
    widest = max(*GAUSS_B1, *GAUSS_B2)
    return int(math.ceil(f32(3.0) * np.sqrt(widest / (f32(2.0) * _PI_SQ)) * f32(ppd)))


@dataclass(frozen=True)
class Filters:
    """FLIP's 1-D filters at one ``ppd``: spatial ``y``, ``cx``, ``cz1``, ``cz2`` of radius
    ``spatial_radius``; feature ``g``, ``dg``, ``ddg`` of radius ``feature_radius``; and the
    colour remapping's ``cmax`` and ``pccmax``."""

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
        vals = (_gaussian(ix2, GAUSS_A1[0], GAUSS_B1[0]), _gaussian(ix2, GAUSS_A1[1], GAUSS_B1[1]),
                _gaussian_sqrt(ix2, GAUSS_A1[2], GAUSS_B1[2]), _gaussian_sqrt(ix2, GAUSS_A2[2], GAUSS_B2[2]))
        for arr, k, v in zip((y, cx, cz1, cz2), range(4), vals):
            arr[i] = v
            sums[k] = f32(sums[k] + v)          # FLIP's float running sums
    norm_cz = f32(1.0) / np.sqrt(sums[2] * sums[2] + sums[3] * sums[3])
    return (y * (f32(1.0) / sums[0]), cx * (f32(1.0) / sums[1]), cz1 * norm_cz, cz2 * norm_cz)


def _feature_filters(ppd: np.float32):
    """``setFeatureFilter``: a Gaussian (sum 1) and its first and second derivatives (positive
    weights summing to 1, negative ones to -1)."""
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
    """FLIP's filters and colour constants at ``ppd`` pixels per degree (as a float, as
    flip-evaluator takes it)."""
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


# -- convolutions ----------------------------------------------------------------------------------

def _correlate_columns(plane: np.ndarray, weights: np.ndarray, out: np.ndarray) -> None:
    """FLIP's x-direction pass: ``out[y, x] = sum_i w[i] plane[y, clamp(x + i - r)]``."""
    from scipy.ndimage import correlate1d

    correlate1d(plane, weights, axis=1, mode="nearest", output=out)


def _correlate_rows(padded: np.ndarray, weights: np.ndarray, r0: int, r1: int) -> np.ndarray:
    """FLIP's y-direction pass for rows ``r0:r1``: ``sum_i w[i] plane[clamp(y + i - r)]``, from
    ``padded``, the plane with ``r`` copies of its first and last rows above and below it.

    Summed in float32 in FLIP's order (``i`` from 0 to ``2r``), a multiply and an add per tap
    on row-shifted slices: as fast here as pairing the symmetric taps, and closer to the C++.
    """
    n = r1 - r0
    out = padded[r0:r0 + n] * weights[0]
    tmp = np.empty_like(out)
    for i in range(1, len(weights)):
        np.multiply(padded[r0 + i:r0 + i + n], weights[i], out=tmp)
        out += tmp
    return out


def _pad_rows(padded: np.ndarray, r: int) -> None:
    """Fill the ``r`` rows above and below the plane in ``padded`` with its edge rows."""
    padded[:r] = padded[r]
    padded[padded.shape[0] - r:] = padded[padded.shape[0] - r - 1]


# -- the pipeline ----------------------------------------------------------------------------------

def _in_host_pool() -> bool:
    return threading.current_thread().name.startswith("hzval-host")


def _blocks(rows: int) -> list[tuple[int, int]]:
    """Row blocks, one per core (one block for small images or inside a host-pool thread)."""
    from hzval import backend

    n = min(backend.host_cores(), rows // PARALLEL_MIN_ROWS)
    if n < 2 or _in_host_pool():
        return [(0, rows)]
    bounds = np.linspace(0, rows, n + 1).astype(int)
    return list(zip(bounds[:-1].tolist(), bounds[1:].tolist()))


def _run(fn, blocks) -> None:
    from hzval import backend

    if len(blocks) == 1:
        fn(*blocks[0])
        return
    for _ in backend.host_pool(len(blocks)).map(lambda b: fn(*b), blocks):
        pass


def _chunks(r0: int, r1: int):
    for c0 in range(r0, r1, CHUNK_ROWS):
        yield c0, min(r1, c0 + CHUNK_ROWS)


def _check_image(img, name: str) -> np.ndarray:
    a = np.asarray(img)
    if a.ndim != 3 or a.shape[2] != 3:
        raise ValueError(f"the {name} image must be (H, W, 3), got shape {a.shape}")
    if a.shape[0] == 0 or a.shape[1] == 0:
        raise ValueError(f"the {name} image is empty ({a.shape[0]} x {a.shape[1]})")
    return a


class _Side:
    """One image's FLIP quantities: its filtered, Hunt-adjusted Lab (``L``, ``A``, ``B``) and its
    edge and point magnitudes, computed row block by row block."""

    def __init__(self, display: np.ndarray, f: Filters):
        self.f = f
        self.display = display
        h, w = display.shape[:2]
        rs, rf = f.spatial_radius, f.feature_radius
        # x-filtered planes, edge-padded in y for the y passes
        self.sp = np.empty((4, h + 2 * rs, w), f32)      # Y, Cx, Cz (first Gaussian), Cz (second)
        self.ft = np.empty((3, h + 2 * rf, w), f32)      # d/dx, d2/dx2, Gaussian of (Y + 16) / 116

    def filter_x(self, r0: int, r1: int) -> None:
        """Rows ``r0:r1``: to YCxCz and the x-direction passes (FLIP's first loops)."""
        f, rs, rf = self.f, self.f.spatial_radius, self.f.feature_radius
        for c0, c1 in _chunks(r0, r1):
            rgb = np.asarray(self.display[c0:c1], f32).transpose(2, 0, 1)
            r, g, b = (_clamp(srgb_to_linear(c)) for c in rgb)
            yy, cx, cz = xyz_to_ycxcz(*linear_rgb_to_xyz(r, g, b))
            _correlate_columns(yy, f.y, self.sp[0, rs + c0:rs + c1])
            _correlate_columns(cx, f.cx, self.sp[1, rs + c0:rs + c1])
            _correlate_columns(cz, f.cz1, self.sp[2, rs + c0:rs + c1])
            _correlate_columns(cz, f.cz2, self.sp[3, rs + c0:rs + c1])
            yn = yy * (f32(1.0) / f32(116.0)) + f32(16.0) / f32(116.0)    # oneOver116, sixteenOver116
            _correlate_columns(yn, f.dg, self.ft[0, rf + c0:rf + c1])
            _correlate_columns(yn, f.ddg, self.ft[1, rf + c0:rf + c1])
            _correlate_columns(yn, f.g, self.ft[2, rf + c0:rf + c1])

    def pad(self) -> None:
        for p in self.sp:
            _pad_rows(p, self.f.spatial_radius)
        for p in self.ft:
            _pad_rows(p, self.f.feature_radius)

    def finish(self, c0: int, c1: int):
        """Rows ``c0:c1`` of ``(L, A, B, edge, point)``: the y-direction passes and what follows them."""
        f = self.f
        yy = _correlate_rows(self.sp[0], f.y, c0, c1)
        cx = _correlate_rows(self.sp[1], f.cx, c0, c1)
        cz = _correlate_rows(self.sp[2], f.cz1, c0, c1)
        cz += _correlate_rows(self.sp[3], f.cz2, c0, c1)
        r, g, b = (_clamp(c) for c in xyz_to_linear_rgb(*ycxcz_to_xyz(yy, cx, cz)))
        L, a, b = xyz_to_cielab(*linear_rgb_to_xyz(r, g, b))
        A, B = hunt(L, a), hunt(L, b)
        dx = _correlate_rows(self.ft[0], f.g, c0, c1)
        ddx = _correlate_rows(self.ft[1], f.g, c0, c1)
        dy = _correlate_rows(self.ft[2], f.dg, c0, c1)
        ddy = _correlate_rows(self.ft[2], f.ddg, c0, c1)
        edge = np.sqrt(dx * dx + dy * dy)
        point = np.sqrt(ddx * ddx + ddy * ddy)
        return L, A, B, edge, point


class FlipReference:
    """The reference image's half of LDR-FLIP, computed once for any number of test images.

    ``reference_display``: ``(H, W, 3)`` sRGB-encoded display values in [0, 1];
    ``ppd``: pixels per degree (FLIP's default, 67.02, unless given).
    ``lab``: ``(3, H, W)`` float32, its spatially filtered, clamped, Hunt-adjusted
    CIELAB (``L``, ``0.01 L a``, ``0.01 L b``); ``edge``, ``point``: ``(H, W)``
    float32, the magnitudes of its first- and second-derivative feature responses.
    """

    def __init__(self, reference_display: np.ndarray, ppd: float = DEFAULT_PPD):
        disp = _check_image(reference_display, "reference")
        self.filters = f = filters(ppd)
        self.shape = disp.shape[:2]
        h, w = self.shape
        self.lab = np.empty((3, h, w), f32)
        self.edge = np.empty((h, w), f32)
        self.point = np.empty((h, w), f32)
        side = _Side(disp, f)
        blocks = _blocks(h)
        _run(side.filter_x, blocks)
        side.pad()

        def finish(r0, r1):
            for c0, c1 in _chunks(r0, r1):
                L, A, B, self.edge[c0:c1], self.point[c0:c1] = side.finish(c0, c1)
                self.lab[0, c0:c1], self.lab[1, c0:c1], self.lab[2, c0:c1] = L, A, B

        _run(finish, blocks)


def flip_error(ref: FlipReference, test_display: np.ndarray) -> tuple[np.ndarray, float]:
    """LDR-FLIP of ``test_display`` (``(H, W, 3)`` sRGB display values) against ``ref``:
    the error map ``(H, W)`` float32 in [0, 1] and its mean (FLIP's: a float32 running sum
    in row-major order over the pixel count)."""
    disp = _check_image(test_display, "test")
    if disp.shape[:2] != ref.shape:
        raise ValueError(f"reference and test image resolutions differ: {ref.shape[0]} x {ref.shape[1]} "
                         f"against {disp.shape[0]} x {disp.shape[1]}")
    f = ref.filters
    h, w = ref.shape
    err = np.empty((h, w), f32)
    side = _Side(disp, f)
    blocks = _blocks(h)
    _run(side.filter_x, blocks)
    side.pad()
    nf = f32(1.0) / np.sqrt(f32(2.0))
    scale_low = PT / f.pccmax

    def finish(r0, r1):
        for c0, c1 in _chunks(r0, r1):
            L, A, B, edge, point = side.finish(c0, c1)
            cd = np.power(hyab(ref.lab[0, c0:c1], ref.lab[1, c0:c1], ref.lab[2, c0:c1], L, A, B), QC)
            # remap to [0, 1]: [0, pccmax) to [0, pt), the rest to [pt, 1]
            cd = np.where(cd < f.pccmax, cd * scale_low,
                          PT + ((cd - f.pccmax) / (f.cmax - f.pccmax)) * (f32(1.0) - PT))
            fd = np.power(nf * np.maximum(np.abs(ref.edge[c0:c1] - edge), np.abs(ref.point[c0:c1] - point)), QF)
            err[c0:c1] = np.power(cd, f32(1.0) - fd)

    _run(finish, blocks)
    return err, mean_error(err)


def mean_error(err: np.ndarray) -> float:
    """FLIP's mean of an error map: a float32 running sum, row by row, over the pixel count."""
    total = np.cumsum(np.asarray(err, f32).ravel(), dtype=f32)[-1]
    return float(total / f32(err.size))


def flip(reference_display: np.ndarray, test_display: np.ndarray, ppd: float = DEFAULT_PPD
         ) -> tuple[np.ndarray, float]:
    """LDR-FLIP of two display images, the error map ``(H, W)`` and its mean (one reference, one test:
    ``flip_error(FlipReference(reference_display, ppd), test_display)``)."""
    return flip_error(FlipReference(reference_display, ppd), test_display)
