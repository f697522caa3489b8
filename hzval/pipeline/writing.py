"""What a sweep writes of each frame: its EXR layers and PNG previews, written by a thread beside the
next frame's render (PNG compression and EXR encoding release the GIL), and the view's maps."""

from __future__ import annotations

import time
from functools import partial
from pathlib import Path

import numpy as np

from hzval.io import files
from hzval.metrics import compare
from hzval.report import images

__all__ = [
    "write_view_maps",
    "UNSEEN_DISPLAY",
    "PNG_LEVEL",
    "shown",
    "write_frame",
    "write_albedo",
]


def write_view_maps(report_dir: Path, maps: dict, seen: np.ndarray) -> dict:
    """``view/<name>.exr`` (texels, NaN where no surface is seen) and a PNG of each of the view's
    maps (magma, 0 to the largest seen value, the unseen pixels in the background colour);
    their paths relative to ``report_dir``."""
    folder = report_dir / "view"
    rel = {}
    for name, values in maps.items():
        v = np.where(seen, values, np.float32(np.nan)).astype(np.float32)
        files.write_exr(folder / f"{name}.exr", {"Y": v}, half=False)
        top = float(np.nanmax(v)) if np.isfinite(v).any() else 1.0
        rgb = images.magma(np.nan_to_num(v / max(top, 1e-12)))
        rgb[~seen] = files.unit_to_u8(np.asarray(UNSEEN_DISPLAY))
        files.write_png(folder / f"{name}.png", rgb)
        rel[name] = f"view/{name}.exr"
        rel[f"{name}_png"] = f"view/{name}.png"
    return rel


#: The display (sRGB) colour of pixels that see no surface (a view's sky, or off an ``open`` tile).
UNSEEN_DISPLAY = (0.33, 0.42, 0.55)
#: The frames' PNGs are written at zlib level 1: the renders' noise leaves zlib little to find, so a
#: higher level saves under 2% of a frame's bytes for several times the time (commit 'PNGs at
#: level 1' has the measurements).
PNG_LEVEL = 1


def shown(display: np.ndarray) -> np.ndarray:
    """A preview's 8-bit values of display values ``(H, W, 3)``: ``(H, W)`` where they are grey.

    Grey display values are quantised once, not per channel: the same values, a third of the
    work, and :func:`hzval.io.files.write_png` takes the ``(H, W)`` result as the grey PNG it would
    have made of them."""
    return files.unit_to_u8(display[..., 0] if files.is_grey(display) else display)


def write_frame(
    out: Path,
    name: str,
    truth_frame,
    plain,
    compared: list,
    scale: float,
    truth_shown: np.ndarray | None = None,
    all_files: bool = False,
    mask: np.ndarray | None = None,
) -> tuple[dict, dict, float]:
    """Write one frame's images; return ``(files, {technique: files}, seconds)``, the files as
    ``{key: path relative to out}`` (``metrics.json``'s ``files``).

    ``compared``: ``(technique, frame, metrics, maps)`` per technique; each
    technique's files are named after its ``file_stem``: ``<stem>.exr``,
    ``<stem>.png``, ``<stem>_factor.exr`` and ``.png``, ``<stem>_flip.png``,
    ``<stem>_visdiff.png``. Previews reuse the 8-bit values of the display values
    :func:`hzval.metrics.compare.compare` computed (``maps["shown"]``, ``truth_shown``: :func:`shown`).

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
    """
    t0 = time.perf_counter()
    w = _FrameWriter(out / "frames" / name, f"frames/{name}", scale, mask)
    rel = w.truth_files(truth_frame, plain, truth_shown, all_files)
    V = truth_frame.layers.get("visibility")
    per = {
        t.name: w.technique_files(t.file_stem, frame, maps, V, all_files) for t, frame, _, maps in compared
    }
    # Ctrl-C (or a writer's error): no writer outlives this frame to put a file into the staging
    # folder after the sweep has removed it
    files.run_writers(w.jobs)
    return rel, per, time.perf_counter() - t0


