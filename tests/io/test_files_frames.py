"""The sweep's frame files: half-float EXRs, grey images as one channel, palette PNGs, all read back.

Each compact form is checked against what the plain one holds: a grey EXR or PNG gives back the
RGB pixels bit for bit, a palette PNG decodes to exactly the RGB image the colour code paints, a
half EXR to the float32 values rounded to half.
"""

from __future__ import annotations

import json
import types

import numpy as np
import OpenEXR
import pytest
from PIL import Image

from hzval.cli import main as cli
from hzval.core.errors import InputError
from hzval.io import files
from hzval.metrics import compare
from hzval.pipeline import sweep
from hzval.report import images

RNG = np.random.default_rng(7)


def exr_layout(path) -> dict[str, str]:
    """``{channel: "HALF" | "FLOAT"}`` of an EXR as stored, and its compression under ``"compression"``."""
    with OpenEXR.File(str(path), separate_channels=True) as f:
        out = {name: ch.type().name for name, ch in f.channels().items()}
        out["compression"] = f.header()["compression"].name
    return out


def png_mode_and_rgb(path) -> tuple[str, np.ndarray]:
    with Image.open(path) as im:
        return im.mode, np.asarray(im.convert("RGB"))


# -- EXR ---------------------------------------------------------------------------------------


def test_half_exr_holds_the_values_rounded_to_half(tmp_path):
    y = np.concatenate([RNG.random(1000), [0.0, 1.0, 1e-7, 3.0e4, -2.5]]).astype(np.float32).reshape(5, 201)
    files.write_exr(tmp_path / "h.exr", {"Y": y}, half=True)
    assert exr_layout(tmp_path / "h.exr") == {"Y": "HALF", "compression": "ZIP_COMPRESSION"}
    back = files.read_exr(tmp_path / "h.exr")["Y"]
    assert back.dtype == np.float32 and np.array_equal(back, y.astype(np.float16).astype(np.float32))
    normal = np.abs(y) >= 2.0**-14
    assert np.all(np.abs(back - y)[normal] <= 2.0**-11 * np.abs(y[normal]))


def test_exr_is_float32_by_default_and_where_half_would_overflow(tmp_path):
    y = RNG.random((4, 4)).astype(np.float32)
    files.write_exr(tmp_path / "f.exr", {"Y": y})
    assert exr_layout(tmp_path / "f.exr")["Y"] == "FLOAT"
    assert np.array_equal(files.read_exr(tmp_path / "f.exr")["Y"], y)
    big = y * 1e5
    inf = np.where(y > 0.5, np.inf, y).astype(np.float32)  # infinite already: half holds that
    files.write_exr(tmp_path / "b.exr", {"big": big, "inf": inf}, half=True)
    assert exr_layout(tmp_path / "b.exr") == {"big": "FLOAT", "inf": "HALF", "compression": "ZIP_COMPRESSION"}
    assert np.array_equal(files.read_exr(tmp_path / "b.exr")["big"], big)


def test_pxr24_exr_keeps_float32s_range_to_2_pow_minus_16(tmp_path):
    v = (RNG.random((8, 8)) * 10.0 ** RNG.integers(-14, 3, (8, 8))).astype(np.float32)
    files.write_exr(tmp_path / "v.exr", {"Y": v}, compression="pxr24")
    assert exr_layout(tmp_path / "v.exr") == {"Y": "FLOAT", "compression": "PXR24_COMPRESSION"}
    back = files.read_exr(tmp_path / "v.exr")["Y"]
    assert np.all(np.abs(back - v) <= 2.0**-16 * v) and np.all(back[v > 0] > 0)


def test_a_grey_rgb_exr_is_one_y_channel_read_back_as_rgb(tmp_path):
    g = RNG.random((6, 5)).astype(np.float32)
    g[0, 0], g[0, 1] = np.nan, -0.0
    rgb = np.repeat(g[..., None], 3, axis=-1)
    files.write_exr(tmp_path / "g.exr", {"RGB": rgb}, grey=True)
    assert set(files.read_exr(tmp_path / "g.exr")) == {"Y"}
    back = files.read_rgb_exr(tmp_path / "g.exr")
    assert back.shape == (6, 5, 3) and np.array_equal(back.view(np.uint32), rgb.view(np.uint32))
    files.write_exr(tmp_path / "ga.exr", {"RGBA": np.concatenate([rgb, g[..., None] * 0 + 1], -1)}, grey=True)
    assert set(files.read_exr(tmp_path / "ga.exr")) == {"Y", "A"}
    files.write_exr(tmp_path / "kept.exr", {"RGB": rgb})  # grey is asked for, not assumed
    assert set(files.read_exr(tmp_path / "kept.exr")) == {"R", "G", "B"}


