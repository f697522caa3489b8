"""Comparing a technique's frame with the truth (docs/ARCHITECTURE.md, "Metrics").

Visibility, on the one-channel layers in [0, 1]:

* ``visibility_mae``: mean ``|F - V|`` over pixels;
* ``leak_fraction``: pixels the technique lights (``F >= 0.5``) that are in
  shadow (``V < 0.5``);
* ``false_shadow_fraction``: pixels it shadows (``F < 0.5``) that are lit
  (``V >= 0.5``);
* ``reflection_mae`` (with ``reflection_occlusion``): mean ``|o - R|``, the
  Toolbag fade ``o`` of :mod:`hzval.techniques.horizon` against the truth's unoccluded
  fraction ``R`` of the glossy lobe about the mirror direction
  (:mod:`hzval.truth.plane`).

Images: ``rmse`` and ``psnr_db`` on linear values (peak 1: the largest
radiance the declared effects can produce, :func:`hzval.core.shading.exposure`); FLIP
(NVIDIA's LDR-FLIP, :mod:`hzval.metrics.flip`, validated against ``flip-evaluator``;
67 pixels per degree) and CIEDE2000 (a Dr.Jit float64 kernel, validated
against colour-science's ``delta_E(method="CIE 2000")``) on display values,
i.e. exposed, clipped to [0, 1] and sRGB-encoded. The truth's half of both
(FLIP's filtered reference, its CIELAB) is computed once per frame
(:class:`Reference`) and reused for every technique compared with it.

``flip_evaluator_flip`` and ``delta_e2000_colour`` run the same metrics through flip-evaluator
and colour-science: the references the tests and ``benchmarks/bench_compare.py`` hold the
kernels to (FLIP means within 2e-7, CIEDE2000 within 1e-12; benchmarks/README.md has the
timings). Display values, the MSE and the visibility metrics are Dr.Jit kernels too, so that an
image crosses into NumPy only for the files.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import flip_evaluator
import numpy as np

from hzval.core import backend, srgb
from hzval.core.backend import dr, mi  # Dr.Jit loads at first use, once the LLVM is chosen
from hzval.core.errors import HzvalError
from hzval.io import codecs
from hzval.metrics import flip as hzflip
from hzval.metrics.flip import FlipReference

__all__ = [
    "LIT_THRESHOLD",
    "FLIP_PPD",
    "FrameMetrics",
    "display",
    "visibility_metrics",
    "flip",
    "flip_evaluator_flip",
    "PARALLEL_MIN_ROWS",
    "SRGB_TO_XYZ",
    "D65_XYZ",
    "LabImage",
    "lab",
    "delta_e2000",
    "delta_e2000_colour",
    "Reference",
    "compare",
    "IMAGE_METRICS",
    "flip_error",
    "image_metrics",
    "pooled_psnr_db",
]

#: A layer value at or above this counts as lit (``V`` and ``F`` alike): the
#: leak and false-shadow counts here and the maps of :mod:`hzval.report.images`.
LIT_THRESHOLD = 0.5

#: FLIP's viewing condition: its default 67 pixels per degree (a 0.7 m
#: viewing distance from a 3840-pixel, 0.7 m wide monitor), fixed so that
#: numbers compare across runs.
FLIP_PPD = 67.0


@dataclass(frozen=True)
class FrameMetrics:
    """A technique's scores in one frame against the truth: visibility errors, FLIP, RMSE, PSNR, ΔE."""

    visibility_mae: float | None
    leak_fraction: float | None
    false_shadow_fraction: float | None
    flip_mean: float
    rmse: float
    psnr_db: float
    delta_e2000_mean: float
    reflection_mae: float | None = None

    def as_dict(self) -> dict:
        """Return the scores as a JSON object; ``reflection_mae`` only where the scene declares it."""
        d = asdict(self)
        if d["reflection_mae"] is None:  # only scenes that declare reflection_occlusion have it
            del d["reflection_mae"]
        return d


