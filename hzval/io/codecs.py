"""Image codecs: EXR, PNG, matplotlib figures as PNG, and the previews of large PNGs.

EXR goes through OpenEXR, PNG through libpng (imagecodecs; palette images and reading through Pillow). Every
writer is atomic (:func:`hzval.io.atomic.atomic_path`).
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import errno
import os
import sys
import tempfile
import zlib
from pathlib import Path
from typing import Iterator, Mapping, NamedTuple

import imagecodecs
import numpy as np
import OpenEXR
from PIL import Image

from hzval.core import backend
from hzval.core.errors import InputError, first_line
from hzval.io.atomic import atomic_path

__all__ = [
    "HALF_MAX",
    "write_exr",
    "is_grey",
    "read_exr",
    "read_exr_attributes",
    "read_rgb_exr",
    "rgb_of",
    "library_output",
    "run_writers",
    "Writers",
    "Indexed",
    "write_png",
    "PREVIEW_ABOVE_PX",
    "PREVIEW_PX",
    "write_figure",
    "preview_of",
    "write_png_with_preview",
    "unit_to_u8",
]


# --------------------------------------------------------------------------
# EXR
# --------------------------------------------------------------------------

#: The largest finite OpenEXR HALF (float16): a larger value would be stored as infinity.
HALF_MAX = 65504.0


def write_exr(
    path: str | os.PathLike,
    channels: Mapping[str, np.ndarray],
    *,
    atomic: bool = True,
    compression: str = "zip",
    half: bool = False,
    grey: bool = False,
    attributes: Mapping[str, str] | None = None,
) -> None:
    """Write channels ``{name: (rows, cols)}`` to a scanline EXR, float32 or half.

    Channel names ``R, G, B, A`` are written as such; an ``(rows, cols, 3|4)``
    array under the key ``"RGB"``/``"RGBA"`` is split into them.
    ``compression``: ``"zip"``, ``"none"`` (float32 bake data compresses
    by under 10%, at five times the writing time) or ``"pxr24"`` (OpenEXR's
    24-bit float: float32's range with 2^-16 relative precision, the lowest
    8 bits of a float32 rounded away; 35% fewer bytes than ZIP on noisy
    float32 data; lossless on half).

    ``half``: each channel as OpenEXR HALF (11 significant bits: 2^-11
    relative from 6.1e-5 up; below that steps of 6e-8), about half the bytes
    and time; a channel with a finite value beyond :data:`HALF_MAX` stays
    float32 rather than turn infinite. The default, float32, is for data that
    is read back as it was computed (the bake cache, the check's references).
    ``grey``: an ``"RGB"``/``"RGBA"`` array whose R, G and B are bitwise equal
    is written as one ``Y`` channel (and ``A``): lossless, a third of the
    bytes; :func:`read_rgb_exr` reads either back as RGB.
    ``attributes``: string attributes for the header (:func:`read_exr_attributes` reads them back).
    """
    chans: dict[str, np.ndarray] = {}
    for name, arr in channels.items():
        arr = np.asarray(arr, dtype=np.float32)
        if name in ("RGB", "RGBA"):
            chans.update(_split_colour(name, arr, grey))
        else:
            chans[name] = np.ascontiguousarray(arr)
    if half:
        chans = {name: _as_half(arr) for name, arr in chans.items()}
    codec = {
        "zip": OpenEXR.ZIP_COMPRESSION,
        "none": OpenEXR.NO_COMPRESSION,
        "pxr24": OpenEXR.PXR24_COMPRESSION,
    }[compression]
    header = {**dict(attributes or {}), "compression": codec, "type": OpenEXR.scanlineimage}
    target = Path(path)
    ctx = atomic_path(target) if atomic else contextlib.nullcontext(target)
    with ctx as tmp:
        try:
            with OpenEXR.File(header, chans) as f:
                f.write(str(tmp))
        except RuntimeError as exc:  # OpenEXR's text for what the OS said
            raise _write_error(exc, target) from None


#: The OS errors an EXR write reports in its own words, by their text (OpenEXR raises RuntimeError).
_WRITE_ERRNOS = (errno.ENOSPC, errno.EFBIG, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EIO)


def _write_error(exc: RuntimeError, target: Path) -> Exception:
    """Return the :class:`OSError` a library's write error stands for, naming ``target``.

    A full disk is ENOSPC, a file too large EFBIG; the error names ``target`` rather than its temporary name.
    Any other error becomes one line naming ``target``.
    """
    text = str(exc)
    for code in _WRITE_ERRNOS:
        if os.strerror(code) in text:
            return OSError(code, os.strerror(code), str(target))
    return InputError(target, f"cannot be written ({first_line(exc)})")


def _split_colour(name: str, arr: np.ndarray, grey: bool) -> dict[str, np.ndarray]:
    """Return the colour channels of an ``(rows, cols, 3|4)`` float32 array by name.

    They are ``{"R": .., "G": .., "B": ..[, "A": ..]}``, or ``{"Y": ..[, "A": ..]}`` with ``grey`` when R, G
    and B are bitwise equal (NaNs and signed zeros included, so nothing is lost).
    """
    planes = {c: np.ascontiguousarray(arr[..., k]) for k, c in enumerate(name)}
    if grey and is_grey(arr[..., :3]):
        return {"Y": planes["R"], **({"A": planes["A"]} if "A" in planes else {})}
    return planes


def is_grey(rgb: np.ndarray) -> bool:
    """Check whether the channels of an ``(..., 3)`` array are bitwise equal everywhere.

    Floats are compared as their bits: NaNs and signed zeros included.
    """
    rgb = np.asarray(rgb)
    if rgb.shape[-1:] != (3,):
        return False
    bits = rgb.view(f"u{rgb.itemsize}") if rgb.dtype.kind == "f" else rgb
    return bool(np.array_equal(bits[..., 0], bits[..., 1]) and np.array_equal(bits[..., 1], bits[..., 2]))


def _as_half(arr: np.ndarray) -> np.ndarray:
    """Return a float32 channel as float16 (rounded to nearest) unless that makes a finite value infinite.

    That is a value beyond :data:`HALF_MAX` and its rounding margin.
    """
    with np.errstate(over="ignore"):
        h = arr.astype(np.float16)
    overflow = np.isinf(h)
    if overflow.any() and np.isfinite(arr[overflow]).any():
        return arr
    return h


def read_exr(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Read every channel of the first part of an EXR as float32 ``(rows, cols)`` arrays.

    Raises :class:`InputError` naming the file if it cannot be read.
    """
    if not Path(path).is_file():  # the library would call a missing file "0 parts"
        raise InputError(path, "no such file" if not Path(path).exists() else "not a file")
    with library_output() as printed:
        try:
            with OpenEXR.File(str(path), separate_channels=True) as f:
                return {name: np.asarray(ch.pixels, dtype=np.float32) for name, ch in f.channels().items()}
        except Exception as exc:  # OpenEXR raises bare RuntimeErrors with library text
            error = exc
    # the C library's own diagnosis (e.g. a corrupt chunk) is more telling
    # than the binding's exception, which may only say "0 parts"
    lines = [ln for ln in printed() if "EXR_ERR" in ln] or printed() or [first_line(error)]
    detail = lines[-1].removeprefix(f"{path}: ")
    raise InputError(path, f"truncated or corrupt EXR file: {detail}")


def read_exr_attributes(path: str | os.PathLike) -> dict[str, str]:
    """Return the string attributes of an EXR's first header.

    They are those :func:`write_exr` was given, and any other writer's; ``{}`` for a file that cannot be read
    (:func:`read_exr` names its problem).
    """
    with library_output():
        try:
            with OpenEXR.File(str(path), header_only=True) as f:
                return {k: v for k, v in f.header().items() if isinstance(v, str)}
        except Exception:  # the caller reads the channels too, which reports the damage
            return {}


def read_rgb_exr(path: str | os.PathLike) -> np.ndarray:
    """Return an EXR's colour as ``(rows, cols, 3)`` float32.

    It is its ``R, G, B`` channels, or its grey ``Y`` channel repeated (:func:`write_exr` with ``grey`` stores
    an image with R == G == B so; the sweep's frames are written that way). Half channels come back as
    float32, exactly.

    Raises :class:`InputError` naming the file if it has neither.
    """
    return rgb_of(read_exr(path), path)


def rgb_of(channels: Mapping[str, np.ndarray], path: str | os.PathLike) -> np.ndarray:
    """``(rows, cols, 3)`` float32 of channels read by :func:`read_exr`: R, G, B, else Y as grey."""
    if all(c in channels for c in "RGB"):
        return np.stack([channels[c] for c in "RGB"], axis=-1)
    if "Y" in channels:
        return np.repeat(channels["Y"][..., None], 3, axis=-1)
    raise InputError(path, f"no R, G, B or Y channel (has {', '.join(sorted(channels))})")


@contextlib.contextmanager
def library_output() -> Iterator:
    """Capture what C/C++ libraries print on stdout and stderr (file descriptors 1, 2).

    OpenEXR reports a corrupt file by printing to both before it raises; a
    command line that promises one-line errors must not let that through.
    Yields a function that returns the captured lines.
    """
    for stream in (sys.stdout, sys.stderr):
        stream.flush()
    lines: list[str] = []
    with tempfile.TemporaryFile(mode="w+b") as sink:
        saved = [os.dup(1), os.dup(2)]
        try:
            os.dup2(sink.fileno(), 1)
            os.dup2(sink.fileno(), 2)
            yield lambda: lines
        finally:
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)
            sink.seek(0)
            lines[:] = [ln.strip() for ln in sink.read().decode(errors="replace").splitlines() if ln.strip()]


