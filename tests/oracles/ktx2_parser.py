"""An independent reader of KTX 2.0 files and BC blocks, for the tests of hzval.io.ktx2: written from
the Khronos specification (KTX 2.0, Data Format Specification 1.3), sharing no code with hzval, and
decoding BC blocks with Pillow's DDS decoder (a second decoder beside hzval's texture2ddecoder)."""

from __future__ import annotations

import io
import struct
from dataclasses import dataclass, field

import numpy as np

IDENTIFIER = bytes([0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A])
#: VkFormat -> (DXGI format for a DDS, texel block bytes) of the BC formats.
BC = {131: (71, 8), 137: (77, 16), 139: (80, 8), 141: (83, 16), 145: (98, 16)}


@dataclass
class Parsed:
    vk_format: int
    type_size: int
    width: int
    height: int
    level_count: int
    scheme: int
    levels: list = field(default_factory=list)  # (offset, length, uncompressed length), level 0 first
    dfd: dict = field(default_factory=dict)
    kv: list = field(default_factory=list)  # (key, value bytes, entry length), in file order
    raw: bytes = b""


def parse(data: bytes) -> Parsed:
    assert data[:12] == IDENTIFIER, "identifier"
    fields = struct.unpack("<9I", data[12:48])
    p = Parsed(fields[0], fields[1], fields[2], fields[3], fields[7], fields[8], raw=data)
    assert fields[4] == 0 and fields[5] == 0 and fields[6] == 1, "a 2-D texture, one face, no layers"
    dfd_off, dfd_len, kvd_off, kvd_len = struct.unpack("<4I", data[48:64])
    sgd_off, sgd_len = struct.unpack("<2Q", data[64:80])
    for i in range(p.level_count):
        p.levels.append(struct.unpack("<3Q", data[80 + 24 * i : 104 + 24 * i]))
    total = struct.unpack("<I", data[dfd_off : dfd_off + 4])[0]
    assert total == dfd_len, "dfdTotalSize"
    block = data[dfd_off + 4 : dfd_off + dfd_len]
    word0, version, size = struct.unpack("<IHH", block[:8])
    model, primaries, transfer, flags = block[8:12]
    dims = tuple(block[12:16])
    planes = tuple(block[16:24])
    samples = []
    for k in range((size - 24) // 16):
        s = block[24 + 16 * k : 40 + 16 * k]
        offset, length, channel = struct.unpack("<HBB", s[:4])
        lower, upper = struct.unpack("<II", s[8:16])
        samples.append(
            {"offset": offset, "bits": length + 1, "channel": channel, "lower": lower, "upper": upper}
        )
    p.dfd = dict(
        vendor_and_type=word0,
        version=version,
        size=size,
        model=model,
        primaries=primaries,
        transfer=transfer,
        flags=flags,
        dims=dims,
        planes=planes,
        samples=samples,
    )
    at = kvd_off
    while at < kvd_off + kvd_len:
        (n,) = struct.unpack("<I", data[at : at + 4])
        key, _, value = data[at + 4 : at + 4 + n].partition(b"\0")
        p.kv.append((key.decode(), value, n))
        at += 4 + n + (-n % 4)
    assert sgd_len == 0 and sgd_off == 0
    return p


def bc_level(p: Parsed, level: int, width: int, height: int) -> np.ndarray:
    """A BC level decoded by Pillow, through a DDS with a DX10 header: ``(height, width, 4)`` uint8."""
    from PIL import Image

    dxgi, _ = BC[p.vk_format]
    offset, length, _ = p.levels[level]
    blocks = p.raw[offset : offset + length]
    W, H = -(-width // 4) * 4, -(-height // 4) * 4
    pf = struct.pack("<II4s5I", 32, 0x4, b"DX10", 0, 0, 0, 0, 0)
    header = struct.pack("<7I", 124, 0x1 | 0x2 | 0x4 | 0x1000 | 0x80000, H, W, len(blocks), 0, 1)
    header += b"\0" * 44 + pf + struct.pack("<5I", 0x1000, 0, 0, 0, 0)
    dx10 = struct.pack("<5I", dxgi, 3, 0, 1, 0)
    with Image.open(io.BytesIO(b"DDS " + header + dx10 + blocks)) as img:
        rgba = np.asarray(img.convert("RGBA"))
    return rgba[:height, :width]
