"""Reading and writing hzval's files: EXR (OpenEXR), PNG (Pillow), JSON.

Every writer is atomic: it writes to a hidden temporary name in the target
folder and renames it into place (``os.replace``), so a reader never sees a
partial file and a crash leaves no corrupt output behind. :class:`Staging`
extends that to a whole set of outputs: nothing appears in the output folder
until every file has been written.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import os
import shutil
import socket
import tempfile
import time
from pathlib import Path
from typing import Iterator, Mapping, NamedTuple

import numpy as np

from hzval.errors import InputError


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it to ``path`` on success.

    On an exception the temporary file is removed and ``path`` is untouched.
    The file gets the permissions a plain ``open`` would give it (``0666``
    less the umask), not ``mkstemp``'s private ``0600``: reports are shared.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp" + path.suffix, dir=path.parent)
    os.close(fd)
    tmp = Path(tmp)
    try:
        yield tmp
        if tmp.exists():
            os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def _umask() -> int:
    """The process's umask (read by setting it and setting it back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


#: The lock file of an output folder (:func:`folder_lock`).
LOCK_NAME = ".hzval-lock"


@contextlib.contextmanager
def folder_lock(folder: str | os.PathLike, command: str = "") -> Iterator[Path]:
    """Hold ``folder`` for this run: an exclusive ``flock`` on ``folder/.hzval-lock``.

    A second run into the same folder fails at once with an :class:`InputError`
    naming the run that holds it (host, pid, start time and command, which
    the holder writes into the lock file). The kernel drops the lock when its
    process ends, however it ends, so a crashed run leaves no stale lock. A
    folder this creates and the run leaves empty is removed again: a run
    refused for bad input leaves nothing behind.
    """
    import fcntl

    folder = Path(folder)
    created = not folder.exists()
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / LOCK_NAME
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 4096, 0).decode("utf-8", "replace").strip() or "another run"
            raise InputError(folder, f"in use by another hzval run ({holder}); wait for it or choose "
                                     "another --out") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, (f"{socket.gethostname()} pid {os.getpid()}, since "
                       f"{time.strftime('%Y-%m-%d %H:%M:%S')}: {command or 'hzval'}").encode(), 0)
        yield path
    finally:
        if created and [p.name for p in folder.iterdir()] == [LOCK_NAME]:
            path.unlink(missing_ok=True)
            with contextlib.suppress(OSError):
                folder.rmdir()
        os.close(fd)                 # releases the lock


def file_digest(path: str | os.PathLike) -> str:
    """``"sha256:<hex>"`` of a file's bytes."""
    with open(path, "rb") as f:
        return "sha256:" + hashlib.file_digest(f, "sha256").hexdigest()


class Staging:
    """Collect a set of output files, then move them into ``out`` together.

    Files are written under a hidden folder inside ``out`` (same file system,
    so the final moves are renames). :meth:`commit` moves each into place;
    leaving the ``with`` block without committing removes everything staged.
    ``out`` itself is created only on :meth:`commit`, or if it is needed to
    hold the staging folder.
    """

    def __init__(self, out: str | os.PathLike):
        self.out = Path(out)
        self._created_out = not self.out.exists()
        self.out.mkdir(parents=True, exist_ok=True)
        self.dir = Path(tempfile.mkdtemp(prefix=".hzval-staging-", dir=self.out))
        self._committed = False

    def path(self, name: str) -> Path:
        """Path in the staging folder for the output called ``name`` (may contain '/')."""
        p = self.dir / name
        p.parent.mkdir(parents=True, exist_ok=True)
        return p

    def commit(self) -> list[Path]:
        """Move every staged file to its place under ``out``; return the final paths."""
        final = []
        for src in sorted(p for p in self.dir.rglob("*") if p.is_file()):
            dst = self.out / src.relative_to(self.dir)
            dst.parent.mkdir(parents=True, exist_ok=True)
            os.replace(src, dst)
            final.append(dst)
        shutil.rmtree(self.dir, ignore_errors=True)
        self._committed = True
        return final

    def swap(self) -> None:
        """Put each staged top-level entry in place of ``out``'s entry of that name, whole: a folder
        replaces the old folder (none of its old files survive), a file the old file. Each swap is
        two renames, so a reader sees the old entry or the new one."""
        for src in sorted(self.dir.iterdir()):
            dst = self.out / src.name
            if src.is_dir() and dst.is_dir():
                old = Path(tempfile.mkdtemp(prefix=".hzval-old-", dir=self.out))
                os.replace(dst, old / src.name)
                os.replace(src, dst)
                shutil.rmtree(old, ignore_errors=True)
            else:
                if dst.is_dir():
                    shutil.rmtree(dst)
                os.replace(src, dst)
        shutil.rmtree(self.dir, ignore_errors=True)
        self._committed = True

    @staticmethod
    def remove_leftovers(out: str | os.PathLike) -> None:
        """Remove the staging folders a killed run left in ``out`` (call it holding :func:`folder_lock`)."""
        for p in Path(out).glob(".hzval-staging-*"):
            shutil.rmtree(p, ignore_errors=True)
        for p in Path(out).glob(".hzval-old-*"):
            shutil.rmtree(p, ignore_errors=True)

    def __enter__(self) -> "Staging":
        return self

    def __exit__(self, *exc) -> None:
        if not self._committed:
            shutil.rmtree(self.dir, ignore_errors=True)
            if self._created_out:
                with contextlib.suppress(OSError):
                    self.out.rmdir()  # only if empty


