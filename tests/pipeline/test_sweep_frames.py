"""The sweep's frame files (hzval.pipeline.sweep): each file stored in its compact form and exactly, the
files the others determine left out by default, and a default sweep's renders grey and scored from them."""

from __future__ import annotations

import json
import types

import numpy as np
import pytest

from hzval.cli import main as cli
from hzval.io import codecs
from hzval.metrics import compare
from hzval.pipeline import writing as pipeline_writing
from tests.helpers import exr_layout, magma_as_before, png_mode_and_rgb, visdiff_as_before

RNG = np.random.default_rng(7)


# -- the sweep's frame -------------------------------------------------------------------------


def write_frame(out, truth, plain, compared, scale, all_files=False):
    """A frame's files as the sweep starts them: each technique's, then the truth's; their paths."""
    V = truth.layers.get("visibility")
    with pipeline_writing.FrameWriter(out, "az+0", scale, None, all_files) as writer:
        per = {t.name: writer.technique_files(t.file_stem, f, maps, V) for t, f, _, maps in compared}
        rel = writer.truth_files(truth, plain)
    return rel, per


def synthetic_frame(size=32, grey=True):
    """What a FrameWriter is given: truth and unshadowed frames, one technique's, compared."""
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
def test_a_frames_files_are_stored_compactly_and_exactly(tmp_path, grey):
    truth, plain, compared = synthetic_frame(grey=grey)
    rel, per = write_frame(tmp_path, truth, plain, compared, 4.0, all_files=True)
    assert per["horizon"]["flip_png"] == "frames/az+0/horizon_flip.png"
    layout = {k: exr_layout(tmp_path / p) for k, p in {**rel, **per["horizon"]}.items() if p.endswith(".exr")}
    colour = {"Y"} if grey else {"R", "G", "B"}
    for key in ("truth", "plain", "image", "truth_variance"):
        assert layout[key] == {**{c: "HALF" for c in colour}, "compression": "ZIP_COMPRESSION"}, key
    assert layout["visibility"]["Y"] == layout["factor"]["Y"] == "HALF"
    t, frame, _, maps = compared[0]
    for key, img in (("truth", truth.image), ("plain", plain.image)):
        back = codecs.read_rgb_exr(tmp_path / rel[key])
        assert np.array_equal(back, img.astype(np.float16).astype(np.float32)), key
    for key, img in (
        ("truth_png", compare.display(truth.image, 4.0)),
        ("plain_png", compare.display(plain.image, 4.0)),
    ):
        mode, back = png_mode_and_rgb(tmp_path / rel[key])
        assert mode == ("L" if grey else "RGB") and np.array_equal(back, codecs.unit_to_u8(img)), key
    V, F = truth.layers["visibility"], frame.layers["factor"]
    for key, want_mode, expected in (
        ("flip_png", "P", magma_as_before(maps["flip"])),
        ("visdiff_png", "P", visdiff_as_before(V, F)),
        ("png", "L" if grey else "RGB", codecs.unit_to_u8(maps["display"])),
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
        assert set(codecs.read_exr(out / path)) == {"Y"}, path
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
    rel, per = write_frame(tmp_path, truth, plain, compared, 4.0)
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
