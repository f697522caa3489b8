"""``hzval bake`` end to end: the files it writes, and what it does with bad input."""

import json
import subprocess
import sys
import zlib

import numpy as np
import pytest
from PIL import Image

from hzval.cli import main as cli
from hzval.io import codecs

BAKE_FILES = {
    "horizon0.exr",
    "horizon1.exr",
    "horizon0.png",
    "horizon1.png",
    "normal.exr",
    "normal.png",
    "ambient.exr",
    "bent_normal.exr",
    "bent_normal.png",
    "ssbump.exr",
    "ssbump.png",
    "bake.json",
} | {f"cube/{f}.png" for f in ("posx", "negx", "posy", "negy", "posz", "negz")}


def listing(folder):
    return {str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file() and p.name != ".hzval"}


@pytest.fixture(scope="module")
def height_png(tmp_path_factory):
    """A 40x24 16-bit PNG whose values are exact in 8 bits too (multiples of 257)."""
    rng = np.random.default_rng(11)
    v8 = rng.integers(0, 256, size=(24, 40), dtype=np.uint16)
    d = tmp_path_factory.mktemp("inputs")
    Image.fromarray((v8 * 257).astype(np.uint16)).save(d / "h16.png")
    Image.fromarray(v8.astype(np.uint8)).save(d / "h8.png")
    return d


def run(*argv):
    return cli.main([str(a) for a in argv])


def test_bake_writes_every_file_and_a_record(variant, height_png, tmp_path):
    out = tmp_path / "out"
    assert (
        run(
            "bake",
            height_png / "h16.png",
            "--depth",
            "0.1",
            "--radius",
            "5",
            "--angles",
            "16",
            "--boundary",
            "open",
            "--out",
            out,
        )
        == 0
    )
    assert listing(out) == BAKE_FILES
    record = json.loads((out / "bake.json").read_text())
    assert record["parameters"] == {
        "depth": 0.1,
        "radius": 5,
        "angles": 16,
        "boundary": "open",
        "method": "seed",
        "directions": 8,
        "ssbump_lift": 0.55,
    }
    assert record["input"]["digest"].startswith("sha256:")
    assert record["input"]["rows"] == 24 and record["input"]["cols"] == 40
    assert "horizon_s" in record["timings_s"] and record["versions"]["mitsuba"]
    h0 = codecs.read_exr(out / "horizon0.exr")
    assert set(h0) == {"R", "G", "B", "A"} and h0["R"].shape == (24, 40)
    png = np.asarray(Image.open(out / "horizon0.png"))
    assert png.shape == (24, 40, 4)
    assert np.abs(png[..., 1] / 255.0 - h0["G"]).max() <= 0.5 / 255 + 1e-6
    amb = codecs.read_exr(out / "ambient.exr")
    assert set(amb) == {"mean_cos", "mean_cos2"}
    n = codecs.read_exr(out / "normal.exr")
    assert np.allclose(n["R"] ** 2 + n["G"] ** 2 + n["B"] ** 2, 1.0, atol=1e-5)
    assert [p.name for p in out.iterdir() if p.name.startswith(".")] == [".hzval"]  # no staging or lock left


def test_8_and_16_bit_png_of_the_same_data_bake_the_same(variant, height_png, tmp_path):
    for name in ("h8", "h16"):
        assert (
            run(
                "bake",
                height_png / f"{name}.png",
                "--radius",
                "5",
                "--angles",
                "16",
                "--out",
                tmp_path / name,
            )
            == 0
        )
    for f in ("horizon0.exr", "horizon1.exr", "normal.exr", "ambient.exr"):
        a, b = codecs.read_exr(tmp_path / "h8" / f), codecs.read_exr(tmp_path / "h16" / f)
        for ch in a:
            assert np.array_equal(a[ch], b[ch]), (f, ch)