def display(image: np.ndarray, scale: float) -> np.ndarray:
    """Linear radiance to sRGB-encoded display values, as a viewer shows them.

    ``srgb_encode(clip(scale * image, 0, 1))`` (:func:`hzval.core.srgb.encode`, IEC
    61966-2-1), in one float64 Dr.Jit kernel over every value; it matches colour-science's
    ``cctf_encoding`` to 4e-16 (``benchmarks/bench_compare.py`` has the timings).

    Parameters
    ----------
    image : numpy.ndarray
        Linear radiance, ``(H, W)`` (grey) or ``(H, W, 3)``.
    scale : float
        The exposure (:func:`hzval.core.shading.exposure`): radiance times ``scale`` is 1 at white.

    Returns
    -------
    numpy.ndarray
        ``(H, W, 3)`` float64 display values in [0, 1]; a grey image is repeated on the three channels.
    """
    backend.variant()
    img = np.asarray(image)
    grey = img.ndim == 2
    v = mi.Float64(_flat_values(img)) * dr.opaque(mi.Float64, float(scale))
    shown = np.asarray(srgb.encode(dr.clip(v, 0.0, 1.0)), dtype=np.float64).reshape(img.shape)
    return np.repeat(shown[..., None], 3, axis=-1) if grey else shown


def visibility_metrics(
    V: np.ndarray, F: np.ndarray, mask: np.ndarray | None = None
) -> tuple[float, float, float]:
    """Return the visibility scores of a technique's shadow factor against the truth's visibility.

    A pixel is lit where its value is at least :data:`LIT_THRESHOLD`; one float64 Dr.Jit kernel
    computes the three sums (the counts exact, the mean NumPy's to 1e-15).

    Parameters
    ----------
    V, F : numpy.ndarray
        ``(H, W)`` truth visibility and technique factor, in [0, 1].
    mask : numpy.ndarray, optional
        ``(H, W)`` bool, the pixels that see the surface; ``None``: all.

    Returns
    -------
    tuple of float
        ``(mean |F - V|, leak fraction, false-shadow fraction)``: leaks are lit by the technique where
        the truth is shadowed, false shadows the reverse, each a fraction of the counted pixels; NaN
        where no pixel is counted.

    Raises
    ------
    hzval.core.errors.HzvalError
        When ``V`` and ``F`` differ in shape.
    """
    backend.variant()
    if np.shape(V) != np.shape(F):
        raise HzvalError(f"visibility layers of different shapes: {np.shape(V)} and {np.shape(F)}")
    v, f = mi.Float64(_flat_values(V)), mi.Float64(_flat_values(F))
    lit_truth, lit_test = v >= LIT_THRESHOLD, f >= LIT_THRESHOLD
    terms = [
        dr.abs(f - v),
        dr.select(lit_test & ~lit_truth, 1.0, 0.0),
        dr.select(~lit_test & lit_truth, 1.0, 0.0),
    ]
    count = np.size(V)
    if mask is not None:
        seen = mi.Bool(np.ascontiguousarray(mask, bool).ravel())
        terms = [dr.select(seen, t, 0.0) for t in terms]
        count = int(np.count_nonzero(mask))
    sums = [dr.sum(t) for t in terms]
    dr.eval(sums)
    if not count:
        return (math.nan,) * 3
    return tuple(float(t[0]) / count for t in sums)


def flip(reference_display: np.ndarray, test_display: np.ndarray) -> tuple[np.ndarray, float]:
    """Return the FLIP error (Andersson et al. 2020, LDR) of a test image against a reference.

    Parameters
    ----------
    reference_display, test_display : numpy.ndarray
        ``(H, W, 3)`` sRGB display values in [0, 1] (:func:`display`).

    Returns
    -------
    error : numpy.ndarray
        ``(H, W)`` float32 per-pixel FLIP, in [0, 1].
    mean : float
        Its mean.

    Raises
    ------
    hzval.core.errors.HzvalError
        For images of different sizes or not ``(H, W, 3)``.

    Notes
    -----
    :mod:`hzval.metrics.flip` at :data:`FLIP_PPD` pixels per degree; :class:`Reference` keeps the
    reference's half for several test images (:func:`flip_error`).
    """
    try:
        return hzflip.flip(reference_display, test_display, FLIP_PPD)
    except ValueError as exc:
        raise HzvalError(f"FLIP refused its input ({exc})") from None