def run_writers(jobs) -> None:
    """Run the callables ``jobs`` (each writes a file) on the host pool and wait for every one.

    This uses :class:`Writers`.
    """
    with Writers() as writers:
        for job in jobs:
            writers.submit(job)


class Writers:
    """File writers started as given, on the host pool, and awaited when the ``with`` block ends.

    Writers are given by :meth:`submit`; the pool has a thread per core (the image encoders release the GIL).
    A writer's error is raised when the block ends; on it, or on an error or Ctrl-C in the block, the writers
    not yet started are cancelled and the running ones awaited, so that none puts a file into a folder after
    its caller has removed it.
    """

    def __enter__(self) -> "Writers":
        """Start collecting the writes to wait for."""
        self.pending: list = []
        return self

    def submit(self, job) -> None:
        """Start the callable ``job`` (it writes a file) on the host pool."""
        self.pending.append(backend.host_pool().submit(job))

    def wait(self) -> None:
        """Wait for every writer started so far; a writer's error is raised here."""
        for done in self.pending:
            done.result()

    def __exit__(self, kind, error, trace) -> bool:
        """Wait for the writers; on an error, cancel those not yet started and wait for the running ones."""
        try:
            if kind is None:
                self.wait()
        except BaseException:
            kind = BaseException
            raise
        finally:
            if kind is not None:
                for p in self.pending:
                    p.cancel()
                concurrent.futures.wait(self.pending)
        return False