class _FrameWriter:
    """The writers of one frame's files (:func:`write_frame`), queued to run on a thread per core:
    the encoders release the GIL (2 cores: 0.55x the time)."""

    def __init__(self, folder: Path, prefix: str, scale: float, mask: np.ndarray | None):
        self.folder, self.prefix, self.scale, self.mask = folder, prefix, scale, mask
        self.jobs: list = []

    def exr(self, rel: dict, key: str, filename: str, channels) -> None:
        self.jobs.append(partial(files.write_exr, self.folder / filename, channels, half=True, grey=True))
        rel[key] = f"{self.prefix}/{filename}"

    def png(self, rel: dict, key: str, filename: str, make, *args) -> None:
        self.jobs.append(partial(_write_png_of, self.folder / filename, make, *args))
        rel[key] = f"{self.prefix}/{filename}"

    def shown(self, img, values=None):
        # computed here, not in a writer: compare.display runs on the writers' own pool, and a writer
        # waiting for it holds its thread until the queue has drained (the rest of the frame on one)
        return shown(compare.display(img, self.scale)) if values is None else values

    def layer(self, values):
        return (
            values
            if self.mask is None
            else np.where(self.mask, values, np.float32(np.nan)).astype(np.float32)
        )

    def truth_files(self, truth_frame, plain, truth_shown, all_files: bool) -> dict:
        """The truth's and the unshadowed render's files."""
        rel: dict = {}
        self.exr(rel, "truth", "truth.exr", {"RGB": truth_frame.image})
        if all_files:
            self.exr(rel, "plain", "plain.exr", {"RGB": plain.image})
        if "image" in truth_frame.variance:
            self.exr(rel, "truth_variance", "truth_variance.exr", {"RGB": truth_frame.variance["image"]})
        self.png(rel, "truth_png", "truth.png", _as_is, self.shown(truth_frame.image, truth_shown))
        self.png(rel, "plain_png", "plain.png", _as_is, self.shown(plain.image))
        V = truth_frame.layers.get("visibility")
        if V is not None:
            self.exr(rel, "visibility", "visibility.exr", {"Y": self.layer(V)})
            if all_files:
                self.png(rel, "visibility_png", "visibility.png", files.unit_to_u8, V)
        return rel

    def technique_files(self, stem: str, frame, maps: dict, V, all_files: bool) -> dict:
        """One technique's files, named after its ``stem``."""
        own: dict = {}
        if all_files:
            self.exr(own, "image", f"{stem}.exr", {"RGB": frame.image})
        self.png(own, "png", f"{stem}.png", _as_is, self.shown(frame.image, maps.get("shown")))
        self.png(own, "flip_png", f"{stem}_flip.png", images.flip_indexed, maps["flip"])
        F = frame.layers.get("factor")
        if F is not None:
            self.exr(own, "factor", f"{stem}_factor.exr", {"Y": self.layer(F)})
            if all_files:
                self.png(own, "factor_png", f"{stem}_factor.png", files.unit_to_u8, F)
            if V is not None:
                self.png(own, "visdiff_png", f"{stem}_visdiff.png", images.visibility_diff_indexed, V, F)
        return own


def _as_is(pixels):
    return pixels


def _write_png_of(path: Path, make, *args) -> None:
    """Write ``make(*args)`` (uint8 pixels or a palette image) at :data:`PNG_LEVEL`, grey RGB as grey,
    with the report's preview if it is large (:func:`hzval.io.files.write_png_with_preview`)."""
    files.write_png_with_preview(path, make(*args), compress_level=PNG_LEVEL, grey=True)


def write_albedo(folder: Path, albedo: np.ndarray) -> dict:
    """An albedo image where an engine finds it: ``albedo.exr`` (``R, G, B``, linear, as the truth
    reads it) and ``albedo.png`` (sRGB, as an engine's texture holds it), in ``folder``.

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
    from hzval.core import conventions as cv

    files.write_exr(folder / "albedo.exr", {"RGB": np.asarray(albedo, np.float32)})
    files.write_png(folder / "albedo.png", files.unit_to_u8(cv.srgb_encode(np.clip(albedo, 0.0, 1.0))))
    return {
        "linear": "albedo.exr",
        "srgb": "albedo.png",
        "encoding": "albedo.exr: linear R, G, B; albedo.png: the same, sRGB-encoded 8-bit",
    }
