"""How a horizon map is stored for the GPU: float, 8-bit, or block-compressed, and what each costs.

Shipping a horizon map means storing its sines in textures an engine can
sample, and block compression has an error of its own. Each storage format
here turns the baked ``(rows, cols, D)`` sines into what a GPU would read
back (:meth:`Storage.roundtrip`) and says how many bytes that takes
(:meth:`Storage.bytes`). The approximation's ``storage`` setting
(:class:`hzval.techniques.horizon.Horizon`, ``--horizon-storage``) names one; ``hzval
tradeoff`` measures each.

Formats (:data:`STORAGES`)
    ``float``  the bake's float32, 4 bytes a channel;
    ``u8``     8-bit RGBA layers (:func:`hzval.io.codecs.unit_to_u8`), 1 byte a channel;
    ``bc7``    BC7 RGBA layers, 16 bytes a 4 x 4 block (1 byte a texel for 4 channels);
    ``bc3``    BC3 (DXT5) RGBA layers: colour end points in 5:6:5, 8-bit alpha, 1 byte a texel;
    ``bc1``    BC1 (DXT1) RGB textures, 8 bytes a block: the channels packed three to a texture
               (8 channels in 3 textures);
    ``bc4``    BC4, one channel a texture, 8 bytes a block;
    ``bc5``    BC5, two channels a texture, 16 bytes a block (a bent normal's x and y).

Each block format also comes as ``<format>-sqrt``: the texture holds ``sqrt(s)``
and the shader squares what it samples, which spends the 8-bit and block
precision where horizons are low (shallow angles), as radial-Fourier and
map-bumper horizon maps do. ``u8-sqrt`` likewise.

Encoders and decoders are maintained PyPI packages, not code of hzval's:
``etcpak`` (BC1, BC3, BC4, BC5, BC7 encoders) and ``texture2ddecoder`` (Perfare's decoders, as a GPU
decodes the blocks; its output is BGRA). A map whose sides are not multiples of 4 is
padded by repeating its edge (as engines pad) and cropped back.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import etcpak
import numpy as np
import texture2ddecoder

from hzval.core import conventions as cv
from hzval.core.errors import InputError
from hzval.io.codecs import unit_to_u8

__all__ = ["Storage", "STORAGES", "get", "names"]


@dataclass(frozen=True)
class Storage:
    """A storage format: its channels, block or texel size, codec and whether it stores ``sqrt(s)``.

    It has ``channels`` per texture, ``block_bytes`` per 4 x 4 block (0: uncompressed, ``texel_bytes`` per
    channel and texel), and its codec (``None``: uncompressed).
    """

    name: str
    label: str
    channels: int
    block_bytes: int = 0
    texel_bytes: float = 0.0
    codec: tuple[Callable, Callable] | None = None
    sqrt: bool = False

    def bytes(self, rows: int, cols: int, directions: int = cv.CHANNEL_COUNT) -> int:
        """Texture memory of a ``rows x cols`` map of ``directions`` channels, bytes."""
        if not self.block_bytes:
            return int(rows * cols * directions * self.texel_bytes)
        textures = math.ceil(directions / self.channels)
        return textures * math.ceil(rows / 4) * math.ceil(cols / 4) * self.block_bytes

    def roundtrip(self, sines: np.ndarray, blocks_out: list | None = None) -> np.ndarray:
        """Return what the GPU samples (before filtering) of the sines ``(rows, cols, D)`` in [0, 1]: float32.

        ``blocks_out`` (a list; block formats) receives the encoded blocks of each texture, as uploaded.
        """
        s = np.asarray(sines, np.float32)
        if self.name == "float":
            return s
        v = np.sqrt(np.clip(s, 0.0, 1.0)) if self.sqrt else s
        if self.codec is None:
            out = unit_to_u8(v).astype(np.float32) / np.float32(255.0)
        else:
            out = _block_roundtrip(v, self.channels, *self.codec, blocks_out=blocks_out)
        return (out * out if self.sqrt else out).astype(np.float32)


def _encode_blocks(v: np.ndarray, per_texture: int, encode) -> tuple[list[tuple[list[int], bytes]], int, int]:
    """Return the channels of ``v`` packed ``per_texture`` to RGBA8 images, each encoded.

    The result is ``([(channels, blocks), ...], W, H)``; the images are padded to multiples of 4 by repeating
    the edge, and the encoded bytes are what a GPU uploads.
    """
    rows, cols, D = v.shape
    pr, pc = -rows % 4, -cols % 4
    padded = np.pad(v, ((0, pr), (0, pc), (0, 0)), mode="edge")
    H, W = padded.shape[:2]
    out = []
    for first in range(0, D, per_texture):
        chans = list(range(first, min(first + per_texture, D)))
        rgba = np.zeros((H, W, 4), np.uint8)
        rgba[..., 3] = 255
        rgba[..., : len(chans)] = unit_to_u8(padded[..., chans])
        out.append((chans, encode(np.ascontiguousarray(rgba).tobytes(), W, H)))
    return out, W, H


def _block_roundtrip(
    v: np.ndarray, per_texture: int, encode, decode, blocks_out: list | None = None
) -> np.ndarray:
    """Pack the channels ``per_texture`` to an RGBA8 image, encode, decode (BGRA) and unpack.

    ``blocks_out`` (a list) receives each texture's encoded blocks.
    """
    rows, cols, D = v.shape
    textures, W, H = _encode_blocks(v, per_texture, encode)
    out = np.empty((H, W, D), np.float32)
    for chans, blocks in textures:
        bgra = np.frombuffer(decode(blocks, W, H), np.uint8).reshape(H, W, 4)
        rgba_back = bgra[..., [2, 1, 0, 3]]
        out[..., chans] = rgba_back[..., : len(chans)].astype(np.float32) / np.float32(255.0)
    if blocks_out is not None:
        blocks_out.extend(blocks for _, blocks in textures)
    return out[:rows, :cols]


def _codecs() -> dict[str, tuple[Callable, Callable]]:
    t2d = texture2ddecoder
    return {
        "bc7": (etcpak.compress_bc7, t2d.decode_bc7),
        "bc3": (etcpak.compress_bc3, t2d.decode_bc3),
        "bc1": (etcpak.compress_bc1, t2d.decode_bc1),
        "bc4": (etcpak.compress_bc4, t2d.decode_bc4),
        "bc5": (etcpak.compress_bc5, t2d.decode_bc5),
    }


def _table() -> dict[str, Storage]:
    out = {
        "float": Storage("float", "float32", 1, texel_bytes=4.0),
        "u8": Storage("u8", "8-bit RGBA", 4, texel_bytes=1.0),
        "u8-sqrt": Storage("u8-sqrt", "8-bit RGBA, square-root sines", 4, texel_bytes=1.0, sqrt=True),
    }
    layout = {
        "bc7": ("BC7 RGBA", 4, 16),
        "bc3": ("BC3 (DXT5) RGBA", 4, 16),
        "bc1": ("BC1 (DXT1) RGB, 3 channels a texture", 3, 8),
        "bc4": ("BC4, a texture a channel", 1, 8),
        "bc5": ("BC5, two channels a texture", 2, 16),
    }
    codecs = _codecs()
    for name, (label, channels, block) in layout.items():
        out[name] = Storage(name, label, channels, block_bytes=block, codec=codecs[name])
        out[f"{name}-sqrt"] = Storage(
            f"{name}-sqrt",
            f"{label}, square-root sines",
            channels,
            block_bytes=block,
            codec=codecs[name],
            sqrt=True,
        )
    return out


#: Every storage format by name.
STORAGES: dict[str, Storage] = _table()


def names() -> list[str]:
    """Return the storage format names."""
    return list(STORAGES)


def get(name: str) -> Storage:
    """Return the storage format called ``name``."""
    if name not in STORAGES:
        raise InputError("--storage", f"unknown storage {name!r}; choose from {', '.join(STORAGES)}")
    return STORAGES[name]
