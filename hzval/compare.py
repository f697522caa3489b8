"""Comparing a frame of the approximation with the truth (docs/ARCHITECTURE.md, "Metrics").

Visibility, on the one-channel layers in [0, 1]:

* ``visibility_mae``: mean ``|F - V|`` over pixels;
* ``leak_fraction``: pixels the technique lights (``F >= 0.5``) that are in
  shadow (``V < 0.5``);
* ``false_shadow_fraction``: pixels it shadows (``F < 0.5``) that are lit
  (``V >= 0.5``);
* ``reflection_mae`` (with ``reflection_occlusion``): mean ``|o - R|``, the
  Toolbag fade ``o`` of :mod:`hzval.approx` against the truth's unoccluded
  fraction ``R`` of the glossy lobe about the mirror direction
  (:mod:`hzval.truth`).

Images: ``rmse`` and ``psnr_db`` on linear values (peak 1: the largest
radiance the declared effects can produce, :func:`hzval.shading.exposure`); FLIP (NVIDIA,
``flip-evaluator``, LDR, 67 pixels per degree) and CIEDE2000 (colour-science)
on display values, i.e. exposed, clipped to [0, 1] and sRGB-encoded.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from hzval import conventions as cv
from hzval.errors import HzvalError

#: A layer value at or above this counts as lit (``V`` and ``F`` alike): the
#: leak and false-shadow counts here and the maps of :mod:`hzval.images`.
LIT_THRESHOLD = 0.5

#: FLIP's viewing condition: its default 67 pixels per degree (a 0.7 m
#: viewing distance from a 3840-pixel, 0.7 m wide monitor), fixed so that
#: numbers compare across runs.
FLIP_PPD = 67.0


@dataclass(frozen=True)
class FrameMetrics:
    visibility_mae: float | None
    leak_fraction: float | None
    false_shadow_fraction: float | None
    flip_mean: float
    rmse: float
    psnr_db: float
    delta_e2000_mean: float
    reflection_mae: float | None = None

    def as_dict(self) -> dict:
        d = asdict(self)
        if d["reflection_mae"] is None:       # only scenes that declare reflection_occlusion have it
            del d["reflection_mae"]
        return d


def display(image: np.ndarray, scale: float) -> np.ndarray:
    """Linear radiance ``(H, W[, 3])`` to sRGB-encoded display values in [0, 1], ``(H, W, 3)``."""
    img = np.asarray(image, dtype=np.float64)
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=-1)
    return _by_rows(lambda x: cv.srgb_encode(np.clip(x * scale, 0.0, 1.0)), img)


def visibility_metrics(V: np.ndarray, F: np.ndarray) -> tuple[float, float, float]:
    """``(mean |F - V|, leak fraction, false-shadow fraction)`` of two ``(H, W)`` layers."""
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.float64)
    lit_truth, lit_approx = V >= LIT_THRESHOLD, F >= LIT_THRESHOLD
    return (float(np.mean(np.abs(F - V))),
            float(np.mean(lit_approx & ~lit_truth)),
            float(np.mean(~lit_approx & lit_truth)))


def flip(reference_display: np.ndarray, test_display: np.ndarray) -> tuple[np.ndarray, float]:
    """FLIP error map ``(H, W)`` and its mean, for sRGB display values in [0, 1].

    ``flip-evaluator``'s Python wrapper calls ``sys.exit`` on some bad
    arguments and raises ``RuntimeError`` on others; both become an
    :class:`~hzval.errors.HzvalError` here rather than ending the process.
    """
    import flip_evaluator

    try:
        err, mean, _ = flip_evaluator.evaluate(
            np.ascontiguousarray(reference_display, dtype=np.float32),
            np.ascontiguousarray(test_display, dtype=np.float32),
            "LDR", inputsRGB=True, applyMagma=False, computeMeanError=True,
            parameters={"ppd": FLIP_PPD})
    except SystemExit as exc:
        raise HzvalError(f"flip-evaluator refused its input (exit {exc.code})") from None
    except (RuntimeError, ValueError) as exc:
        raise HzvalError(f"flip-evaluator refused its input ({str(exc).splitlines()[0]})") from None
    err = np.asarray(err, dtype=np.float32)
    return err.reshape(err.shape[:2]), float(mean)


#: Images of at least this many rows are converted in row blocks on a thread
#: per core (:func:`_by_rows`); smaller ones are not worth the threads.
PARALLEL_MIN_ROWS = 64


def _by_rows(fn, *arrays: np.ndarray) -> np.ndarray:
    """``fn(*arrays)`` for a per-pixel ``fn``, computed in row blocks on a thread per core.

    colour-science's conversions and CIEDE2000 are NumPy expressions that
    release the GIL, on one core each: on the 2-core machine two blocks at
    once take 0.57x the time of the whole image in one (512 x 512 random
    images, CIEDE2000 with both Lab conversions: 0.27 s against 0.47 s).
    The values are bit for bit those of one call.
    """
    from hzval import backend

    rows = arrays[0].shape[0]
    n = min(backend.host_cores(), rows // PARALLEL_MIN_ROWS)
    if n < 2:
        return fn(*arrays)
    bounds = np.linspace(0, rows, n + 1).astype(int)
    parts = list(backend.host_pool(n).map(lambda a, b: fn(*(x[a:b] for x in arrays)), bounds[:-1], bounds[1:]))
    return np.concatenate(parts, axis=0)


def _lab(display_rgb: np.ndarray) -> np.ndarray:
    """CIELAB (D65) of sRGB display values, as :func:`delta_e2000` computes it."""
    import colour

    def lab(rgb):
        return colour.XYZ_to_Lab(colour.sRGB_to_XYZ(rgb, apply_cctf_decoding=True))

    return _by_rows(lab, np.asarray(display_rgb, dtype=np.float64))


def delta_e2000(reference_display: np.ndarray, test_display: np.ndarray, *,
                reference_lab: np.ndarray | None = None) -> np.ndarray:
    """Per-pixel CIEDE2000 between two sRGB display images (D65), via colour-science.

    ``reference_lab``: the reference's Lab when the caller has it already
    (:class:`Reference`); the same values either way.
    """
    import colour

    ref = _lab(reference_display) if reference_lab is None else reference_lab
    return np.asarray(_by_rows(lambda a, b: colour.delta_E(a, b, method="CIE 2000"), ref, _lab(test_display)))


class Reference:
    """What :func:`compare` derives from the truth alone, computed once per frame.

    A frame compared with several techniques (horizon map, terrain) reuses
    the truth's linear values, display values and Lab; every metric's value
    is the same as without it.
    """

    def __init__(self, truth, scale: float):
        self.truth, self.scale = truth, float(scale)
        self.linear = np.asarray(truth.image, np.float64) * scale
        self.display = display(truth.image, scale)
        self.lab = _lab(self.display)


def compare(truth, approx, scale: float, *, reference: Reference | None = None
            ) -> tuple[FrameMetrics, dict[str, np.ndarray]]:
    """Metrics of one frame and the maps behind them (``flip``, ``delta_e``,
    ``visibility_diff``, and ``display``, the approximation's display values).

    ``truth`` and ``approx`` are :class:`hzval.scene.Frame`; ``scale`` is the
    sweep's :func:`hzval.shading.exposure`; ``reference``: ``Reference(truth, scale)``
    when several techniques are compared with the same truth.
    """
    ref = reference if reference is not None else Reference(truth, scale)
    maps: dict[str, np.ndarray] = {}
    V, F = truth.layers.get("visibility"), approx.layers.get("factor")
    if V is not None and F is not None:
        mae, leak, false_shadow = visibility_metrics(V, F)
        maps["visibility_diff"] = np.asarray(F, np.float32) - np.asarray(V, np.float32)
    else:
        mae = leak = false_shadow = None
    O, R = approx.layers.get("reflection_occlusion"), truth.layers.get("reflection_occlusion")
    reflection = None
    if O is not None and R is not None:
        reflection = float(np.mean(np.abs(np.asarray(O, np.float64) - np.asarray(R, np.float64))))
    scores, image_maps = image_metrics(ref, approx.image)
    maps.update(image_maps)
    return FrameMetrics(mae, leak, false_shadow, scores["flip_mean"], scores["rmse"], scores["psnr_db"],
                        scores["delta_e2000_mean"], reflection), maps


#: The image metrics of a frame, the keys of :func:`image_metrics` (and of a frame's ``floor``).
IMAGE_METRICS: tuple[str, ...] = ("flip_mean", "rmse", "psnr_db", "delta_e2000_mean")


def image_metrics(ref: Reference, image: np.ndarray) -> tuple[dict[str, float], dict[str, np.ndarray]]:
    """``({flip_mean, rmse, psnr_db, delta_e2000_mean}, {display, flip, delta_e})`` of a linear
    ``(H, W, 3)`` image against the truth of ``ref``: RMSE and PSNR (peak 1) on exposed linear
    values, FLIP and CIEDE2000 on display values."""
    a_lin = np.asarray(image, np.float64) * ref.scale
    mse = float(np.mean((ref.linear - a_lin) ** 2))
    psnr = float("inf") if mse == 0 else 10.0 * math.log10(1.0 / mse)
    maps = {"display": display(image, ref.scale)}
    maps["flip"], flip_mean = flip(ref.display, maps["display"])
    maps["delta_e"] = delta_e2000(ref.display, maps["display"], reference_lab=ref.lab)
    return {"flip_mean": flip_mean, "rmse": math.sqrt(mse), "psnr_db": psnr,
            "delta_e2000_mean": float(np.mean(maps["delta_e"]))}, maps
