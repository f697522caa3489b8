"""What a sweep writes of each frame: its EXR layers and PNG previews, and the view's maps.

Each file is written on a thread as soon as it is made, beside the next technique's render and comparison (PNG
compression and EXR encoding release the GIL).
"""

from __future__ import annotations

from functools import partial
from pathlib import Path

import numpy as np

from hzval.core import srgb
from hzval.io import codecs
from hzval.metrics import compare
from hzval.report import images

__all__ = [
    "write_view_maps",
    "UNSEEN_DISPLAY",
    "PNG_LEVEL",
    "PNG_RUNS",
    "shown",
    "FrameWriter",
    "write_albedo",
]


def write_view_maps(report_dir: Path, maps: dict, seen: np.ndarray) -> dict:
    """Write ``view/<name>.exr`` and a PNG of each of the view's maps, and return their paths.

    The EXRs are in texels, NaN where no surface is seen; the PNGs are in magma, 0 to the largest seen value,
    the unseen pixels in the background colour. The paths are relative to ``report_dir``.
    """
    folder = report_dir / "view"
    rel = {}
    for name, values in maps.items():
        v = np.where(seen, values, np.float32(np.nan)).astype(np.float32)
        codecs.write_exr(folder / f"{name}.exr", {"Y": v}, half=False)
        top = float(np.nanmax(v)) if np.isfinite(v).any() else 1.0
        rgb = images.magma(np.nan_to_num(v / max(top, 1e-12)))
        rgb[~seen] = codecs.unit_to_u8(np.asarray(UNSEEN_DISPLAY))
        codecs.write_png(folder / f"{name}.png", rgb)
        rel[name] = f"view/{name}.exr"
        rel[f"{name}_png"] = f"view/{name}.png"
    return rel


#: The display (sRGB) colour of pixels that see no surface (a view's sky, or off an ``open`` tile).
UNSEEN_DISPLAY = (0.33, 0.42, 0.55)
#: The frames' PNGs are written at zlib level 1: the renders' noise leaves zlib little to find, so a
#: higher level saves under 2% of a frame's bytes for several times the time (commit 'PNGs at
#: level 1' has the measurements).
PNG_LEVEL = 1
#: ... with zlib's run-length strategy (:func:`hzval.io.codecs.write_png`'s ``runs``): at level 1 it
#: is faster than the default strategy on the frames' renders and maps, for about as many bytes
#: (``benchmarks/bench_png.py``; benchmarks/README.md has the figures).
PNG_RUNS = True


def shown(display: np.ndarray) -> np.ndarray:
    """Return a preview's 8-bit values of display values ``(H, W, 3)``: ``(H, W)`` where they are grey.

    Grey display values are quantised once, not per channel: the same values, a third of the
    work, and :func:`hzval.io.codecs.write_png` takes the ``(H, W)`` result as the grey PNG it would
    have made of them.
    """
    return codecs.unit_to_u8(display[..., 0] if codecs.is_grey(display) else display)


