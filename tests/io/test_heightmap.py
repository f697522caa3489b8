"""Reading height maps: every PNG mode, EXR, .npy, orientation, and every bad input."""

import hashlib
import os
import struct
import zlib

import numpy as np
import pytest
from PIL import Image, ImageFile

from hzval.core.errors import InputError
from hzval.core.srgb import luminance_weights
from hzval.io.codecs import write_exr, write_png
from hzval.io.heightmap import HeightMap, from_array, load_height, probe_shape

RNG = np.random.default_rng(20240607)


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def _write_png_by_hand(path, samples, colour_type, bit_depth=16):
    """A PNG written without Pillow or pypng: samples (rows, cols[, planes]), filter 0."""
    rows, cols = samples.shape[:2]
    lines = samples.astype(">u2" if bit_depth == 16 else "u1").reshape(rows, -1)
    raw = b"".join(b"\0" + line.tobytes() for line in lines)
    ihdr = struct.pack(">IIBBBBB", cols, rows, bit_depth, colour_type, 0, 0, 0)
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n"
        + _chunk(b"IHDR", ihdr)
        + _chunk(b"IDAT", zlib.compress(raw))
        + _chunk(b"IEND", b"")
    )
    return path


def _grey_png(path, rows, cols):
    write_png(path, RNG.integers(0, 256, (rows, cols), dtype=np.uint8))
    return path


def _assert_input_error(path, call=load_height, **kwargs) -> str:
    with pytest.raises(InputError) as info:
        call(path, **kwargs)
    message = str(info.value)
    assert message.startswith(f"{os.fspath(path)}: ")
    assert "\n" not in message and "Traceback" not in message
    return message


# --------------------------------------------------------------------------
# PNG modes
# --------------------------------------------------------------------------


def test_8_and_16_bit_grey_agree(tmp_path):
    data = RNG.integers(0, 65536, (6, 9), dtype=np.uint16)
    write_png(tmp_path / "g16.png", data)
    write_png(tmp_path / "g8.png", np.round(data / 257.0).astype(np.uint8))
    h16 = load_height(tmp_path / "g16.png")
    h8 = load_height(tmp_path / "g8.png")
    assert isinstance(h16, HeightMap)
    assert h16.height.dtype == np.float32 and h16.height.flags.c_contiguous
    assert h16.height.shape == (6, 9)
    np.testing.assert_allclose(h16.height, data / 65535.0, rtol=0, atol=0.5 / 65535)
    np.testing.assert_allclose(h8.height, h16.height, rtol=0, atol=1 / 255)
    assert h16.source == "16-bit PNG, grey" and h8.source == "8-bit PNG, grey"
    assert h16.path == os.fspath(tmp_path / "g16.png")
    assert h16.digest == "sha256:" + hashlib.sha256((tmp_path / "g16.png").read_bytes()).hexdigest()


def test_16_bit_grey_full_range(tmp_path):
    write_png(tmp_path / "g.png", np.array([[0, 1, 65534, 65535]], dtype=np.uint16))
    h = load_height(tmp_path / "g.png").height
    assert h[0, 0] == 0 and h[0, 3] == 1
    assert h[0, 1] == np.float32(1 / 65535) and h[0, 2] == np.float32(65534 / 65535)


@pytest.mark.parametrize("colour_type,planes,name", [(2, 3, "RGB"), (6, 4, "RGBA"), (4, 2, "grey+alpha")])
def test_16_bit_colour_keeps_16_bits(tmp_path, colour_type, planes, name):
    # values that differ only in the low byte: 8-bit decoding would merge them
    samples = (0x8000 + RNG.integers(0, 256, (5, 7, planes))).astype(np.uint16)
    path = _write_png_by_hand(tmp_path / "c16.png", samples, colour_type)
    hm = load_height(path)
    values = samples / 65535.0
    expected = values[..., :3] @ luminance_weights() if planes >= 3 else values[..., 0]
    np.testing.assert_allclose(hm.height, expected, rtol=0, atol=1e-6)
    assert len(np.unique(hm.height)) > 20
    assert hm.source.startswith(f"16-bit PNG, {name}")
    assert ("alpha ignored" in hm.source) == (planes in (2, 4))