def test_builtin_material_bakes_with_no_input(variant, tmp_path):
    assert run("bake", "--size", "48", "--radius", "5", "--angles", "16", "--mesh", "--out", tmp_path) == 0
    record = json.loads((tmp_path / "bake.json").read_text())
    assert record["input"]["builtin"] == "bricks" and record["input"]["path"] is None
    assert (tmp_path / "mesh.ply").stat().st_size > 0


def _truncated_png(path):
    Image.fromarray(np.arange(64 * 64, dtype=np.uint16).reshape(64, 64)).save(path)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


def _huge_png(path):
    # a valid PNG header claiming 200000 x 200000 pixels, and no pixel data
    def chunk(kind, body):
        return len(body).to_bytes(4, "big") + kind + body + zlib.crc32(kind + body).to_bytes(4, "big")

    ihdr = (200000).to_bytes(4, "big") * 2 + bytes([16, 0, 0, 0, 0])
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IEND", b""))


BAD_INPUTS = {
    "missing": (lambda p: None, "missing.png"),
    "empty": (lambda p: p.write_bytes(b""), "empty.png"),
    "truncated": (_truncated_png, "cut.png"),
    "corrupt": (lambda p: p.write_bytes(b"\x89PNG\r\n\x1a\n" + b"\x00garbage" * 20), "corrupt.png"),
    "not an image": (lambda p: p.write_text("hello"), "notes.txt"),
    "nan": (lambda p: np.save(p, np.array([[0.0, np.nan], [1.0, 0.5]])), "nan.npy"),
    "inf": (lambda p: np.save(p, np.array([[0.0, np.inf], [1.0, 0.5]])), "inf.npy"),
    "one pixel": (lambda p: Image.fromarray(np.zeros((1, 1), np.uint8)).save(p), "one.png"),
    "too big for memory": (_huge_png, "huge.png"),
}


@pytest.mark.parametrize("case", sorted(BAD_INPUTS))
def test_bad_input_is_one_line_exit_2_and_no_files(case, tmp_path, capsys):
    make, name = BAD_INPUTS[case]
    path = tmp_path / name
    make(path)
    out = tmp_path / "out"
    assert run("bake", path, "--out", out) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"hzval: error: {path}: ") and err.count("\n") == 1, err
    assert not out.exists()


@pytest.mark.parametrize(
    "flags,what",
    [
        (["--depth", "0"], "--depth"),
        (["--depth", "-0.5"], "--depth"),
        (["--angles", "20"], "--angles"),
        (["--size", "1"], "--size"),
        (["--directions", "12"], "--directions"),
        (["--directions", "16", "--angles", "48"], "--angles"),
        (["--directions", "16", "--method", "exact"], "--directions"),
    ],
)
def test_bad_parameter_is_one_line_exit_2_and_no_files(flags, what, tmp_path, capsys):
    out = tmp_path / "out"
    assert run("bake", *flags, "--out", out) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"hzval: error: {what}: ") and err.count("\n") == 1, err
    assert not out.exists()


def test_the_console_script_exits_2_without_a_traceback(tmp_path):
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"")
    proc = subprocess.run(
        [sys.executable, "-m", "hzval", "bake", str(bad), "--out", str(tmp_path / "o")],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and proc.stderr.strip() == f"hzval: error: {bad}: file is empty"


def test_usage_errors_exit_2(capsys):
    with pytest.raises(SystemExit) as e:
        cli.main(["bake"])  # --out is required
    assert e.value.code == 2


def test_sixteen_directions_bake_four_layers_and_no_cube(variant, tmp_path):
    out = tmp_path / "out"
    assert run("bake", "--size", 24, "--directions", 16, "--out", out) == 0
    names = {p.name for p in out.iterdir()}
    assert {f"horizon{i}.{e}" for i in range(4) for e in ("exr", "png")} <= names
    assert "cube" not in names
    assert json.loads((out / "bake.json").read_text())["parameters"]["directions"] == 16