def flip_evaluator_flip(reference_display: np.ndarray, test_display: np.ndarray) -> tuple[np.ndarray, float]:
    """Compute :func:`flip` through NVIDIA's ``flip-evaluator`` package.

    It is the implementation :mod:`hzval.metrics.flip` is validated against (the tests,
    ``benchmarks/bench_compare.py``).

    Parameters
    ----------
    reference_display, test_display : numpy.ndarray
        ``(H, W, 3)`` sRGB display values in [0, 1].

    Returns
    -------
    error : numpy.ndarray
        ``(H, W)`` float32 per-pixel FLIP.
    mean : float
        Its mean, as the package computes it.

    Raises
    ------
    hzval.core.errors.HzvalError
        Where the package's wrapper would exit the process (``sys.exit``) or raises ``RuntimeError``.
    """
    try:
        err, mean, _ = flip_evaluator.evaluate(
            np.ascontiguousarray(reference_display, dtype=np.float32),
            np.ascontiguousarray(test_display, dtype=np.float32),
            "LDR",
            inputsRGB=True,
            applyMagma=False,
            computeMeanError=True,
            parameters={"ppd": FLIP_PPD},
        )
    except SystemExit as exc:
        raise HzvalError(f"flip-evaluator refused its input (exit {exc.code})") from None
    except (RuntimeError, ValueError) as exc:
        raise HzvalError(f"flip-evaluator refused its input ({str(exc).splitlines()[0]})") from None
    err = np.asarray(err, dtype=np.float32)
    return err.reshape(err.shape[:2]), float(mean)


#: Images of at least this many rows are converted in row blocks on a thread
#: per core (:func:`by_rows`); smaller ones are not worth the threads.
PARALLEL_MIN_ROWS = 64