def test_rgb_is_reduced_to_luminance_of_the_stored_values(tmp_path):
    rgb = RNG.integers(0, 256, (4, 6, 3), dtype=np.uint8)
    write_png(tmp_path / "rgb.png", rgb)
    hm = load_height(tmp_path / "rgb.png")
    np.testing.assert_allclose(hm.height, (rgb / 255.0) @ luminance_weights(), rtol=0, atol=1e-6)
    assert hm.source == "8-bit PNG, RGB -> luminance (Rec. 709 weights)"
    pure = np.zeros((1, 3, 3), np.uint8)
    pure[0, np.arange(3), np.arange(3)] = 255  # red, green, blue
    write_png(tmp_path / "primaries.png", pure)
    np.testing.assert_allclose(
        load_height(tmp_path / "primaries.png").height[0], luminance_weights(), atol=1e-7
    )


def test_rgba_ignores_alpha(tmp_path):
    rgba = RNG.integers(0, 256, (4, 5, 4), dtype=np.uint8)
    write_png(tmp_path / "rgba.png", rgba)
    hm = load_height(tmp_path / "rgba.png")
    np.testing.assert_allclose(hm.height, (rgba[..., :3] / 255.0) @ luminance_weights(), atol=1e-6)
    assert hm.source.endswith(", alpha ignored")


def test_grey_alpha_ignores_alpha(tmp_path):
    grey = RNG.integers(0, 256, (4, 5), dtype=np.uint8)
    alpha = RNG.integers(0, 256, (4, 5), dtype=np.uint8)
    Image.merge("LA", [Image.fromarray(grey), Image.fromarray(alpha)]).save(tmp_path / "la.png")
    hm = load_height(tmp_path / "la.png")
    np.testing.assert_allclose(hm.height, grey / 255.0, atol=1e-7)
    assert hm.source == "8-bit PNG, grey+alpha, alpha ignored"


def test_palette_goes_through_rgb(tmp_path):
    palette = np.array([[0, 0, 0], [255, 0, 0], [10, 200, 30], [255, 255, 255]], dtype=np.uint8)
    index = RNG.integers(0, 4, (5, 6), dtype=np.uint8)
    img = Image.frombytes("P", (6, 5), index.tobytes())
    img.putpalette(palette.ravel().tolist())
    img.save(tmp_path / "p.png")
    hm = load_height(tmp_path / "p.png")
    np.testing.assert_allclose(hm.height, (palette[index] / 255.0) @ luminance_weights(), atol=1e-6)
    assert "palette -> RGB -> luminance" in hm.source


def test_one_bit(tmp_path):
    bits = RNG.random((5, 11)) < 0.5
    Image.fromarray(bits).save(tmp_path / "bits.png")
    hm = load_height(tmp_path / "bits.png")
    np.testing.assert_array_equal(hm.height, bits.astype(np.float32))
    assert hm.source == "1-bit PNG, grey"


# --------------------------------------------------------------------------
# EXR and .npy
# --------------------------------------------------------------------------


def test_exr_channel_y(tmp_path):
    y = RNG.normal(size=(6, 5)).astype(np.float32) * 3.0  # values as they are, not clipped
    write_exr(tmp_path / "y.exr", {"Y": y, "A": np.ones_like(y)})
    hm = load_height(tmp_path / "y.exr")
    np.testing.assert_array_equal(hm.height, y)
    assert hm.source == "EXR channel Y, alpha ignored"


def test_exr_rgb_is_reduced_to_luminance(tmp_path):
    rgb = RNG.random((4, 7, 3)).astype(np.float32) * 2.0
    write_exr(tmp_path / "rgb.exr", {"RGB": rgb})
    hm = load_height(tmp_path / "rgb.exr")
    np.testing.assert_allclose(hm.height, rgb @ luminance_weights(), rtol=1e-6)
    assert hm.source == "EXR channels R, G, B -> luminance (Rec. 709 weights)"


def test_exr_single_channel(tmp_path):
    z = RNG.random((3, 4)).astype(np.float32)
    write_exr(tmp_path / "z.exr", {"height": z})
    hm = load_height(tmp_path / "z.exr")
    np.testing.assert_array_equal(hm.height, z)
    assert hm.source == "EXR channel height"