class FrameWriter:
    """One frame's files, each written on the host pool as soon as it is given.

    The host pool has a thread per core: the encoders release the GIL. A technique's files are written while
    the next technique is rendered and compared, so that what they are made of is freed one technique at a
    time (the preview's 8-bit values and the FLIP map: 7 bytes a pixel a technique, 0.9 GiB at 4096 x 4096
    with eight). A context manager: the ``with`` block's end waits for every file; an error or Ctrl-C in it
    cancels the files not yet started and waits for the running ones (:class:`hzval.io.codecs.Writers`), so
    that no writer outlives the frame to put a file into the staging folder after the sweep has removed it.

    Each technique's files are named after its ``file_stem``: ``<stem>.exr``, ``<stem>.png``,
    ``<stem>_factor.exr`` and ``.png``, ``<stem>_flip.png``, ``<stem>_visdiff.png``. Previews reuse
    the 8-bit values of the display values :func:`hzval.metrics.compare.compare` computed
    (``maps["shown"]``, the truth's: :func:`shown`).

    What is written: the truth (``truth.exr``, its variance, ``visibility.exr``), each technique's
    ``F`` (``<stem>_factor.exr``), and the PNGs the report shows. The files that these determine
    are written only with ``all_files`` (``--all-files``): ``plain.exr`` (the report shows
    ``plain.png``), each technique's image ``<stem>.exr`` (``plain`` times ``F`` for the
    techniques that shade through :class:`hzval.techniques.surface.Unshadowed`; ``<stem>.png`` shows it) and
    the 8-bit PNGs of ``V`` and ``F`` (the EXRs hold them).

    Formats, each chosen to lose nothing a reader needs (the metrics were computed in float32
    before; docs/ARCHITECTURE.md, "metrics.json"): EXRs in half float, ZIP (2^-11 relative,
    finer than the previews' 8 bits; the variance's smallest values are rounded far inside the
    estimate's own relative error, sqrt(2 / (spp - 1))); an image with R == G == B as one ``Y``
    channel and an 8-bit grey PNG (lossless); FLIP and visibility-difference maps as palette PNGs
    (exact). ``mask``: the pixels a view's camera rays see; the layers' EXRs are NaN at the others.

    Parameters
    ----------
    out : pathlib.Path
        The report's folder; the frame's files go to ``frames/<name>/`` in it.
    name : str
        The frame's folder name (:func:`hzval.pipeline.records.frame_folder`).
    scale : float
        The sweep's exposure, for the previews' display values.
    mask : numpy.ndarray or None
        ``(H, W)`` bool, the pixels the view sees (``None``: all).
    all_files : bool
        Whether to write the files the others determine too.
    """

    def __init__(self, out: Path, name: str, scale: float, mask: np.ndarray | None, all_files: bool = False):
        self.folder, self.prefix = out / "frames" / name, f"frames/{name}"
        self.scale, self.mask, self.all_files = scale, mask, all_files
        self._visdiff: tuple | None = None  # (V, its images.VisibilityDiff), made at the first technique

    def __enter__(self) -> "FrameWriter":
        """Start the frame's writers."""
        self._writers = codecs.Writers().__enter__()
        return self

    def __exit__(self, kind, error, trace) -> bool:
        """Wait for the frame's writes; an error of a write is raised here."""
        return self._writers.__exit__(kind, error, trace)

    def wait(self) -> None:
        """Wait for every file started so far (a writer's error is raised here)."""
        self._writers.wait()

    def _exr(self, rel: dict, key: str, filename: str, channels) -> None:
        self._writers.submit(
            partial(codecs.write_exr, self.folder / filename, channels, half=True, grey=True)
        )
        rel[key] = f"{self.prefix}/{filename}"

    def _png(self, rel: dict, key: str, filename: str, make, *args) -> None:
        self._writers.submit(partial(_write_png_of, self.folder / filename, make, *args))
        rel[key] = f"{self.prefix}/{filename}"

    def _shown(self, img, values=None):
        # computed here, on the sweep's thread, not in a writer: compare.display is a Dr.Jit kernel,
        # and the sweep's thread launches every one of them
        return shown(compare.display(img, self.scale)) if values is None else values

    def _layer(self, values):
        return (
            values
            if self.mask is None
            else np.where(self.mask, values, np.float32(np.nan)).astype(np.float32)
        )

    def truth_files(self, truth_frame, plain, truth_shown: np.ndarray | None = None) -> dict:
        """Start the truth's and the unshadowed render's files; their paths, by key."""
        rel: dict = {}
        all_files = self.all_files
        self._exr(rel, "truth", "truth.exr", {"RGB": truth_frame.image})
        if all_files:
            self._exr(rel, "plain", "plain.exr", {"RGB": plain.image})
        if "image" in truth_frame.variance:
            self._exr(rel, "truth_variance", "truth_variance.exr", {"RGB": truth_frame.variance["image"]})
        self._png(rel, "truth_png", "truth.png", _as_is, self._shown(truth_frame.image, truth_shown))
        self._png(rel, "plain_png", "plain.png", _as_is, self._shown(plain.image))
        V = truth_frame.layers.get("visibility")
        if V is not None:
            self._exr(rel, "visibility", "visibility.exr", {"Y": self._layer(V)})
            if all_files:
                self._png(rel, "visibility_png", "visibility.png", codecs.unit_to_u8, V)
        return rel

    def technique_files(self, stem: str, frame, maps: dict, V) -> dict:
        """Start one technique's files, named after its ``stem``, and return their paths by key.

        ``maps``: ``shown`` and ``flip``; ``V``: the truth's visibility, or ``None``.
        """
        own: dict = {}
        if self.all_files:
            self._exr(own, "image", f"{stem}.exr", {"RGB": frame.image})
        self._png(own, "png", f"{stem}.png", _as_is, self._shown(frame.image, maps.get("shown")))
        self._png(own, "flip_png", f"{stem}_flip.png", images.flip_indexed, maps["flip"])
        F = frame.layers.get("factor")
        if F is not None:
            self._exr(own, "factor", f"{stem}_factor.exr", {"Y": self._layer(F)})
            if self.all_files:
                self._png(own, "factor_png", f"{stem}_factor.png", codecs.unit_to_u8, F)
            if V is not None:
                self._png(own, "visdiff_png", f"{stem}_visdiff.png", self._truth_diff(V).indexed, F)
        return own

    def _truth_diff(self, V) -> images.VisibilityDiff:
        # the truth's half of the frame's visibility-difference maps, made once, on the sweep's
        # thread, for every technique's map: a writer then only marks a technique's leaks
        if self._visdiff is None or self._visdiff[0] is not V:
            self._visdiff = (V, images.VisibilityDiff(V))
        return self._visdiff[1]


def _as_is(pixels):
    return pixels


def _write_png_of(path: Path, make, *args) -> None:
    """Write ``make(*args)`` (uint8 pixels or a palette image) at :data:`PNG_LEVEL`, grey RGB as grey.

    A large image gets the report's preview too (:func:`hzval.io.codecs.write_png_with_preview`).
    """
    codecs.write_png_with_preview(path, make(*args), compress_level=PNG_LEVEL, grey=True, runs=PNG_RUNS)


def write_albedo(folder: Path, albedo: np.ndarray) -> dict:
    """Write an albedo image in ``folder``, where an engine finds it.

    The files are ``albedo.exr`` (``R, G, B``, linear, as the truth reads it) and ``albedo.png`` (sRGB, as an
    engine's texture holds it).

    Parameters
    ----------
    folder : pathlib.Path
        The sweep's folder (its staging folder while it writes).
    albedo : numpy.ndarray
        ``(rows, cols, 3)`` linear albedo, row 0 at the top.

    Returns
    -------
    dict
        ``frames.json``'s ``albedo`` paths, relative to ``folder``: ``linear``, ``srgb`` and the
        ``encoding`` of each.
    """
    codecs.write_exr(folder / "albedo.exr", {"RGB": np.asarray(albedo, np.float32)})
    codecs.write_png(folder / "albedo.png", codecs.unit_to_u8(srgb.encode(np.clip(albedo, 0.0, 1.0))))
    return {
        "linear": "albedo.exr",
        "srgb": "albedo.png",
        "encoding": "albedo.exr: linear R, G, B; albedo.png: the same, sRGB-encoded 8-bit",
    }
