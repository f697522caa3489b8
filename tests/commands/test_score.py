"""``hzval score``: an engine's frames scored against a sweep's truth, with the sweep's own metrics."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from hzval.cli import main as cli
from hzval.io import codecs


@pytest.fixture(scope="module")
def sweep_dir(tmp_path_factory, variant):
    out = tmp_path_factory.mktemp("score") / "sweep"
    assert (
        cli.main(
            [
                "sweep",
                "--size",
                "48",
                "--azimuths",
                "-30,0,30",
                "--spp",
                "4",
                "--quiet",
                "--all-files",
                "--out",
                str(out),
            ]
        )
        == 0
    )  # the technique's own EXRs are scored as an engine's
    return out


def engine(tmp, sweep_dir, source: str, ext: str = "exr"):
    """A folder of 'engine frames': copies of one of the sweep's own images per light."""
    frames = json.loads((sweep_dir / "frames.json").read_text())["frames"]
    d = tmp / f"{source}_{ext}"
    d.mkdir()
    for f in frames:
        shutil.copyfile(sweep_dir / "frames" / f["name"] / f"{source}.{ext}", d / f"{f['name']}.{ext}")
    return d


def test_frames_json_says_how_to_render_the_frames(sweep_dir):
    e = json.loads((sweep_dir / "frames.json").read_text())
    m = json.loads((sweep_dir / "metrics.json").read_text())
    assert e["image_size"] == [48, 48] and e["camera"] == m["camera"] and e["camera"]["kind"] == "top"
    assert e["exposure"] == pytest.approx(m["exposure"]["scale"])
    assert [f["name"] for f in e["frames"]] == ["az-30", "az+0", "az+30"]
    L = np.array(e["frames"][0]["light_direction"])
    assert np.linalg.norm(L) == pytest.approx(1) and L[2] == pytest.approx(np.sin(np.radians(30)))
    assert L[1] < 0  # azimuth -30: counterclockwise from +x, so below the x axis


def test_the_sweeps_own_images_reproduce_its_scores(sweep_dir, tmp_path):
    """The horizon map's EXRs scored as an engine's give the sweep's FLIP (to 2e-5: the same
    computation, but the files are half float); its truth gives 0; its 8-bit sRGB previews add
    their quantisation (under 0.01)."""
    m = json.loads((sweep_dir / "metrics.json").read_text())
    # horizon.exr and truth.exr hold half floats (2^-11 relative), the sweep scored float32 in memory:
    # measured at most 6e-6 FLIP at this size, a thousandth of what 8-bit quantisation adds (4e-3)
    for source, ext, tol in (("horizon", "exr", 2e-5), ("truth", "exr", 0), ("horizon", "png", 0.01)):
        out = tmp_path / f"out_{source}_{ext}"
        assert (
            cli.main(
                [
                    "score",
                    str(engine(tmp_path, sweep_dir, source, ext)),
                    "--against",
                    str(sweep_dir),
                    "--out",
                    str(out),
                ]
            )
            == 0
        )
        s = json.loads((out / "metrics.json").read_text())
        for mine, swept in zip(s["frames"], m["frames"]):
            assert mine["azimuth_deg"] == swept["azimuth_deg"]
            theirs = swept["techniques"]["horizon"]
            expect = 0.0 if source == "truth" else theirs["flip_mean"]
            assert mine["flip_mean"] == pytest.approx(expect, abs=tol + 1e-12)
            if (source, ext) == ("horizon", "exr"):  # the other scores: measured 1.4e-5, 1.3e-6
                assert mine["delta_e2000_mean"] == pytest.approx(theirs["delta_e2000_mean"], abs=1e-4)
                assert mine["rmse"] == pytest.approx(theirs["rmse"], abs=tol)
            if source == "truth":
                # 0 on LLVM (PSNR infinite, recorded null); on CUDA the compiler fuses the scaled
                # difference into a multiply-add: 2e-17, PSNR 340 dB
                assert mine["rmse"] <= 1e-12 and (mine["psnr_db"] is None or mine["psnr_db"] > 200)
        html = (out / "index.html").read_text(encoding="utf-8")
        assert "your renderer" in html and (out / "frames" / "az+0" / "engine_flip.png").is_file()


def test_bad_frames_are_one_line_errors(sweep_dir, tmp_path, capsys):
    good = engine(tmp_path, sweep_dir, "horizon")
    cases = []
    missing = tmp_path / "missing"
    shutil.copytree(good, missing)
    (missing / "az+0.exr").unlink()
    cases.append((missing, sweep_dir, "az+0"))
    small = tmp_path / "small"
    shutil.copytree(good, small)
    codecs.write_exr(small / "az+0.exr", {"RGB": np.zeros((8, 8, 3), np.float32)})
    cases.append((small, sweep_dir, "8x8"))
    nan = tmp_path / "nan"
    shutil.copytree(good, nan)
    img = np.zeros((48, 48, 3), np.float32)
    img[3, 4] = np.nan
    codecs.write_exr(nan / "az+0.exr", {"RGB": img})
    cases.append((nan, sweep_dir, "non-finite"))
    cases.append((good, tmp_path, "is not a sweep's folder"))
    for frames, against, needle in cases:
        out = tmp_path / f"o_{frames.name}_{against.name}"
        assert cli.main(["score", str(frames), "--against", str(against), "--out", str(out)]) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("hzval: error:") and needle in err and "\n" not in err, err
        assert not out.exists()