# --------------------------------------------------------------------------
# PNG
# --------------------------------------------------------------------------


class Indexed(NamedTuple):
    """An 8-bit palette image: ``index`` uint8 ``(rows, cols)`` into ``palette`` uint8 ``(n, 3)``.

    The palette holds sRGB colours, ``n <= 256``. It is exact for an image of at most 256 colours (a colour
    map's, a legend's), at about a third of an RGB PNG's bytes; it decodes to ``palette[index]``.
    """

    index: np.ndarray
    palette: np.ndarray

    def rgb(self) -> np.ndarray:
        """Return the image as uint8 ``(rows, cols, 3)``."""
        return self.palette[self.index]


def write_png(
    path: str | os.PathLike,
    pixels: np.ndarray | Indexed,
    *,
    atomic: bool = True,
    compress_level: int = 6,
    grey: bool = False,
    runs: bool = False,
) -> None:
    """Write 8-bit grey/RGB/RGBA, 16-bit grey or palette pixels to a PNG.

    ``pixels`` is ``uint8 (rows, cols[, 3|4])``, ``uint16 (rows, cols)`` or an
    :class:`Indexed` image (a PNG of colour type 3, Pillow's mode ``"P"``).
    Values are written as they are: encode them before calling.
    ``compress_level`` is zlib's, 0 (stored) to 9. ``grey``: an 8-bit RGB
    image whose channels are equal everywhere is written as 8-bit grey
    (``"L"``): lossless, a third of the bytes to compress; it decodes (e.g.
    Pillow's ``convert("RGB")``) to the same RGB pixels. ``runs``: zlib's
    run-length strategy (``Z_RLE``), which looks for repeats of the previous
    byte only: on filtered renders and palette maps at level 1 it is faster
    than the default search and about as small (``benchmarks/bench_png.py``).
    """
    target = Path(path)
    ctx = atomic_path(target) if atomic else contextlib.nullcontext(target)
    if isinstance(pixels, Indexed):
        img = _palette_image(pixels)
        with ctx as tmp:  # without runs, Pillow's own strategy
            img.save(
                tmp,
                format="PNG",
                compress_level=compress_level,
                **({"compress_type": zlib.Z_RLE} if runs else {}),
            )
        return

    # libpng through imagecodecs, each row Paeth-filtered: Pillow tries five filters on every row
    # and keeps the best, 1.7x the time for 1.4% fewer bytes on a rendered frame
    data = imagecodecs.png_encode(
        _png_pixels(pixels, grey),
        level=compress_level,
        strategy=zlib.Z_RLE if runs else None,
        filter=PNG_FILTER,
    )
    with ctx as tmp:
        Path(tmp).write_bytes(data)


#: The PNG row filter :func:`write_png` uses for grey and RGB images (PNG's filter type 4, Paeth):
#: the fewest bytes of the single filters on the sweep's renders (``imagecodecs.PNG.FILTER``).
PNG_FILTER = 128