# --------------------------------------------------------------------------
# EXR
# --------------------------------------------------------------------------

#: The largest finite OpenEXR HALF (float16): a larger value would be stored as infinity.
HALF_MAX = 65504.0


def write_exr(path: str | os.PathLike, channels: Mapping[str, np.ndarray], *, atomic: bool = True,
              compression: str = "zip", half: bool = False, grey: bool = False) -> None:
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
    """
    import OpenEXR

    chans: dict[str, np.ndarray] = {}
    for name, arr in channels.items():
        arr = np.asarray(arr, dtype=np.float32)
        if name in ("RGB", "RGBA"):
            chans.update(_split_colour(name, arr, grey))
        else:
            chans[name] = np.ascontiguousarray(arr)
    if half:
        chans = {name: _as_half(arr) for name, arr in chans.items()}
    codec = {"zip": OpenEXR.ZIP_COMPRESSION, "none": OpenEXR.NO_COMPRESSION,
             "pxr24": OpenEXR.PXR24_COMPRESSION}[compression]
    header = {"compression": codec, "type": OpenEXR.scanlineimage}
    target = Path(path)
    ctx = atomic_path(target) if atomic else contextlib.nullcontext(target)
    with ctx as tmp:
        with OpenEXR.File(header, chans) as f:
            f.write(str(tmp))


def _split_colour(name: str, arr: np.ndarray, grey: bool) -> dict[str, np.ndarray]:
    """``{"R": .., "G": .., "B": ..[, "A": ..]}`` of an ``(rows, cols, 3|4)`` float32 array, or
    ``{"Y": ..[, "A": ..]}`` with ``grey`` when R, G and B are bitwise equal (NaNs and signed zeros
    included, so nothing is lost)."""
    planes = {c: np.ascontiguousarray(arr[..., k]) for k, c in enumerate(name)}
    if grey and is_grey(arr[..., :3]):
        return {"Y": planes["R"], **({"A": planes["A"]} if "A" in planes else {})}
    return planes


def is_grey(rgb: np.ndarray) -> bool:
    """Whether the channels of an ``(..., 3)`` array are bitwise equal everywhere (floats compared as
    their bits: NaNs and signed zeros included)."""
    rgb = np.asarray(rgb)
    if rgb.shape[-1:] != (3,):
        return False
    bits = rgb.view(f"u{rgb.itemsize}") if rgb.dtype.kind == "f" else rgb
    return bool(np.array_equal(bits[..., 0], bits[..., 1]) and np.array_equal(bits[..., 1], bits[..., 2]))


def _as_half(arr: np.ndarray) -> np.ndarray:
    """A float32 channel as float16 (rounded to nearest), unless a finite value would become infinite
    (beyond :data:`HALF_MAX` and its rounding margin)."""
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
    import OpenEXR

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


def read_rgb_exr(path: str | os.PathLike) -> np.ndarray:
    """An EXR's colour as ``(rows, cols, 3)`` float32: its ``R, G, B`` channels, or its grey ``Y``
    channel repeated (:func:`write_exr` with ``grey`` stores an image with R == G == B so; the
    sweep's frames are written that way). Half channels come back as float32, exactly.

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
    import sys

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
    """Run the callables ``jobs`` (each writes a file) on the host pool, a thread per core (the
    image encoders release the GIL), and wait for every one. A writer's error is re-raised here; on
    it, or Ctrl-C, the writers not yet started are cancelled and the running ones awaited, so that
    none puts a file into a folder after its caller has removed it."""
    import concurrent.futures

    from hzval import backend

    pending = [backend.host_pool().submit(job) for job in jobs]
    try:
        for done in pending:
            done.result()
    except BaseException:
        for p in pending:
            p.cancel()
        concurrent.futures.wait(pending)
        raise


# --------------------------------------------------------------------------
# PNG
# --------------------------------------------------------------------------

class Indexed(NamedTuple):
    """An 8-bit palette image: ``index`` uint8 ``(rows, cols)`` into ``palette`` uint8 ``(n, 3)``
    sRGB colours, ``n <= 256``. Exact for an image of at most 256 colours (a colour map's, a
    legend's), at about a third of an RGB PNG's bytes; it decodes to ``palette[index]``."""

    index: np.ndarray
    palette: np.ndarray

    def rgb(self) -> np.ndarray:
        """The image as uint8 ``(rows, cols, 3)``."""
        return self.palette[self.index]


def write_png(path: str | os.PathLike, pixels: np.ndarray | Indexed, *, atomic: bool = True,
              compress_level: int = 6, grey: bool = False) -> None:
    """Write 8-bit grey/RGB/RGBA, 16-bit grey or palette pixels to a PNG.

    ``pixels`` is ``uint8 (rows, cols[, 3|4])``, ``uint16 (rows, cols)`` or an
    :class:`Indexed` image (a PNG of colour type 3, Pillow's mode ``"P"``).
    Values are written as they are: encode them before calling.
    ``compress_level`` is zlib's, 0 (stored) to 9. ``grey``: an 8-bit RGB
    image whose channels are equal everywhere is written as 8-bit grey
    (``"L"``): lossless, a third of the bytes to compress; it decodes (e.g.
    Pillow's ``convert("RGB")``) to the same RGB pixels.
    """
    target = Path(path)
    img = _png_image(pixels, grey)
    ctx = atomic_path(target) if atomic else contextlib.nullcontext(target)
    with ctx as tmp:
        img.save(tmp, format="PNG", compress_level=compress_level)


def _png_image(pixels: np.ndarray | Indexed, grey: bool):
    """The Pillow image :func:`write_png` saves."""
    from PIL import Image

    if isinstance(pixels, Indexed):
        index, palette = np.ascontiguousarray(pixels.index, np.uint8), np.asarray(pixels.palette, np.uint8)
        if index.ndim != 2 or palette.ndim != 2 or palette.shape[1] != 3 or not 1 <= len(palette) <= 256:
            raise ValueError(f"an Indexed image needs (rows, cols) indices and 1-256 RGB colours, "
                             f"got {index.shape} and {palette.shape}")
        img = Image.frombytes("P", (index.shape[1], index.shape[0]), index.tobytes())
        img.putpalette(palette.tobytes(), rawmode="RGB")
        return img
    pixels = np.ascontiguousarray(pixels)
    if pixels.dtype not in (np.uint8, np.uint16):
        raise TypeError(f"write_png needs uint8 or uint16 pixels, got {pixels.dtype}")
    if grey and pixels.dtype == np.uint8 and pixels.ndim == 3 and pixels.shape[-1] == 3 and is_grey(pixels):
        pixels = np.ascontiguousarray(pixels[..., 0])
    return Image.fromarray(pixels)      # uint16 (rows, cols): 16-bit grey ("I;16")


#: A PNG with more pixels than this on its longer side also gets a preview (:func:`preview_of`)
#: for the report's pages, which a 4096 x 4096 sweep's full images (126 of 8-20 MB) would stall.
PREVIEW_ABOVE_PX = 2048
#: The preview's longer side at most, in pixels: the full image box-filtered by a whole factor.
PREVIEW_PX = 1024


def preview_of(rel: str) -> str:
    """Where the preview of the PNG ``rel`` lives: ``frames/az+0/truth.png`` ->
    ``frames/az+0/previews/truth.png`` (the writer's and the report's one convention)."""
    head, _, name = rel.replace("\\", "/").rpartition("/")
    return f"{head}/previews/{name}" if head else f"previews/{name}"


def write_png_with_preview(path: str | os.PathLike, pixels: np.ndarray | Indexed, **kw) -> bool:
    """:func:`write_png`, and, for an image larger than :data:`PREVIEW_ABOVE_PX`, its preview at
    :func:`preview_of` (every channel box-averaged over ``f x f`` pixels, ``f`` the smallest whole
    factor that brings it to :data:`PREVIEW_PX`; edges repeated to a multiple of ``f``). Returns
    whether a preview was written."""
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
    """Quantise values in [0, 1] to 8 bits, rounding to nearest (as a GPU upload does)."""
    # the float32 product, then rounded and clipped in place: one temporary, not four
    out = np.multiply(values, np.float32(255.0), dtype=np.float32)
    np.rint(out, out=out)
    np.clip(out, 0, 255, out=out)
    return out.astype(np.uint8)


# --------------------------------------------------------------------------
# JSON
# --------------------------------------------------------------------------

def write_json(path: str | os.PathLike, data, *, atomic: bool = True) -> None:
    """Write ``data`` as indented JSON, atomically."""
    text = json.dumps(data, indent=2, sort_keys=False, default=_json_default) + "\n"
    target = Path(path)
    ctx = atomic_path(target) if atomic else contextlib.nullcontext(target)
    with ctx as tmp:
        tmp.write_text(text, encoding="utf-8")


def _json_default(obj):
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return dataclasses.asdict(obj)
    raise TypeError(f"cannot serialise {type(obj).__name__}")


def first_line(exc: BaseException) -> str:
    """The first line of an exception's message, for one-line errors."""
    text = str(exc).strip() or type(exc).__name__
    return text.splitlines()[0]