def test_an_rgb_exr_that_is_not_quite_grey_keeps_its_channels(tmp_path):
    rgb = np.repeat(RNG.random((6, 5, 1)).astype(np.float32), 3, axis=-1)
    rgb[3, 2, 1] = np.nextafter(rgb[3, 2, 1], 2)  # one bit of one pixel
    files.write_exr(tmp_path / "c.exr", {"RGB": rgb}, grey=True, half=False)
    assert set(files.read_exr(tmp_path / "c.exr")) == {"R", "G", "B"}
    assert np.array_equal(files.read_rgb_exr(tmp_path / "c.exr"), rgb)


def test_read_rgb_exr_names_the_file_without_colour_channels(tmp_path):
    files.write_exr(tmp_path / "z.exr", {"Z": np.zeros((2, 2))})
    with pytest.raises(InputError, match="no R, G, B or Y channel") as e:
        files.read_rgb_exr(tmp_path / "z.exr")
    assert "z.exr" in str(e.value)


# -- PNG ---------------------------------------------------------------------------------------


def test_a_grey_rgb_png_is_8_bit_grey_and_decodes_to_the_same_rgb(tmp_path):
    rgb = np.repeat(RNG.integers(0, 256, (9, 7, 1), dtype=np.uint8), 3, axis=-1)
    files.write_png(tmp_path / "g.png", rgb, grey=True)
    mode, back = png_mode_and_rgb(tmp_path / "g.png")
    assert mode == "L" and np.array_equal(back, rgb)
    rgb[4, 4, 2] ^= 1
    files.write_png(tmp_path / "c.png", rgb, grey=True)
    mode, back = png_mode_and_rgb(tmp_path / "c.png")
    assert mode == "RGB" and np.array_equal(back, rgb)


def magma_as_before(values):
    """The FLIP map as the sweep painted it before palettes: matplotlib's magma, 8-bit RGB."""
    from matplotlib import colormaps

    return (colormaps["magma"](np.clip(values, 0, 1))[..., :3] * 255 + 0.5).astype(np.uint8)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_the_flip_palette_png_decodes_to_the_rgb_map(tmp_path, dtype):
    edges = np.concatenate([np.arange(257) / 256, np.nextafter(np.arange(257) / 256, 0), [-1, 2, np.inf]])
    error = np.concatenate([edges, RNG.random(64 * 64 - edges.size)]).astype(dtype).reshape(64, 64)
    expected = magma_as_before(error)
    assert np.array_equal(images.flip_image(error), expected)
    files.write_png(tmp_path / "flip.png", images.flip_indexed(error))
    mode, back = png_mode_and_rgb(tmp_path / "flip.png")
    assert mode == "P" and np.array_equal(back, expected)


def test_a_flip_map_with_nan_is_rgb_with_nan_black_as_before(tmp_path):
    error = RNG.random((8, 8)).astype(np.float32)
    error[2, 3] = np.nan
    made = images.flip_indexed(error)
    assert isinstance(made, np.ndarray) and np.array_equal(made, magma_as_before(error))
    assert made[2, 3].tolist() == [0, 0, 0]


def visdiff_as_before(V, F):
    """The visibility-difference map as the sweep painted it before palettes."""
    grey = files.unit_to_u8(0.25 + 0.5 * np.clip(V, 0, 1))
    img = np.repeat(grey[..., None], 3, axis=-1)
    lit_v, lit_f = V >= compare.LIT_THRESHOLD, F >= compare.LIT_THRESHOLD
    img[lit_f & ~lit_v] = images.LEAK_RGB
    img[~lit_f & lit_v] = images.FALSE_SHADOW_RGB
    return img


@pytest.mark.parametrize("levels", [4, None])  # V = k/4 as spp 4 gives it; any value in [0, 1]
def test_the_visibility_difference_palette_png_decodes_to_the_rgb_map(tmp_path, levels):
    V = RNG.random((40, 50))
    V = (np.round(V * levels) / levels if levels else V).astype(np.float32)
    F = np.clip(V + RNG.normal(0, 0.3, V.shape), 0, 1).astype(np.float32)
    expected = visdiff_as_before(V, F)
    assert {tuple(images.LEAK_RGB), tuple(images.FALSE_SHADOW_RGB)} <= {
        tuple(p) for p in expected.reshape(-1, 3)
    }
    assert np.array_equal(images.visibility_diff_image(V, F), expected)
    made = images.visibility_diff_indexed(V, F)
    assert isinstance(made, files.Indexed) and len(made.palette) <= (levels or 128) + 3
    files.write_png(tmp_path / "vd.png", made)
    mode, back = png_mode_and_rgb(tmp_path / "vd.png")
    assert mode == "P" and np.array_equal(back, expected)


# -- the sweep's frame -------------------------------------------------------------------------