def test_exr_without_a_height_channel(tmp_path):
    write_exr(tmp_path / "uv.exr", {"U": np.zeros((3, 3)), "V": np.zeros((3, 3))})
    assert _assert_input_error(tmp_path / "uv.exr").endswith(
        "EXR has channels U, V; a height map needs Y, or R, G and B, or a single channel"
    )


@pytest.mark.parametrize("dtype", [np.float64, np.uint16])
def test_npy_values_as_they_are(tmp_path, dtype):
    data = (RNG.random((4, 6)) * 1000).astype(dtype)
    np.save(tmp_path / "h.npy", data)
    hm = load_height(tmp_path / "h.npy")
    assert hm.height.dtype == np.float32
    np.testing.assert_allclose(hm.height, data, rtol=1e-7)
    assert hm.source == f".npy {np.dtype(dtype).name}"


def test_npy_3d_with_one_channel_and_fortran_order(tmp_path):
    data = np.asfortranarray(RNG.random((5, 3)))
    np.save(tmp_path / "f.npy", data)
    np.save(tmp_path / "c1.npy", data[..., None])
    for name in ("f.npy", "c1.npy"):
        hm = load_height(tmp_path / name)
        assert hm.height.flags.c_contiguous
        np.testing.assert_allclose(hm.height, data, rtol=1e-7)


# --------------------------------------------------------------------------
# Sizes and orientation
# --------------------------------------------------------------------------


@pytest.mark.parametrize("rows,cols", [(3, 7), (1, 5), (5, 1), (17, 2)])
def test_any_shape_row_zero_is_top(tmp_path, rows, cols):
    img = Image.new("L", (cols, rows))
    img.putpixel((cols - 1, 0), 255)  # Pillow's (x, y): top-right pixel as displayed
    img.save(tmp_path / "m.png")
    hm = load_height(tmp_path / "m.png")
    assert hm.height.shape == (rows, cols) == probe_shape(tmp_path / "m.png")
    assert hm.height[0, cols - 1] == 1 and hm.height.sum() == 1


def test_exr_and_npy_orientation(tmp_path):
    data = np.zeros((3, 7), np.float32)
    data[0, 6] = 1.0
    write_exr(tmp_path / "m.exr", {"Y": data})
    np.save(tmp_path / "m.npy", data)
    for name in ("m.exr", "m.npy"):
        assert probe_shape(tmp_path / name) == (3, 7)
        np.testing.assert_array_equal(load_height(tmp_path / name).height, data)


def test_format_comes_from_content_not_name(tmp_path):
    path = _grey_png(tmp_path / "renamed.npy", 4, 4)
    hm = load_height(path)
    assert hm.source == "8-bit PNG, grey" and hm.height.shape == (4, 4)


# --------------------------------------------------------------------------
# probe_shape reads headers only
# --------------------------------------------------------------------------


