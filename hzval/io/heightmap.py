"""Reading height maps from PNG, EXR and ``.npy`` files.

A height map is ``H[row, col]``, float32, row 0 at the top of the image as
displayed (:mod:`hzval.core.conventions`). PNG samples are *data*, not colour: 8-
and 16-bit values are divided by 255 and 65535 and are not sRGB-decoded,
because a height map's encoder wrote heights, not light. EXR and ``.npy``
values are taken as they are. Colour inputs are reduced to their luminance
``Y = w . rgb`` on the stored values, with the weights of
:func:`hzval.core.srgb.luminance_weights`; alpha never contributes.

Every failure is an :class:`~hzval.core.errors.InputError` naming the file: the
command line prints it as one line, and a height map that is truncated,
corrupt or not finite must never become silently wrong heights.

Pillow reduces 16-bit RGB, RGBA and grey+alpha PNGs to 8 bits (Pillow 13
has no 16-bit colour mode), so those are decoded with pypng, which keeps all
16 bits; pypng is pure Python and much slower, so every other PNG goes through Pillow.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import stat
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator

import numpy as np
import OpenEXR
import png
from PIL import Image, ImageFile, UnidentifiedImageError

from hzval.core.errors import InputError, first_line
from hzval.core.srgb import luminance_weights
from hzval.io.codecs import library_output, read_exr

__all__ = ["SUFFIXES", "MIN_SIDE", "HeightMap", "probe_shape", "load_height", "check_usable", "from_array"]

_PathLike = str | os.PathLike

_LUMINANCE = "luminance (Rec. 709 weights)"

_MAGIC = {b"\x89PNG\r\n\x1a\n": "png", b"v/1\x01": "exr", b"\x93NUMPY": "npy"}
_KIND_BY_EXTENSION = {".png": "png", ".exr": "exr", ".npy": "npy"}
#: The suffixes height map files have (a file is read by its content, whatever its name): hzval's
#: own formats, then the images Pillow reads that a height map comes as.
SUFFIXES: tuple[str, ...] = (*_KIND_BY_EXTENSION, ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".webp")
_KIND_NAME = {"png": "PNG", "exr": "EXR", "npy": ".npy", "pillow": "image"}
#: The smallest height map a file may hold: a smaller one has hardly a shadow to cast, and every
#: score of it is noise.
MIN_SIDE = 8

#: PNG colour types (IHDR) by name, and those that carry RGB.
_PNG_COLOUR_TYPES = {0: "grey", 2: "RGB", 3: "palette", 4: "grey+alpha", 6: "RGBA"}
_PNG_RGB_TYPES = (2, 3, 6)
#: 16-bit colour types that Pillow would reduce to 8 bits.
_PNG_PYPNG_TYPES = (2, 4, 6)
#: Pillow modes converted before reading the samples: both give 8-bit data.
_PILLOW_CONVERSIONS = {"1": "L", "P": "RGB"}


@dataclass(frozen=True)
class HeightMap:
    """A height map and where it came from.

    ``height`` is float32 ``(rows, cols)``, C-contiguous, row 0 at the top;
    PNG values are normalised to [0, 1], EXR and ``.npy`` values are as
    stored. ``digest`` (``"sha256:<hex>"``) identifies the input in reports
    and bake records: of the file's bytes, or for a generated map of its
    shape and float32 values (see :func:`from_array`).
    """

    height: np.ndarray
    path: str | None
    source: str
    digest: str

    @property
    def colour(self) -> bool:
        """Whether the file held colour, reduced to its luminance (the caller says so)."""
        return _LUMINANCE in self.source


def probe_shape(path: _PathLike) -> tuple[int, int]:
    """``(rows, cols)`` of a height map file, read from its header alone.

    No pixels are decoded, so size limits can be checked before paying for
    (or being bombed by) a decode. Raises :class:`InputError` for a file
    that is missing or not a PNG, EXR or ``.npy`` with a readable header.
    """
    return _probe(path)[1]


def load_height(path: _PathLike, *, max_pixels: int | None = None) -> HeightMap:
    """Read a PNG, EXR or ``.npy`` height map.

    The format is decided by the file's content, not its name. A map with
    more than ``max_pixels`` pixels is refused before it is decoded. Raises
    :class:`InputError`, and nothing else, for any file it cannot use.
    """
    kind, (rows, cols) = _probe(path)
    _check_size(path, rows, cols, max_pixels)
    height, source = _LOADERS[kind](path)
    height = _validated(path, height)
    return HeightMap(height, os.fspath(path), source, _file_digest(path))


def check_usable(hm: HeightMap) -> HeightMap:
    """Refuse, in one line naming the file, a height map smaller than :data:`MIN_SIDE` texels a side.

    A flat one runs: it is the null test where every technique must give ``F = 1``.

    Parameters
    ----------
    hm : HeightMap

    Returns
    -------
    HeightMap
        ``hm``, when it is usable.

    Raises
    ------
    hzval.core.errors.InputError
    """
    rows, cols = hm.height.shape
    what = hm.path or hm.source
    if rows < MIN_SIDE or cols < MIN_SIDE:
        raise InputError(what, f"is {cols}x{rows} texels; a height map needs at least {MIN_SIDE}x{MIN_SIDE}")
    # a flat map runs: nothing casts a shadow, so every technique must give F = 1 (a null test of the
    # shading, exposure and colour pipeline); the sweep's few-shadows warning says so
    return hm


def from_array(height: np.ndarray, *, source: str = "array") -> HeightMap:
    """Wrap a generated height map, with the checks a file gets.

    Its digest hashes the shape (two little-endian int64) and the float32
    values (little-endian), so equal maps get equal digests on any machine.
    """
    height = np.asarray(height)
    _check_dtype(source, height.dtype)
    height = _validated(source, height)
    digest = hashlib.sha256(np.asarray(height.shape, dtype="<i8").tobytes())
    digest.update(height.astype("<f4", copy=False))
    return HeightMap(height, None, source, "sha256:" + digest.hexdigest())


# --------------------------------------------------------------------------
# Checks shared by every format
# --------------------------------------------------------------------------


def _check_size(what: _PathLike, rows: int, cols: int, max_pixels: int | None = None) -> None:
    pixels = rows * cols
    if pixels < 2:  # the command line's rule (check_usable), in its words
        raise InputError(what, f"is {cols}x{rows} texels; a height map needs at least {MIN_SIDE}x{MIN_SIDE}")
    if max_pixels is not None and pixels > max_pixels:
        raise InputError(
            what,
            f"image is {rows}x{cols} pixels (rows x columns, {pixels:,} in all); "
            f"the limit here is {max_pixels:,}",
        )


def _check_dtype(what: _PathLike, dtype: np.dtype) -> None:
    if not (np.issubdtype(dtype, np.integer) or np.issubdtype(dtype, np.floating)):
        raise InputError(what, f"array has dtype {dtype}; a height map needs real numbers")


def _plane_shape(what: _PathLike, shape: tuple[int, ...]) -> tuple[int, int]:
    """``(rows, cols)`` of an array shaped ``(rows, cols)`` or ``(rows, cols, 1)``."""
    if len(shape) == 2 or (len(shape) == 3 and shape[2] == 1):
        return shape[0], shape[1]
    raise InputError(what, f"array has shape {shape}; a height map needs (rows, cols) or (rows, cols, 1)")


def _validated(what: _PathLike, height: np.ndarray) -> np.ndarray:
    """``height`` as C-contiguous float32 ``(rows, cols)``, or an InputError."""
    rows, cols = _plane_shape(what, height.shape)
    _check_size(what, rows, cols)
    height = height.reshape(rows, cols)
    with np.errstate(over="ignore"):  # overflow is reported below, with the count
        values = np.ascontiguousarray(height, dtype=np.float32)
    if not np.isfinite(values).all():
        nan = int(np.isnan(values).sum())
        inf = int(np.isinf(values).sum())
        overflow = inf - int(np.isinf(height).sum())
        beyond = f" ({overflow} of them finite but beyond float32's range)" if overflow else ""
        raise InputError(what, f"contains {nan} NaN and {inf} infinite values{beyond}")
    return values


# --------------------------------------------------------------------------
# Files: what they are, and their headers
# --------------------------------------------------------------------------


def _open(path: _PathLike):
    try:
        return open(path, "rb")
    except OSError as exc:
        raise InputError(path, f"cannot read ({exc.strerror or exc})") from None


def _kind(path: _PathLike) -> str:
    """``"png"``, ``"exr"`` or ``"npy"`` from the magic bytes.

    The extension only sharpens the error for a file that matches none: a
    ``.png`` that is not one is reported as such.
    """
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except OSError as exc:
        raise InputError(path, f"cannot read ({exc.strerror or exc})") from None
    if stat.S_ISDIR(mode):
        raise InputError(path, "is a directory, not a file")
    if not stat.S_ISREG(mode):
        raise InputError(path, "not a regular file")
    with _open(path) as f:
        head = f.read(8)
    if not head:
        raise InputError(path, "file is empty")
    for magic, kind in _MAGIC.items():
        if head.startswith(magic):
            return kind
        if magic.startswith(head):
            raise InputError(path, f"truncated {_KIND_NAME[kind]} file ({len(head)} bytes)")
    named = _KIND_BY_EXTENSION.get(Path(path).suffix.lower())
    if named is None and _pillow_reads(path):
        return "pillow"  # JPEG, TIFF, BMP, WebP, ...: whatever Pillow reads, as a grey or colour image
    if named is not None:
        raise InputError(
            path, f"not a {_KIND_NAME[named]} file (no {_KIND_NAME[named]} signature at its start)"
        )
    raise InputError(
        path, "not an image hzval reads: PNG, EXR, .npy, or any image Pillow opens (JPEG, TIFF, ...)"
    )


def _probe(path: _PathLike) -> tuple[str, tuple[int, int]]:
    kind = _kind(path)
    return kind, _PROBES[kind](path)


def _file_digest(path: _PathLike) -> str:
    with _open(path) as f:
        return "sha256:" + hashlib.file_digest(f, "sha256").hexdigest()


@contextlib.contextmanager
def _pillow_strict() -> Iterator[None]:
    """Pillow's globals as hzval needs them, restored afterwards.

    Pillow's decompression-bomb limit is off: ``max_pixels`` is ours to
    enforce, before decoding and with a clearer message. Truncated data is
    an error, never zero-filled heights.
    """
    saved = Image.MAX_IMAGE_PIXELS, ImageFile.LOAD_TRUNCATED_IMAGES
    Image.MAX_IMAGE_PIXELS, ImageFile.LOAD_TRUNCATED_IMAGES = None, False
    try:
        yield
    finally:
        Image.MAX_IMAGE_PIXELS, ImageFile.LOAD_TRUNCATED_IMAGES = saved


# --------------------------------------------------------------------------
# PNG
# --------------------------------------------------------------------------


def _png_corrupt(path: _PathLike, exc: BaseException) -> InputError:
    return InputError(path, f"truncated or corrupt PNG ({first_line(exc)})")


def _probe_png(path: _PathLike) -> tuple[int, int]:
    try:
        with _pillow_strict(), Image.open(path, formats=["PNG"]) as img:  # reads the header only
            cols, rows = img.size
    except UnidentifiedImageError:  # its text only repeats the path
        raise InputError(path, "truncated or corrupt PNG (unreadable header chunks)") from None
    except Exception as exc:  # Pillow raises many types for bad headers
        raise _png_corrupt(path, exc) from None
    return rows, cols


def _png_header(path: _PathLike) -> tuple[int, int]:
    """``(bit depth, colour type)`` from the IHDR chunk, which the PNG spec puts first."""
    with _open(path) as f:
        head = f.read(26)
    if len(head) < 26 or head[12:16] != b"IHDR":
        raise InputError(path, "truncated or corrupt PNG (no IHDR chunk first)")
    return head[24], head[25]


def _load_png(path: _PathLike) -> tuple[np.ndarray, str]:
    bit_depth, colour_type = _png_header(path)
    if bit_depth == 16 and colour_type in _PNG_PYPNG_TYPES:
        samples, transparency = _decode_png_pypng(path)
    else:
        samples, transparency = _decode_png_pillow(path)
    if colour_type in _PNG_RGB_TYPES:
        data = samples[..., :3] @ luminance_weights()
        via_rgb = " -> RGB" if colour_type == 3 else ""
        source = f"{_PNG_COLOUR_TYPES[colour_type]}{via_rgb} -> {_LUMINANCE}"
    else:
        data = samples[..., 0]
        source = _PNG_COLOUR_TYPES[colour_type]
    if transparency or colour_type in (4, 6):
        source += ", alpha ignored"
    height = data / (65535.0 if bit_depth == 16 else 255.0)
    return height, f"{bit_depth}-bit PNG, {source}"


def _decode_png_pillow(path: _PathLike) -> tuple[np.ndarray, bool]:
    """Return the samples ``(rows, cols, planes)`` and whether the file has tRNS.

    1-bit grey and palettes are converted to 8 bits, and Pillow scales 2- and
    4-bit grey to 0..255, so that every sample counts in 255ths (65535ths for
    16-bit grey) whatever the bit depth.
    """
    try:
        with _pillow_strict():
            with Image.open(path, formats=["PNG"]) as img:
                img.load()
                transparency = "transparency" in img.info
                if img.mode in _PILLOW_CONVERSIONS:
                    img = img.convert(_PILLOW_CONVERSIONS[img.mode])
                samples = np.asarray(img)
            with Image.open(path, formats=["PNG"]) as img:
                img.verify()  # chunk checksums: load() does not check IDAT's
    except Exception as exc:  # Pillow raises many types for bad data
        raise _png_corrupt(path, exc) from None
    return samples.reshape(samples.shape[0], samples.shape[1], -1), transparency


def _decode_png_pypng(path: _PathLike) -> tuple[np.ndarray, bool]:
    """16-bit samples ``(rows, cols, planes)`` of a colour or grey+alpha PNG, and whether it has tRNS."""
    with _open(path) as f:
        try:
            cols, rows, lines, info = png.Reader(file=f).read()
            samples = np.vstack([np.frombuffer(line, dtype=np.uint16) for line in lines])
        except Exception as exc:  # pypng's own errors, zlib's, and short reads
            raise _png_corrupt(path, exc) from None
    return samples.reshape(rows, cols, info["planes"]), "transparent" in info


# --------------------------------------------------------------------------
# EXR
# --------------------------------------------------------------------------


def _probe_exr(path: _PathLike) -> tuple[int, int]:

    with library_output():  # the C library prints its complaints; we raise ours
        try:
            with OpenEXR.File(os.fspath(path), header_only=True) as f:
                (xmin, ymin), (xmax, ymax) = f.header()["dataWindow"]
        except Exception as exc:  # OpenEXR raises bare RuntimeErrors with library text
            raise InputError(path, f"not a readable EXR file ({first_line(exc)})") from None
    return int(ymax - ymin + 1), int(xmax - xmin + 1)


def _load_exr(path: _PathLike) -> tuple[np.ndarray, str]:
    """Channel Y, else the luminance of R, G, B, else the only channel besides A."""
    channels = read_exr(path)
    alpha = ", alpha ignored" if "A" in channels else ""
    if "Y" in channels:
        return channels["Y"], f"EXR channel Y{alpha}"
    if {"R", "G", "B"} <= channels.keys():
        if len({channels[c].shape for c in "RGB"}) != 1:
            raise InputError(
                path, "EXR channels R, G, B differ in size (subsampled); a height map needs them equal"
            )
        rgb = np.stack([channels[c] for c in "RGB"], axis=-1)
        return rgb @ luminance_weights(), f"EXR channels R, G, B -> {_LUMINANCE}{alpha}"
    others = [name for name in channels if name != "A"]
    if len(others) != 1:
        raise InputError(
            path,
            f"EXR has channels {', '.join(sorted(channels)) or '(none)'}; "
            "a height map needs Y, or R, G and B, or a single channel",
        )
    return channels[others[0]], f"EXR channel {others[0]}{alpha}"


# --------------------------------------------------------------------------
# .npy
# --------------------------------------------------------------------------

_NPY_HEADER_READERS = {
    (1, 0): np.lib.format.read_array_header_1_0,
    (2, 0): np.lib.format.read_array_header_2_0,
}


def _npy_header(path: _PathLike) -> tuple[tuple[int, ...], np.dtype]:
    with _open(path) as f:
        try:
            version = np.lib.format.read_magic(f)
            if version not in _NPY_HEADER_READERS:
                raise ValueError(f"format version {version[0]}.{version[1]} is not supported")
            shape, _, dtype = _NPY_HEADER_READERS[version](f)
        except Exception as exc:  # NumPy raises ValueError for bad headers
            raise InputError(path, f"unreadable .npy header ({first_line(exc)})") from None
    return shape, dtype


def _probe_npy(path: _PathLike) -> tuple[int, int]:
    return _plane_shape(path, _npy_header(path)[0])


def _load_npy(path: _PathLike) -> tuple[np.ndarray, str]:
    _, dtype = _npy_header(path)
    _check_dtype(path, dtype)  # before np.load, which would refuse object arrays less clearly
    try:
        height = np.load(path, allow_pickle=False)
    except Exception as exc:  # short data: ValueError or EOFError
        raise InputError(path, f"truncated or corrupt .npy file ({first_line(exc)})") from None
    return height, f".npy {dtype.name}"


# --------------------------------------------------------------------------
# Any other image Pillow reads
# --------------------------------------------------------------------------


def _pillow_reads(path: _PathLike) -> bool:
    try:
        with _pillow_strict(), Image.open(path) as img:
            return img.size[0] > 0
    except Exception:  # not an image Pillow knows
        return False


def _probe_pillow(path: _PathLike) -> tuple[int, int]:
    with _pillow_strict(), Image.open(path) as img:
        return img.size[1], img.size[0]


#: Pillow's grey modes and the value of their white.
_PILLOW_GREY = {"L": 255.0, "I;16": 65535.0, "I;16B": 65535.0, "I": 1.0, "F": 1.0}


def _load_pillow(path: _PathLike) -> tuple[np.ndarray, str]:
    """Return a grey image's samples over its white, or a colour image's 8-bit luminance.

    Grey samples of 8 and 16 bits give data in [0, 1]; 32-bit integer and float ones come as stored. A colour
    image goes through Pillow's conversion to RGB first.
    """
    try:
        with _pillow_strict(), Image.open(path) as img:
            img.load()
            fmt, mode = img.format or "image", img.mode
            if mode in _PILLOW_GREY:
                return np.asarray(img, np.float64) / _PILLOW_GREY[mode], f"{fmt} {mode}"
            rgb = np.asarray(img.convert("RGB"), np.float64) / 255.0
    except (OSError, ValueError, SyntaxError) as exc:
        raise InputError(path, f"truncated or corrupt image ({first_line(exc)})") from None
    return rgb @ luminance_weights(), f"{fmt} {mode} -> {_LUMINANCE}"


_PROBES: dict[str, Callable[[_PathLike], tuple[int, int]]] = {
    "png": _probe_png,
    "exr": _probe_exr,
    "npy": _probe_npy,
    "pillow": _probe_pillow,
}
_LOADERS: dict[str, Callable[[_PathLike], tuple[np.ndarray, str]]] = {
    "png": _load_png,
    "exr": _load_exr,
    "npy": _load_npy,
    "pillow": _load_pillow,
}