def by_rows(fn, *arrays: np.ndarray) -> np.ndarray:
    """``fn(*arrays)`` of a per-pixel ``fn``, computed in row blocks on a thread per core.

    NumPy's and colour-science's expressions release the GIL, so blocks run at once on the host's
    cores; the result is bit for bit that of one call (``benchmarks/bench_compare.py`` has the
    speed-up). Images of fewer than ``2 * PARALLEL_MIN_ROWS`` rows are computed in one call.

    Parameters
    ----------
    fn : callable
        A function of arrays whose first axis is the image's rows, with no dependence between rows.
    *arrays : numpy.ndarray
        Its arguments, all with the same number of rows.

    Returns
    -------
    numpy.ndarray
        ``fn``'s result, the blocks concatenated along the rows.
    """
    rows = arrays[0].shape[0]
    n = min(backend.host_cores(), rows // PARALLEL_MIN_ROWS)
    if n < 2:
        return fn(*arrays)
    bounds = np.linspace(0, rows, n + 1).astype(int)
    parts = list(
        backend.host_pool(n).map(lambda a, b: fn(*(x[a:b] for x in arrays)), bounds[:-1], bounds[1:])
    )
    return np.concatenate(parts, axis=0)


# -- CIELAB and CIEDE2000 ------------------------------------------------------------------------
#
# colour-science's definitions, as ``colour.XYZ_to_Lab(colour.sRGB_to_XYZ(rgb))`` and
# ``colour.delta_E(lab_1, lab_2, method="CIE 2000")`` compute them (colour 0.4.7): its sRGB
# decoding (linear below ``eotf_inverse_sRGB(0.0031308)``), its sRGB matrix (IEC 61966-2-1's
# four digits), D65 from its chromaticity (0.3127, 0.329), and Sharma, Wu and Dalal's CIEDE2000
# with colour's ``np.select`` branches, term for term, in float64.

#: colour-science's sRGB-to-XYZ matrix (linear sRGB to CIE XYZ, D65).
SRGB_TO_XYZ = ((0.4124, 0.3576, 0.1805), (0.2126, 0.7152, 0.0722), (0.0193, 0.1192, 0.9505))
#: CIE XYZ of D65, from colour-science's chromaticity of it (CIE 1931 2 degree observer).
D65_XYZ = (0.3127 / 0.329, 1.0, (1.0 - 0.3127 - 0.329) / 0.329)
#: colour-science's sRGB decoding is linear at and below this encoded value.
_SRGB_LINEAR_BELOW = 1.055 * 0.0031308 ** (1 / 2.4) - 0.055


def _lab_kernel(r, g, b):
    """Dr.Jit: sRGB-encoded ``r, g, b`` (float64 arrays of the current variant) to CIELAB."""

    def decode(v):
        return dr.select(_SRGB_LINEAR_BELOW >= v, v / 12.92, dr.power((v + 0.055) / 1.055, 2.4))

    lin = [decode(v) for v in (r, g, b)]
    f = []
    for row, white in zip(SRGB_TO_XYZ, D65_XYZ):
        t = (row[0] * lin[0] + row[1] * lin[1] + row[2] * lin[2]) / white
        f.append(dr.select(t > (24 / 116) ** 3, dr.power(t, 1 / 3), (841 / 108) * t + 16 / 116))
    return 116 * f[1] - 16, 500 * (f[0] - f[1]), 200 * (f[1] - f[2])


def _delta_e2000_kernel(L1, a1, b1, L2, a2, b2):
    """Dr.Jit: CIEDE2000 (k_L = k_C = k_H = 1) of two CIELAB arrays, as colour-science has it."""
    rad, deg = math.pi / 180, 180 / math.pi
    C1, C2 = dr.sqrt(a1 * a1 + b1 * b1), dr.sqrt(a2 * a2 + b2 * b2)
    Cb7 = dr.power((C1 + C2) / 2, 7)
    G = 0.5 * (1 - dr.sqrt(Cb7 / (Cb7 + 25**7)))
    ap1, ap2 = (1 + G) * a1, (1 + G) * a2
    Cp1, Cp2 = dr.sqrt(ap1 * ap1 + b1 * b1), dr.sqrt(ap2 * ap2 + b2 * b2)

    def hue(b, ap):  # degrees in [0, 360), 0 where a' = b = 0
        h = dr.atan2(b, ap) * deg
        return dr.select((b == 0) & (ap == 0), 0, dr.select(h < 0, h + 360, h))

    h1, h2 = hue(b1, ap1), hue(b2, ap2)
    C12 = Cp1 * Cp2
    d = h2 - h1
    dh = dr.select(C12 == 0, 0, dr.select(dr.abs(d) <= 180, d, dr.select(d > 180, d - 360, d + 360)))
    dH = 2 * dr.sqrt(C12) * dr.sin(dh / 2 * rad)
    s = h1 + h2
    hb = dr.select(
        C12 == 0,
        s,
        dr.select(dr.abs(h1 - h2) <= 180, s / 2, dr.select(s < 360, (s + 360) / 2, (s - 360) / 2)),
    )
    T = (
        1
        - 0.17 * dr.cos((hb - 30) * rad)
        + 0.24 * dr.cos((2 * hb) * rad)
        + 0.32 * dr.cos((3 * hb + 6) * rad)
        - 0.20 * dr.cos((4 * hb - 63) * rad)
    )
    q = (hb - 275) / 25
    d_theta = 30 * dr.exp(-(q * q))
    Cbp = (Cp1 + Cp2) / 2
    Cbp7 = dr.power(Cbp, 7)
    RT = -dr.sin((2 * d_theta) * rad) * (2 * dr.sqrt(Cbp7 / (Cbp7 + 25**7)))
    Lb2 = ((L1 + L2) / 2 - 50) * ((L1 + L2) / 2 - 50)
    SL = 1 + (0.015 * Lb2) / dr.sqrt(20 + Lb2)
    SC = 1 + 0.045 * Cbp
    SH = 1 + 0.015 * Cbp * T
    x, y, z = (L2 - L1) / SL, (Cp2 - Cp1) / SC, dH / SH
    return dr.sqrt(x * x + y * y + z * z + RT * y * z)


def _rgb_planes(display_rgb: np.ndarray, grey: bool = False):
    """Return an ``(H, W, 3)`` display image as three float64 Dr.Jit arrays.

    They are gathered from one float64 array of it (which the LLVM backend maps without copying, keeping a
    reference). With ``grey`` (its channels bitwise equal, as the caller has checked) it is one array three
    times, so that what is computed from the channels is computed once (Dr.Jit merges equal expressions of
    equal variables), the same bit for bit.
    """
    backend.variant()
    img = np.asarray(display_rgb)
    if img.ndim != 3 or img.shape[2] != 3 or img.shape[0] * img.shape[1] == 0:
        raise HzvalError(f"CIEDE2000 needs an (H, W, 3) image, got shape {img.shape}")
    buf = np.ascontiguousarray(img, dtype=np.float64).ravel()
    flat = mi.Float64(buf)
    i = dr.arange(mi.UInt32, img.shape[0] * img.shape[1]) * 3
    if grey:
        return (dr.gather(mi.Float64, flat, i),) * 3
    return tuple(dr.gather(mi.Float64, flat, i + c) for c in range(3))


class LabImage:
    """CIELAB (D65) of an sRGB display image, as float64 Dr.Jit arrays of the current variant.

    The arrays are ``L``, ``a``, ``b``, row-major, for :func:`delta_e2000` against several test images.
    """

    def __init__(self, display_rgb: np.ndarray, *, grey: bool = False):

        self.shape = tuple(np.shape(display_rgb)[:2])
        self.L, self.a, self.b = _lab_kernel(*_rgb_planes(display_rgb, grey))
        dr.eval(self.L, self.a, self.b)

    @classmethod
    def from_array(cls, lab: np.ndarray) -> "LabImage":
        """Return a :class:`LabImage` of given ``(H, W, 3)`` CIELAB values."""
        backend.variant()
        lab = np.asarray(lab, dtype=np.float64)
        self = cls.__new__(cls)
        self.shape = lab.shape[:2]
        self.L, self.a, self.b = (
            mi.Float64(np.array(lab[..., c], dtype=np.float64).ravel()) for c in range(3)
        )
        dr.eval(self.L, self.a, self.b)
        return self

    def numpy(self) -> np.ndarray:
        """``(H, W, 3)`` float64 CIELAB."""
        return np.stack(
            [np.asarray(c, dtype=np.float64).reshape(self.shape) for c in (self.L, self.a, self.b)], axis=-1
        )


def lab(display_rgb: np.ndarray) -> np.ndarray:
    """CIELAB (D65) of sRGB display values, as :func:`delta_e2000` computes it.

    Parameters
    ----------
    display_rgb : numpy.ndarray
        ``(H, W, 3)`` sRGB display values in [0, 1].

    Returns
    -------
    numpy.ndarray
        ``(H, W, 3)`` float64 ``L*, a*, b*``: colour-science's ``XYZ_to_Lab(sRGB_to_XYZ(rgb))`` to
        within 1e-12.
    """
    return LabImage(display_rgb).numpy()


def delta_e2000(
    reference_display: np.ndarray,
    test_display: np.ndarray,
    *,
    reference_lab: "LabImage | np.ndarray | None" = None,
    grey: bool = False,
) -> np.ndarray:
    """Per-pixel CIEDE2000 (Sharma, Wu and Dalal 2005) between two sRGB display images, D65.

    One float64 Dr.Jit kernel takes the test image from sRGB to CIELAB and on to CIEDE2000. It
    agrees with colour-science (:func:`delta_e2000_colour`) to 1e-11 a pixel, near-grey pixels
    against saturated ones included; float32 would not (a grey's hue is then rounding noise that
    ``dH' = 2 sqrt(C1 C2) sin(dh / 2)`` carries). ``benchmarks/bench_compare.py`` measures both.

    Parameters
    ----------
    reference_display, test_display : numpy.ndarray
        ``(H, W, 3)`` sRGB display values in [0, 1].
    reference_lab : LabImage or numpy.ndarray, optional
        The reference's CIELAB when the caller has it (:class:`Reference` keeps it): the same values
        either way.
    grey : bool, optional
        The test image's channels are bitwise equal, as the caller has checked
        (:func:`hzval.io.codecs.is_grey`): its colour is then converted once, the same values either
        way.

    Returns
    -------
    numpy.ndarray
        ``(H, W)`` float64 CIEDE2000.

    Raises
    ------
    hzval.core.errors.HzvalError
        For images of different sizes.
    """
    if reference_lab is None:
        ref = LabImage(reference_display)
    elif isinstance(reference_lab, LabImage):
        ref = reference_lab
    else:
        ref = LabImage.from_array(reference_lab)
    rgb = _rgb_planes(test_display, grey)
    if tuple(np.shape(test_display)[:2]) != tuple(ref.shape):
        raise HzvalError(
            f"CIEDE2000 of images of different sizes: {ref.shape} and {np.shape(test_display)[:2]}"
        )
    out = _delta_e2000_kernel(ref.L, ref.a, ref.b, *_lab_kernel(*rgb))
    dr.eval(out)
    return np.asarray(out, dtype=np.float64).reshape(ref.shape)


def delta_e2000_colour(reference_display: np.ndarray, test_display: np.ndarray) -> np.ndarray:
    """Compute :func:`delta_e2000` through colour-science, in row blocks (:func:`by_rows`).

    It is the implementation the kernel is validated against (the tests, ``benchmarks/bench_compare.py``).

    Parameters
    ----------
    reference_display, test_display : numpy.ndarray
        ``(H, W, 3)`` sRGB display values in [0, 1].

    Returns
    -------
    numpy.ndarray
        ``(H, W)`` float64 CIEDE2000.
    """
    # colour-science: 1.7 s to import, paid only where a conversion runs
    import colour

    def lab_of(rgb):
        return colour.XYZ_to_Lab(colour.sRGB_to_XYZ(rgb, apply_cctf_decoding=True))

    ref = by_rows(lab_of, np.asarray(reference_display, dtype=np.float64))
    test = by_rows(lab_of, np.asarray(test_display, dtype=np.float64))
    return np.asarray(by_rows(lambda a, b: colour.delta_E(a, b, method="CIE 2000"), ref, test))


class Reference:
    """What :func:`compare` derives from the truth alone, computed once per frame.

    A frame compared with several techniques (horizon map, terrain) reuses
    the truth's linear values, display values, CIELAB (``lab``, a
    :class:`LabImage`) and FLIP's filtered reference (``flip``, a
    :class:`hzval.metrics.flip.FlipReference`); every metric's value is the same as
    without it.
    """

    def __init__(self, truth, scale: float):

        self.truth, self.scale = truth, float(scale)
        self.linear = _flat_values(truth.image)
        grey = codecs.is_grey(truth.image)
        self.display = display(truth.image, scale)
        self.lab = LabImage(self.display, grey=grey)
        self.flip = FlipReference(self.display, FLIP_PPD, grey=grey)


def compare(
    truth, test, scale: float, *, reference: Reference | None = None
) -> tuple[FrameMetrics, dict[str, np.ndarray]]:
    """Return the metrics of one frame of a technique, and the maps behind them.

    Parameters
    ----------
    truth, test : hzval.scene.spec.Frame
        The truth's frame and the technique's, of one light.
    scale : float
        The sweep's exposure (:func:`hzval.core.shading.exposure`).
    reference : Reference, optional
        ``Reference(truth, scale)``, when several techniques are compared with the same truth.

    Returns
    -------
    metrics : FrameMetrics
        Visibility scores (where both frames have them, :func:`visibility_metrics`), the reflection
        error (where both have reflection occlusion), and the image scores (:func:`image_metrics`).
    maps : dict of numpy.ndarray
        ``flip``, ``delta_e`` and ``display`` (the technique's display values), per pixel
        (:func:`image_metrics`); the visibility maps are drawn from ``F`` and ``V`` themselves
        (:mod:`hzval.report.images`).
    """
    ref = reference if reference is not None else Reference(truth, scale)
    maps: dict[str, np.ndarray] = {}
    V, F = truth.layers.get("visibility"), test.layers.get("factor")
    mask = truth.mask
    if V is not None and F is not None:
        mae, leak, false_shadow = visibility_metrics(V, F, mask)
    else:
        mae = leak = false_shadow = None
    O, R = test.layers.get("reflection_occlusion"), truth.layers.get("reflection_occlusion")
    reflection = None
    if O is not None and R is not None:
        reflection = float(
            np.mean(_seen(np.abs(np.asarray(O, np.float64) - np.asarray(R, np.float64)), mask))
        )
    scores, image_maps = image_metrics(ref, test.image)
    maps.update(image_maps)
    return FrameMetrics(
        mae,
        leak,
        false_shadow,
        scores["flip_mean"],
        scores["rmse"],
        scores["psnr_db"],
        scores["delta_e2000_mean"],
        reflection,
    ), maps


#: The image metrics of a frame, the keys of :func:`image_metrics` (and of a frame's ``floor``).
IMAGE_METRICS: tuple[str, ...] = ("flip_mean", "rmse", "psnr_db", "delta_e2000_mean")


def flip_error(ref_flip, test_display: np.ndarray, *, grey: bool = False) -> tuple[np.ndarray, float]:
    """:func:`flip` of a test image against a reference's kept half.

    Parameters
    ----------
    ref_flip : hzval.metrics.flip.FlipReference
        The reference's filtered values (:class:`Reference` keeps them).
    test_display : numpy.ndarray
        ``(H, W, 3)`` sRGB display values in [0, 1].
    grey : bool, optional
        Its channels are bitwise equal, as the caller has checked (:func:`hzval.metrics.flip.flip_error`).

    Returns
    -------
    error : numpy.ndarray
        ``(H, W)`` float32 per-pixel FLIP.
    mean : float
        Its mean.
    """
    try:
        return hzflip.flip_error(ref_flip, test_display, grey=grey)
    except ValueError as exc:
        raise HzvalError(f"FLIP refused its input ({exc})") from None


def image_metrics(ref: Reference, image: np.ndarray) -> tuple[dict[str, float], dict[str, np.ndarray]]:
    """Return the image scores of a linear image against the truth of ``ref``.

    RMSE and PSNR (peak 1) on exposed linear values, FLIP and CIEDE2000 on display values; each a
    mean over the pixels that see the surface (the truth frame's ``mask``; all of the ``top``
    view's).

    Parameters
    ----------
    ref : Reference
        The truth's derived values.
    image : numpy.ndarray
        ``(H, W, 3)`` linear radiance.

    Returns
    -------
    scores : dict of float
        ``flip_mean``, ``rmse``, ``psnr_db`` (infinite for a perfect match), ``delta_e2000_mean``.
    maps : dict of numpy.ndarray
        ``display``, ``flip`` and ``delta_e``, per pixel.
    """
    mask = ref.truth.mask
    mse = _mean_squared_error(ref, image)
    psnr = float("inf") if mse == 0 else 10.0 * math.log10(1.0 / mse)
    grey = codecs.is_grey(image)  # checked once, on the linear values: the display's are grey with them
    maps = {"display": display(image, ref.scale)}
    maps["flip"], flip_mean = flip_error(ref.flip, maps["display"], grey=grey)
    if mask is not None:
        flip_mean = float(np.mean(maps["flip"][mask]))
    maps["delta_e"] = delta_e2000(ref.display, maps["display"], reference_lab=ref.lab, grey=grey)
    return {
        "flip_mean": flip_mean,
        "rmse": math.sqrt(mse),
        "psnr_db": psnr,
        "delta_e2000_mean": float(np.mean(_seen(maps["delta_e"], mask))),
    }, maps


def _flat_values(image: np.ndarray):
    """Return an image's values, row-major, as a float32 or float64 Dr.Jit array.

    The array is gathered from its NumPy memory (a gather: a mapped array's contiguous load would compile one
    kernel per alignment).
    """
    backend.variant()
    img = np.asarray(image)
    flat = np.ascontiguousarray(img, dtype=np.float32 if img.dtype.itemsize <= 4 else np.float64).ravel()
    kind = mi.Float if flat.dtype == np.float32 else mi.Float64
    return dr.gather(kind, kind(flat), dr.arange(mi.UInt32, flat.size))


def _mean_squared_error(ref: Reference, image: np.ndarray) -> float:
    """Mean of ``(scale (truth - image))^2`` over the values of the pixels the truth sees, in float64."""
    img = np.asarray(image)
    if img.shape != ref.truth.image.shape:
        raise HzvalError(f"images of different shapes: {ref.truth.image.shape} and {img.shape}")
    s = dr.opaque(mi.Float64, ref.scale)
    d = mi.Float64(ref.linear) * s - mi.Float64(_flat_values(img)) * s
    d2 = d * d
    mask = ref.truth.mask
    count = img.size
    if mask is not None:
        channels = img.size // mask.size
        seen = np.repeat(np.asarray(mask, bool).ravel(), channels)
        d2 = dr.select(mi.Bool(seen), d2, 0.0)
        count = int(seen.sum())
    return float(dr.sum(d2)[0]) / count if count else float("nan")


def _seen(values: np.ndarray, mask: np.ndarray | None) -> np.ndarray:
    """Return the pixels of ``values`` ``(H, W[, C])`` that ``mask`` keeps (all for ``None``)."""
    return values if mask is None else values[mask]


def pooled_psnr_db(rmses) -> float | None:
    """Return the PSNR of several frames together, ``10 log10(1 / mean(rmse^2))`` (peak 1).

    It uses the frames' mean squared error, not the mean of their decibels, which one near-identical frame
    (150 dB) would dominate. It is ``inf`` when every frame is identical, ``None`` with no frame.

    Examples
    --------
    >>> round(pooled_psnr_db([0.1, 0.1]), 6)
    20.0
    >>> round(pooled_psnr_db([0.1, 1e-8]), 2)  # the decibels' mean would be 90
    23.01
    >>> pooled_psnr_db([0.0, 0.0])
    inf
    """
    values = [float(r) ** 2 for r in rmses if isinstance(r, (int, float)) and math.isfinite(r)]
    if not values:
        return None
    mse = sum(values) / len(values)
    return math.inf if mse == 0 else 10.0 * math.log10(1.0 / mse)
