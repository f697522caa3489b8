"""The compact forms of the sweep's frame files (hzval.io.codecs): half-float EXRs and grey images as one
channel, all read back.

Each compact form is checked against what the plain one holds: a grey EXR or PNG gives back the
RGB pixels bit for bit, a half EXR the float32 values rounded to half. The palette PNGs are in
tests/report/test_images.py, the sweep's frames in tests/pipeline/test_sweep_frames.py.
"""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from hzval.core.errors import InputError
from hzval.io import codecs
from tests.helpers import exr_layout, png_mode_and_rgb

RNG = np.random.default_rng(7)


# -- EXR ---------------------------------------------------------------------------------------


def test_half_exr_holds_the_values_rounded_to_half(tmp_path):
    y = np.concatenate([RNG.random(1000), [0.0, 1.0, 1e-7, 3.0e4, -2.5]]).astype(np.float32).reshape(5, 201)
    codecs.write_exr(tmp_path / "h.exr", {"Y": y}, half=True)
    assert exr_layout(tmp_path / "h.exr") == {"Y": "HALF", "compression": "ZIP_COMPRESSION"}
    back = codecs.read_exr(tmp_path / "h.exr")["Y"]
    assert back.dtype == np.float32 and np.array_equal(back, y.astype(np.float16).astype(np.float32))
    normal = np.abs(y) >= 2.0**-14
    assert np.all(np.abs(back - y)[normal] <= 2.0**-11 * np.abs(y[normal]))


def test_exr_is_float32_by_default_and_where_half_would_overflow(tmp_path):
    y = RNG.random((4, 4)).astype(np.float32)
    codecs.write_exr(tmp_path / "f.exr", {"Y": y})
    assert exr_layout(tmp_path / "f.exr")["Y"] == "FLOAT"
    assert np.array_equal(codecs.read_exr(tmp_path / "f.exr")["Y"], y)
    big = y * 1e5
    inf = np.where(y > 0.5, np.inf, y).astype(np.float32)  # infinite already: half holds that
    codecs.write_exr(tmp_path / "b.exr", {"big": big, "inf": inf}, half=True)
    assert exr_layout(tmp_path / "b.exr") == {"big": "FLOAT", "inf": "HALF", "compression": "ZIP_COMPRESSION"}
    assert np.array_equal(codecs.read_exr(tmp_path / "b.exr")["big"], big)


def test_pxr24_exr_keeps_float32s_range_to_2_pow_minus_16(tmp_path):
    v = (RNG.random((8, 8)) * 10.0 ** RNG.integers(-14, 3, (8, 8))).astype(np.float32)
    codecs.write_exr(tmp_path / "v.exr", {"Y": v}, compression="pxr24")
    assert exr_layout(tmp_path / "v.exr") == {"Y": "FLOAT", "compression": "PXR24_COMPRESSION"}
    back = codecs.read_exr(tmp_path / "v.exr")["Y"]
    assert np.all(np.abs(back - v) <= 2.0**-16 * v) and np.all(back[v > 0] > 0)


def test_a_grey_rgb_exr_is_one_y_channel_read_back_as_rgb(tmp_path):
    g = RNG.random((6, 5)).astype(np.float32)
    g[0, 0], g[0, 1] = np.nan, -0.0
    rgb = np.repeat(g[..., None], 3, axis=-1)
    codecs.write_exr(tmp_path / "g.exr", {"RGB": rgb}, grey=True)
    assert set(codecs.read_exr(tmp_path / "g.exr")) == {"Y"}
    back = codecs.read_rgb_exr(tmp_path / "g.exr")
    assert back.shape == (6, 5, 3) and np.array_equal(back.view(np.uint32), rgb.view(np.uint32))
    codecs.write_exr(
        tmp_path / "ga.exr", {"RGBA": np.concatenate([rgb, g[..., None] * 0 + 1], -1)}, grey=True
    )
    assert set(codecs.read_exr(tmp_path / "ga.exr")) == {"Y", "A"}
    codecs.write_exr(tmp_path / "kept.exr", {"RGB": rgb})  # grey is asked for, not assumed
    assert set(codecs.read_exr(tmp_path / "kept.exr")) == {"R", "G", "B"}


def test_an_rgb_exr_that_is_not_quite_grey_keeps_its_channels(tmp_path):
    rgb = np.repeat(RNG.random((6, 5, 1)).astype(np.float32), 3, axis=-1)
    rgb[3, 2, 1] = np.nextafter(rgb[3, 2, 1], 2)  # one bit of one pixel
    codecs.write_exr(tmp_path / "c.exr", {"RGB": rgb}, grey=True, half=False)
    assert set(codecs.read_exr(tmp_path / "c.exr")) == {"R", "G", "B"}
    assert np.array_equal(codecs.read_rgb_exr(tmp_path / "c.exr"), rgb)


def test_read_rgb_exr_names_the_file_without_colour_channels(tmp_path):
    codecs.write_exr(tmp_path / "z.exr", {"Z": np.zeros((2, 2))})
    with pytest.raises(InputError, match="no R, G, B or Y channel") as e:
        codecs.read_rgb_exr(tmp_path / "z.exr")
    assert "z.exr" in str(e.value)


# -- PNG ---------------------------------------------------------------------------------------


def test_a_grey_rgb_png_is_8_bit_grey_and_decodes_to_the_same_rgb(tmp_path):
    rgb = np.repeat(RNG.integers(0, 256, (9, 7, 1), dtype=np.uint8), 3, axis=-1)
    codecs.write_png(tmp_path / "g.png", rgb, grey=True)
    mode, back = png_mode_and_rgb(tmp_path / "g.png")
    assert mode == "L" and np.array_equal(back, rgb)
    rgb[4, 4, 2] ^= 1
    codecs.write_png(tmp_path / "c.png", rgb, grey=True)
    mode, back = png_mode_and_rgb(tmp_path / "c.png")
    assert mode == "RGB" and np.array_equal(back, rgb)


@pytest.mark.parametrize(
    "pixels",
    [
        RNG.integers(0, 256, (13, 11, 3), dtype=np.uint8),
        RNG.integers(0, 256, (5, 17, 4), dtype=np.uint8),
        RNG.integers(0, 256, (1, 1), dtype=np.uint8),
        RNG.integers(0, 65536, (7, 6), dtype=np.uint16),
    ],
    ids=["rgb", "rgba", "one-grey-pixel", "16-bit-grey"],
)
@pytest.mark.parametrize("level", [0, 1, 9])
def test_png_pixels_read_back_exactly_with_pillow(tmp_path, pixels, level):
    """Grey and colour PNGs are written by libpng (imagecodecs), read here by Pillow: every value back,
    at every zlib level, 16-bit grey included."""

    codecs.write_png(tmp_path / "p.png", pixels, compress_level=level)
    with Image.open(tmp_path / "p.png") as im:
        back = np.asarray(im)
    assert back.shape == pixels.shape and np.array_equal(back.astype(pixels.dtype), pixels)


def test_png_refuses_what_it_cannot_write(tmp_path):
    with pytest.raises(TypeError):
        codecs.write_png(tmp_path / "f.png", np.zeros((2, 2), np.float32))
    with pytest.raises(ValueError):
        codecs.write_png(tmp_path / "two.png", np.zeros((2, 2, 2), np.uint8))
    with pytest.raises(ValueError):
        codecs.write_png(tmp_path / "rgb16.png", np.zeros((2, 2, 3), np.uint16))
    assert not list(tmp_path.iterdir())