def _png_pixels(pixels: np.ndarray, grey: bool) -> np.ndarray:
    """Return the pixels :func:`write_png` encodes: uint8 or uint16, grey RGB as one channel with ``grey``."""
    pixels = np.ascontiguousarray(pixels)
    if pixels.dtype not in (np.uint8, np.uint16):
        raise TypeError(f"write_png needs uint8 or uint16 pixels, got {pixels.dtype}")
    if pixels.ndim not in (2, 3) or (pixels.ndim == 3 and pixels.shape[-1] not in (3, 4)):
        raise ValueError(f"write_png needs (rows, cols[, 3|4]) pixels, got {pixels.shape}")
    if pixels.dtype == np.uint16 and pixels.ndim != 2:
        raise ValueError(f"16-bit pixels are written as grey only, got {pixels.shape}")
    if grey and pixels.dtype == np.uint8 and pixels.ndim == 3 and pixels.shape[-1] == 3 and is_grey(pixels):
        pixels = np.ascontiguousarray(pixels[..., 0])
    return pixels


def _palette_image(pixels: Indexed):
    """Return the Pillow image of a palette image (mode ``"P"``), which :func:`write_png` saves."""
    index, palette = np.ascontiguousarray(pixels.index, np.uint8), np.asarray(pixels.palette, np.uint8)
    if index.ndim != 2 or palette.ndim != 2 or palette.shape[1] != 3 or not 1 <= len(palette) <= 256:
        raise ValueError(
            f"an Indexed image needs (rows, cols) indices and 1-256 RGB colours, "
            f"got {index.shape} and {palette.shape}"
        )
    img = Image.frombytes("P", (index.shape[1], index.shape[0]), index.tobytes())
    img.putpalette(palette.tobytes(), rawmode="RGB")
    return img


#: A PNG with more pixels than this on its longer side also gets a preview (:func:`preview_of`)
#: for the report's pages, which a 4096 x 4096 sweep's full images (126 of 8-20 MB) would stall.
PREVIEW_ABOVE_PX = 2048
#: The preview's longer side at most, in pixels: the full image box-filtered by a whole factor.
PREVIEW_PX = 1024


def write_figure(path: str | os.PathLike, fig, **savefig) -> None:
    """Write a matplotlib figure as a PNG at ``path``, atomically.

    The write goes through :func:`atomic_path`, which makes the folder. ``savefig``: matplotlib's own options
    (``dpi``, ``facecolor``, ...).
    """
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", **savefig)


def preview_of(rel: str) -> str:
    """Return where the preview of the PNG ``rel`` lives.

    For example ``frames/az+0/truth.png`` -> ``frames/az+0/previews/truth.png`` (the writer's and the report's
    one convention).
    """
    head, _, name = rel.replace("\\", "/").rpartition("/")
    return f"{head}/previews/{name}" if head else f"previews/{name}"


def write_png_with_preview(path: str | os.PathLike, pixels: np.ndarray | Indexed, **kw) -> bool:
    """Write a PNG by :func:`write_png` and, for a large image, its preview at :func:`preview_of`.

    A preview is written for an image larger than :data:`PREVIEW_ABOVE_PX`: every channel box-averaged over
    ``f x f`` pixels, ``f`` the smallest whole factor that brings it to :data:`PREVIEW_PX`; edges repeated to
    a multiple of ``f``. Returns whether a preview was written.
    """
    write_png(path, pixels, **kw)
    rows, cols = (pixels.index if isinstance(pixels, Indexed) else np.asarray(pixels)).shape[:2]
    if max(rows, cols) <= PREVIEW_ABOVE_PX:
        return False
    rgb = pixels.rgb() if isinstance(pixels, Indexed) else np.asarray(pixels)
    f = -(-max(rows, cols) // PREVIEW_PX)
    pad = [(0, -rows % f), (0, -cols % f)] + [(0, 0)] * (rgb.ndim - 2)
    block = np.pad(rgb, pad, mode="edge").astype(np.float32)
    block = block.reshape(block.shape[0] // f, f, block.shape[1] // f, f, *rgb.shape[2:]).mean(axis=(1, 3))
    small = np.clip(np.rint(block), 0, 255).astype(np.uint8)
    target = Path(path)
    write_png(target.parent / "previews" / target.name, small, **kw)
    return True


def unit_to_u8(values: np.ndarray) -> np.ndarray:
    """Quantise values in [0, 1] to 8 bits, rounding to nearest (as a GPU upload does).

    NaN (a pixel that sees no surface) is 0.
    """
    # the float32 product, then rounded and clipped in place: one temporary, not four
    out = np.multiply(values, np.float32(255.0), dtype=np.float32)
    np.nan_to_num(out, copy=False, nan=0.0)
    np.rint(out, out=out)
    np.clip(out, 0, 255, out=out)
    return out.astype(np.uint8)
