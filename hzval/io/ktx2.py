"""KTX 2.0 textures, written and read by hand: what an engine loads, with BC formats and mips.

No Python package with wheels writes KTX2 here (pyktx has none, libktx is not packaged), and the
container is small: a header, a level index, a Data Format Descriptor (DFD), key/value data and
the levels' bytes (Khronos, "KTX File Format Specification", version 2.0). This module writes
and reads the subset hzval exports: 2-D textures, one layer, one face, a full mip chain, stored
as-is or supercompressed with Zstandard (scheme 2; imagecodecs' zstd, a dependency already).

:data:`FORMATS` holds each format's ``VkFormat`` and its DFD: uncompressed 8-bit UNORM and 16-bit
float formats (``KHR_DF_MODEL_RGBSDA``) and the BC block formats (``KHR_DF_MODEL_BC1A``, ``BC3``,
``BC4``, ``BC5``, ``BC7``). Data is linear (``KHR_DF_TRANSFER_LINEAR``); only albedo is sRGB.
The levels lie in the file smallest first, each aligned to ``lcm(texel block bytes, 4)`` (1 when
supercompressed), and the level index lists level 0 (the largest) first.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from pathlib import Path

import etcpak
import imagecodecs
import numpy as np
import texture2ddecoder

import hzval
from hzval.core.errors import InputError
from hzval.io import atomic
from hzval.io.codecs import unit_to_u8

__all__ = [
    "IDENTIFIER",
    "Format",
    "FORMATS",
    "Texture",
    "write",
    "read",
    "dfd",
    "encode_level",
    "decode_level",
]

#: The file identifier: «KTX 20», CR LF, SUB, LF.
IDENTIFIER = b"\xabKTX 20\xbb\r\n\x1a\n"
#: ``supercompressionScheme`` values.
NONE, ZSTD = 0, 2
#: DFD colour models, transfer functions and channel ids (Khronos Data Format Specification 1.3).
MODEL_RGBSDA, MODEL_BC1A, MODEL_BC3, MODEL_BC4, MODEL_BC5, MODEL_BC7 = 1, 128, 130, 131, 132, 134
PRIMARIES_BT709, TRANSFER_LINEAR, TRANSFER_SRGB = 1, 1, 2
SAMPLE_FLOAT, SAMPLE_SIGNED = 0x80, 0x40
_FLOAT_ONE, _FLOAT_MINUS_ONE = 0x3F800000, 0xBF800000


@dataclass(frozen=True)
class Format:
    """A texture format: ``VkFormat``, texel block, channels, DFD colour model, samples and ``typeSize``.

    The texel block is ``block`` texels a side, ``block_bytes`` bytes; samples are ``((channel id, bit offset,
    bits), ...)``; ``typeSize`` is the data's unit for endianness: 1, or 2 for 16-bit floats.
    """

    name: str
    vk: int
    block: int
    block_bytes: int
    channels: int
    model: int
    samples: tuple[tuple[int, int, int], ...]
    type_size: int = 1
    half: bool = False

    def level_bytes(self, width: int, height: int) -> int:
        """Bytes of a level of ``width x height`` texels (whole blocks)."""
        return math.ceil(width / self.block) * math.ceil(height / self.block) * self.block_bytes


def _rgbsda(name: str, vk: int, channels: int, bits: int, half: bool = False) -> Format:
    ids = (0, 1, 2, 15)[:channels] if channels == 4 else (0, 1, 2)[:channels]
    samples = tuple((c, i * bits, bits) for i, c in enumerate(ids))
    return Format(name, vk, 1, channels * bits // 8, channels, MODEL_RGBSDA, samples, bits // 8, half)


#: The formats hzval writes, by the name of their ``VkFormat`` (``VK_FORMAT_`` left out).
FORMATS: dict[str, Format] = {
    f.name: f
    for f in (
        _rgbsda("R8_UNORM", 9, 1, 8),
        _rgbsda("R8G8_UNORM", 16, 2, 8),
        _rgbsda("R8G8B8A8_UNORM", 37, 4, 8),
        _rgbsda("R16_SFLOAT", 76, 1, 16, half=True),
        _rgbsda("R16G16_SFLOAT", 83, 2, 16, half=True),
        _rgbsda("R16G16B16A16_SFLOAT", 97, 4, 16, half=True),
        Format("BC1_RGB_UNORM_BLOCK", 131, 4, 8, 3, MODEL_BC1A, ((0, 0, 64),)),
        Format("BC3_UNORM_BLOCK", 137, 4, 16, 4, MODEL_BC3, ((15, 0, 64), (0, 64, 64))),
        Format("BC4_UNORM_BLOCK", 139, 4, 8, 1, MODEL_BC4, ((0, 0, 64),)),
        Format("BC5_UNORM_BLOCK", 141, 4, 16, 2, MODEL_BC5, ((0, 0, 64), (1, 64, 64))),
        Format("BC7_UNORM_BLOCK", 145, 4, 16, 4, MODEL_BC7, ((0, 0, 128),)),
    )
}
_BY_VK = {f.vk: f for f in FORMATS.values()}


@dataclass
class Texture:
    """A KTX2 texture: its format, size, levels' bytes and key/value data.

    The levels are level 0 first, uncompressed; the key/value data is ``{key: value}``, strings.
    """

    format: Format
    width: int
    height: int
    levels: list[bytes]
    srgb: bool = False
    kv: dict | None = None


def dfd(fmt: Format, srgb: bool = False) -> bytes:
    """Return the Data Format Descriptor of ``fmt``: its total size, then one basic descriptor block.

    >>> len(dfd(FORMATS["BC7_UNORM_BLOCK"])), len(dfd(FORMATS["R8G8B8A8_UNORM"]))
    (44, 92)
    """
    block_size = 24 + 16 * len(fmt.samples)
    out = struct.pack("<I", 0)  # vendorId 0 (Khronos), descriptorType 0 (basic)
    out += struct.pack("<HH", 2, block_size)  # versionNumber 2 (KDF 1.3)
    transfer = TRANSFER_SRGB if srgb else TRANSFER_LINEAR
    out += struct.pack("<BBBB", fmt.model, PRIMARIES_BT709, transfer, 0)
    out += struct.pack("<BBBB", fmt.block - 1, fmt.block - 1, 0, 0)
    out += struct.pack("<8B", fmt.block_bytes, 0, 0, 0, 0, 0, 0, 0)  # bytesPlane0..7
    for channel, offset, bits in fmt.samples:
        qualifiers = SAMPLE_FLOAT | SAMPLE_SIGNED if fmt.half else 0
        if fmt.half:
            lower, upper = _FLOAT_MINUS_ONE, _FLOAT_ONE
        elif fmt.model == MODEL_RGBSDA:
            lower, upper = 0, (1 << bits) - 1
        else:
            lower, upper = 0, 0xFFFFFFFF
        out += struct.pack("<HBB", offset, bits - 1, channel | qualifiers)
        out += struct.pack("<4B", 0, 0, 0, 0)  # samplePosition: the block's origin
        out += struct.pack("<II", lower, upper)
    return struct.pack("<I", 4 + len(out)) + out


def _kvd(kv: dict) -> bytes:
    """Key/value data, sorted by key, each entry padded to 4 bytes."""
    out = b""
    for key in sorted(kv):
        entry = key.encode() + b"\0" + str(kv[key]).encode() + b"\0"
        out += struct.pack("<I", len(entry)) + entry + b"\0" * (-len(entry) % 4)
    return out


def write(path, tex: Texture, *, zstd: bool = False) -> None:
    """Write ``tex`` to ``path`` atomically (:func:`hzval.io.atomic.atomic_path`).

    ``zstd``: supercompress each level with Zstandard.
    """
    fmt, n = tex.format, len(tex.levels)
    for i, data in enumerate(tex.levels):
        w, h = max(1, tex.width >> i), max(1, tex.height >> i)
        if len(data) != fmt.level_bytes(w, h):
            raise ValueError(
                f"level {i} of {w}x{h} {fmt.name} has {len(data)} bytes, not {fmt.level_bytes(w, h)}"
            )
    stored = [_zstd_encode(d) for d in tex.levels] if zstd else list(tex.levels)
    kv = {"KTXorientation": "rd", "KTXwriter": _writer(), **(tex.kv or {})}
    d, k = dfd(fmt, tex.srgb), _kvd(kv)
    head = 80 + 24 * n  # header (48), index (32), level index
    dfd_at, kvd_at = head, head + len(d)
    cursor = kvd_at + len(k)
    align = 1 if zstd else math.lcm(fmt.block_bytes, 4)
    offsets: list[int] = [0] * n
    body = b""
    for i in reversed(range(n)):  # smallest level first in the file
        pad = -(cursor + len(body)) % align
        body += b"\0" * pad
        offsets[i] = cursor + len(body)
        body += stored[i]
    header = IDENTIFIER + struct.pack(
        "<9I", fmt.vk, fmt.type_size, tex.width, tex.height, 0, 0, 1, n, ZSTD if zstd else NONE
    )
    header += struct.pack("<4I2Q", dfd_at, len(d), kvd_at, len(k), 0, 0)
    for i in range(n):
        header += struct.pack("<3Q", offsets[i], len(stored[i]), len(tex.levels[i]))
    with atomic.atomic_path(path) as tmp:
        Path(tmp).write_bytes(header + d + k + body)


def read(path) -> Texture:
    """Return a KTX2 file as :class:`Texture`, its levels decompressed.

    A file that is not one of the textures :func:`write` writes is refused in one line naming the file.
    """
    raw = Path(path).read_bytes() if Path(path).is_file() else None
    if raw is None:
        raise InputError(path, "no such file")
    if raw[:12] != IDENTIFIER or len(raw) < 80:
        raise InputError(path, "not a KTX 2.0 file (its identifier is missing)")
    vk, _, width, height, depth, layers, faces, n, scheme = struct.unpack_from("<9I", raw, 12)
    fmt = _BY_VK.get(vk)
    if fmt is None or depth or layers or faces != 1 or scheme not in (NONE, ZSTD) or not 0 < n <= 32:
        raise InputError(
            path, f"a KTX2 texture hzval does not read (VkFormat {vk}, {n} levels, scheme {scheme})"
        )
    _, _, kvd_at, kvd_len = struct.unpack_from("<4I", raw, 48)
    levels = []
    for i in range(n):
        at, length, full = struct.unpack_from("<3Q", raw, 80 + 24 * i)
        if at + length > len(raw):
            raise InputError(path, f"truncated: level {i} runs past the end of the file")
        data = raw[at : at + length]
        levels.append(_zstd_decode(data) if scheme == ZSTD else data)
        w, h = max(1, width >> i), max(1, height >> i)
        if len(levels[-1]) != full or full != fmt.level_bytes(w, h):
            raise InputError(path, f"level {i} holds {len(levels[-1])} bytes, not {fmt.level_bytes(w, h)}")
    dfd_at = struct.unpack_from("<I", raw, 48)[0]
    srgb = raw[dfd_at + 4 + 8 + 2] == TRANSFER_SRGB
    return Texture(fmt, width, height, levels, srgb, _read_kvd(raw[kvd_at : kvd_at + kvd_len]))


def _read_kvd(data: bytes) -> dict:
    out, at = {}, 0
    while at + 4 <= len(data):
        (length,) = struct.unpack_from("<I", data, at)
        key, _, value = data[at + 4 : at + 4 + length].partition(b"\0")
        out[key.decode(errors="replace")] = value.rstrip(b"\0").decode(errors="replace")
        at += 4 + length + (-length % 4)
    return out


def _writer() -> str:

    return f"hzval {hzval.__version__}"


def _zstd_encode(data: bytes) -> bytes:

    return bytes(imagecodecs.zstd_encode(data, level=19))


def _zstd_decode(data: bytes) -> bytes:

    return bytes(imagecodecs.zstd_decode(data))


def decode_level(tex: Texture, level: int = 0) -> np.ndarray:
    """Return a level's texels as float32 ``(rows, cols, channels)``.

    UNORM is over 255, half floats are as they are, BC blocks are decoded as a GPU decodes them
    (texture2ddecoder), cropped to the level's size.
    """
    fmt = tex.format
    w, h = max(1, tex.width >> level), max(1, tex.height >> level)
    data = tex.levels[level]
    if fmt.model == MODEL_RGBSDA:
        dtype = np.float16 if fmt.half else np.uint8
        values = np.frombuffer(data, dtype).reshape(h, w, fmt.channels).astype(np.float32)
        return values if fmt.half else values / np.float32(255.0)
    W, H = math.ceil(w / 4) * 4, math.ceil(h / 4) * 4
    decoder = {
        MODEL_BC1A: texture2ddecoder.decode_bc1,
        MODEL_BC3: texture2ddecoder.decode_bc3,
        MODEL_BC4: texture2ddecoder.decode_bc4,
        MODEL_BC5: texture2ddecoder.decode_bc5,
        MODEL_BC7: texture2ddecoder.decode_bc7,
    }[fmt.model]
    bgra = np.frombuffer(decoder(data, W, H), np.uint8).reshape(H, W, 4)
    rgba = bgra[..., [2, 1, 0, 3]][:h, :w, : fmt.channels]
    return rgba.astype(np.float32) / np.float32(255.0)


def encode_level(values: np.ndarray, fmt: Format) -> bytes:
    """Return a level's bytes in ``fmt`` from float32 ``(rows, cols, channels)`` texels.

    UNORM and BC formats take texels in [0, 1] (8-bit quantisation by :func:`hzval.io.codecs.unit_to_u8`),
    half floats take them as they are. BC blocks are etcpak's, on an RGBA8 image padded to whole blocks by
    repeating its edge, the channels it lacks 0 and alpha 255.
    """
    v = np.asarray(values, np.float32)
    if v.ndim == 2:
        v = v[..., None]
    if v.shape[-1] != fmt.channels:
        raise ValueError(f"{fmt.name} holds {fmt.channels} channels, not {v.shape[-1]}")
    if fmt.model == MODEL_RGBSDA:
        return np.ascontiguousarray(v.astype(np.float16) if fmt.half else unit_to_u8(v)).tobytes()
    rows, cols = v.shape[:2]
    padded = np.pad(v, ((0, -rows % 4), (0, -cols % 4), (0, 0)), mode="edge")
    H, W = padded.shape[:2]
    rgba = np.zeros((H, W, 4), np.uint8)
    rgba[..., 3] = 255
    rgba[..., : fmt.channels] = unit_to_u8(padded)
    if fmt.model == MODEL_BC3:  # BC3's fourth channel is its alpha
        rgba[..., 3] = unit_to_u8(padded[..., 3])
    encoder = {
        MODEL_BC1A: etcpak.compress_bc1,
        MODEL_BC3: etcpak.compress_bc3,
        MODEL_BC4: etcpak.compress_bc4,
        MODEL_BC5: etcpak.compress_bc5,
        MODEL_BC7: etcpak.compress_bc7,
    }[fmt.model]
    return bytes(encoder(np.ascontiguousarray(rgba).tobytes(), W, H))