def synthetic_frame(size=32, grey=True):
    """What sweep._write_frame is given: truth and unshadowed frames, one technique's, compared."""
    ns = types.SimpleNamespace

    def render():
        img = RNG.random((size, size, 1 if grey else 3)).astype(np.float32) * 0.25
        return np.repeat(img, 3, axis=-1) if grey else img

    V = (RNG.integers(0, 5, (size, size)) / 4).astype(np.float32)
    F = RNG.random((size, size)).astype(np.float32)
    truth = ns(image=render(), variance={"image": render() * 1e-4}, layers={"visibility": V})
    frame = ns(image=render(), layers={"factor": F})
    maps = {"flip": RNG.random((size, size)).astype(np.float32), "display": compare.display(frame.image, 4.0)}
    return truth, ns(image=render()), [(ns(name="horizon", file_stem="horizon"), frame, {}, maps)]


@pytest.mark.parametrize("grey", [True, False])
def test_write_frame_stores_each_file_compactly_and_exactly(tmp_path, grey):
    truth, plain, compared = synthetic_frame(grey=grey)
    rel, per, seconds = sweep._write_frame(tmp_path, "az+0", truth, plain, compared, 4.0, all_files=True)
    assert seconds > 0 and per["horizon"]["flip_png"] == "frames/az+0/horizon_flip.png"
    layout = {k: exr_layout(tmp_path / p) for k, p in {**rel, **per["horizon"]}.items() if p.endswith(".exr")}
    colour = {"Y"} if grey else {"R", "G", "B"}
    for key in ("truth", "plain", "image", "truth_variance"):
        assert layout[key] == {**{c: "HALF" for c in colour}, "compression": "ZIP_COMPRESSION"}, key
    assert layout["visibility"]["Y"] == layout["factor"]["Y"] == "HALF"
    t, frame, _, maps = compared[0]
    for key, img in (("truth", truth.image), ("plain", plain.image)):
        back = files.read_rgb_exr(tmp_path / rel[key])
        assert np.array_equal(back, img.astype(np.float16).astype(np.float32)), key
    for key, img in (
        ("truth_png", compare.display(truth.image, 4.0)),
        ("plain_png", compare.display(plain.image, 4.0)),
    ):
        mode, back = png_mode_and_rgb(tmp_path / rel[key])
        assert mode == ("L" if grey else "RGB") and np.array_equal(back, files.unit_to_u8(img)), key
    V, F = truth.layers["visibility"], frame.layers["factor"]
    for key, want_mode, expected in (
        ("flip_png", "P", magma_as_before(maps["flip"])),
        ("visdiff_png", "P", visdiff_as_before(V, F)),
        ("png", "L" if grey else "RGB", files.unit_to_u8(maps["display"])),
    ):
        mode, back = png_mode_and_rgb(tmp_path / per["horizon"][key])
        assert mode == want_mode and np.array_equal(back, expected), key


def test_a_default_sweeps_renders_are_grey_and_score_from_their_files(variant, tmp_path):
    """The default scene (grey bricks, white light): every render is R == G == B, so one channel."""
    out = tmp_path / "sweep"
    assert (
        cli.main(
            [
                "sweep",
                "--size",
                "24",
                "--azimuths",
                "0",
                "--spp",
                "2",
                "--techniques",
                "horizon",
                "--quiet",
                "--all-files",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    (f,) = json.loads((out / "metrics.json").read_text())["frames"]
    own = f["techniques"]["horizon"]["files"]
    for path in (f["files"]["truth"], f["files"]["plain"], own["image"], f["files"]["truth_variance"]):
        assert set(files.read_exr(out / path)) == {"Y"}, path
    assert exr_layout(out / f["files"]["truth"])["Y"] == "HALF"
    modes = {
        key: png_mode_and_rgb(out / path)[0]
        for key, path in (
            ("truth_png", f["files"]["truth_png"]),
            ("plain_png", f["files"]["plain_png"]),
            *((k, own[k]) for k in ("png", "flip_png", "visdiff_png")),
        )
    }
    assert modes == {"truth_png": "L", "plain_png": "L", "png": "L", "flip_png": "P", "visdiff_png": "P"}


def test_by_default_a_frame_leaves_out_the_files_the_others_determine(tmp_path):
    """Without --all-files: no plain.exr, technique image EXR or V/F PNG; the rest as with it."""
    truth, plain, compared = synthetic_frame(grey=False)
    rel, per, _ = sweep._write_frame(tmp_path, "az+0", truth, plain, compared, 4.0)
    assert set(rel) == {"truth", "truth_variance", "visibility", "truth_png", "plain_png"}
    assert set(per["horizon"]) == {"png", "flip_png", "factor", "visdiff_png"}
    written = {p.name for p in (tmp_path / "frames" / "az+0").iterdir()}
    assert written == {
        "truth.exr",
        "truth_variance.exr",
        "visibility.exr",
        "truth.png",
        "plain.png",
        "horizon.png",
        "horizon_flip.png",
        "horizon_factor.exr",
        "horizon_visdiff.png",
    }