def test_probe_shape_does_not_decode(tmp_path):
    data = _grey_png(tmp_path / "full.png", 40, 30).read_bytes()
    (tmp_path / "cut.png").write_bytes(data[: len(data) // 2])
    assert probe_shape(tmp_path / "cut.png") == (40, 30)
    _assert_input_error(tmp_path / "cut.png")  # decoding it fails

    npy = tmp_path / "h.npy"
    np.save(npy, np.zeros((20, 9)))
    (tmp_path / "cut.npy").write_bytes(npy.read_bytes()[:200])
    assert probe_shape(tmp_path / "cut.npy") == (20, 9)


def test_max_pixels_is_checked_before_decoding(tmp_path):
    data = _grey_png(tmp_path / "full.png", 40, 30).read_bytes()
    (tmp_path / "cut.png").write_bytes(data[: len(data) // 2])
    message = _assert_input_error(tmp_path / "cut.png", max_pixels=1000)
    assert message.endswith("image is 40x30 pixels (rows x columns, 1,200 in all); the limit here is 1,000")
    assert load_height(tmp_path / "full.png", max_pixels=1200).height.shape == (40, 30)


# --------------------------------------------------------------------------
# Bad input: one InputError, one line, naming the file
# --------------------------------------------------------------------------


def _truncated_png(tmp_path):
    data = _grey_png(tmp_path / "src.png", 32, 32).read_bytes()
    (tmp_path / "t.png").write_bytes(data[: len(data) // 2])
    return tmp_path / "t.png"


def _corrupt_png(tmp_path):
    data = bytearray(_grey_png(tmp_path / "src.png", 32, 32).read_bytes())
    data[len(data) // 2] ^= 0xFF
    (tmp_path / "c.png").write_bytes(bytes(data))
    return tmp_path / "c.png"


def _bad_crc_png(tmp_path):
    """A sample changed after the IDAT checksum was computed, in a valid zlib stream: only the CRC can
    tell."""
    raw = b"".join(b"\0" + bytes(range(16)) for _ in range(4))
    idat = _chunk(b"IDAT", zlib.compress(raw))
    bad = bytearray(raw)
    bad[5] ^= 0x01
    bad_data = zlib.compress(bytes(bad))
    idat = struct.pack(">I", len(bad_data)) + b"IDAT" + bad_data + idat[-4:]
    ihdr = _chunk(b"IHDR", struct.pack(">IIBBBBB", 16, 4, 8, 0, 0, 0, 0))
    return _write(tmp_path, "crc.png", b"\x89PNG\r\n\x1a\n" + ihdr + idat + _chunk(b"IEND", b""))


def _truncated_png16_rgb(tmp_path):
    samples = RNG.integers(0, 65536, (16, 16, 3)).astype(np.uint16)
    data = _write_png_by_hand(tmp_path / "src.png", samples, 2).read_bytes()
    (tmp_path / "t16.png").write_bytes(data[: len(data) // 2])
    return tmp_path / "t16.png"


def _npy(tmp_path, array, name="bad.npy"):
    np.save(tmp_path / name, array)
    return tmp_path / name


def _truncated_npy(tmp_path):
    data = _npy(tmp_path, np.zeros((8, 8))).read_bytes()
    (tmp_path / "t.npy").write_bytes(data[:-10])
    return tmp_path / "t.npy"


def _truncated_exr(tmp_path):
    write_exr(tmp_path / "src.exr", {"Y": RNG.random((32, 32))})
    data = (tmp_path / "src.exr").read_bytes()
    (tmp_path / "t.exr").write_bytes(data[: len(data) // 2])
    return tmp_path / "t.exr"


def _nan_exr(tmp_path):
    y = np.zeros((4, 4), np.float32)
    y[0, :2] = np.nan
    y[3, 3] = -np.inf
    write_exr(tmp_path / "nan.exr", {"Y": y})
    return tmp_path / "nan.exr"


def _write(tmp_path, name, data: bytes):
    (tmp_path / name).write_bytes(data)
    return tmp_path / name


def _nan_npy(tmp_path):
    data = np.zeros((4, 5))
    data[1, 1:4] = np.nan
    return _npy(tmp_path, data)


BAD_INPUTS = {
    "missing": (lambda p: p / "nothing.png", "no such file"),
    "directory": (lambda p: p, "is a directory, not a file"),
    "empty": (lambda p: _write(p, "empty.png", b""), "file is empty"),
    "text": (lambda p: _write(p, "notes.txt", b"hello, world"), "not an image hzval reads"),
    "truncated jpeg": (
        lambda p: _write(p, "photo.jpg", b"\xff\xd8\xff\xe0\0\x10JFIF"),
        "not an image hzval reads",
    ),
    "not a png": (
        lambda p: _write(p, "x.png", b"GIF89a....."),
        "not a PNG file (no PNG signature at its start)",
    ),
    "short png": (lambda p: _write(p, "x.png", b"\x89PNG"), "truncated PNG file (4 bytes)"),
    "truncated png": (_truncated_png, "truncated or corrupt PNG (image file is truncated"),
    "corrupt png": (_corrupt_png, "truncated or corrupt PNG ("),
    "bad crc png": (_bad_crc_png, "truncated or corrupt PNG (broken PNG file (bad header checksum"),
    "truncated 16-bit rgb png": (_truncated_png16_rgb, "truncated or corrupt PNG ("),
    "png header only": (
        lambda p: _write(p, "h.png", _grey_png(p / "s.png", 4, 4).read_bytes()[:33]),
        "truncated or corrupt PNG (unreadable header chunks)",
    ),
    "1x1 png": (
        lambda p: _grey_png(p / "one.png", 1, 1),
        "is 1x1 texels; a height map needs at least 8x8",
    ),
    "0x5 npy": (
        lambda p: _npy(p, np.zeros((0, 5))),
        "is 5x0 texels; a height map needs at least 8x8",
    ),
    "nan npy": (_nan_npy, "contains 3 NaN and 0 infinite values"),
    "nan exr": (_nan_exr, "contains 2 NaN and 1 infinite values"),
    "float32 overflow": (
        lambda p: _npy(p, np.array([[1e300, 0.0]])),
        "contains 0 NaN and 1 infinite values (1 of them finite but beyond float32's range)",
    ),
    "npy rgb": (
        lambda p: _npy(p, np.zeros((4, 4, 3))),
        "array has shape (4, 4, 3); a height map needs (rows, cols) or (rows, cols, 1)",
    ),
    "npy 1-d": (lambda p: _npy(p, np.zeros(6)), "array has shape (6,)"),
    "npy complex": (lambda p: _npy(p, np.zeros((3, 3), complex)), "array has dtype complex128"),
    "npy bool": (lambda p: _npy(p, np.zeros((3, 3), bool)), "array has dtype bool"),
    "npy object": (lambda p: _npy(p, np.array([[None, 1]], dtype=object)), "array has dtype object"),
    "truncated npy": (_truncated_npy, "truncated or corrupt .npy file ("),
    "corrupt npy header": (
        lambda p: _write(p, "h.npy", b"\x93NUMPY\x01\x00\x10\x00{'descr': <?? }\n"),
        "unreadable .npy header (",
    ),
    "truncated exr": (_truncated_exr, "truncated or corrupt EXR file: (EXR_ERR_BAD_CHUNK_LEADER)"),
    "exr header only": (lambda p: _write(p, "h.exr", b"v/1\x01\x02\0\0\0"), "not a readable EXR file ("),
}


@pytest.mark.parametrize("case", BAD_INPUTS)
def test_bad_input_is_one_line_input_error(tmp_path, case):
    make, problem = BAD_INPUTS[case]
    path = make(tmp_path)
    assert problem in _assert_input_error(path)


@pytest.mark.parametrize(
    "case", ["missing", "directory", "empty", "text", "short png", "npy rgb", "exr header only"]
)
def test_probe_shape_reports_bad_input_too(tmp_path, case):
    make, problem = BAD_INPUTS[case]
    assert problem in _assert_input_error(make(tmp_path), call=probe_shape)


def test_pillow_settings_are_forced_and_restored(tmp_path, monkeypatch):
    monkeypatch.setattr(ImageFile, "LOAD_TRUNCATED_IMAGES", True)
    monkeypatch.setattr(Image, "MAX_IMAGE_PIXELS", 10)
    assert "image file is truncated" in _assert_input_error(_truncated_png(tmp_path))  # not zero-filled
    assert load_height(_grey_png(tmp_path / "big.png", 8, 8)).height.shape == (
        8,
        8,
    )  # our limit, not Pillow's
    assert ImageFile.LOAD_TRUNCATED_IMAGES is True and Image.MAX_IMAGE_PIXELS == 10


# --------------------------------------------------------------------------
# Generated maps
# --------------------------------------------------------------------------


def test_from_array():
    data = RNG.random((4, 3))
    hm = from_array(data, source="noise")
    assert hm.path is None and hm.source == "noise"
    assert hm.height.dtype == np.float32 and hm.height.flags.c_contiguous
    np.testing.assert_allclose(hm.height, data, rtol=1e-7)
    assert hm.digest.startswith("sha256:") and len(hm.digest) == 7 + 64
    assert from_array(data.astype(np.float32)).digest == hm.digest  # digest of float32 values
    assert from_array(hm.height.reshape(3, 4)).digest != hm.digest  # and of the shape
    assert from_array(np.asfortranarray(data)).digest == hm.digest


@pytest.mark.parametrize(
    "array,problem",
    [
        (np.full((2, 2), np.inf), "array: contains 0 NaN and 4 infinite values"),
        (np.zeros((1, 1)), "array: is 1x1 texels; a height map needs at least 8x8"),
        (np.zeros((2, 2), bool), "array: array has dtype bool; a height map needs real numbers"),
        (np.zeros((2, 2, 2)), "array: array has shape (2, 2, 2)"),
    ],
)
def test_from_array_rejects(array, problem):
    with pytest.raises(InputError) as info:
        from_array(array)
    assert str(info.value).startswith(problem)
