"""Every bad input a clear error: one line on stderr naming the culprit, exit status 2, no files,
never a traceback; through hzval.cli.main.main and once through the installed console script.

(tests/integration/test_bake.py and tests/pipeline/test_sweep.py check a few of these for one command
each; here every case runs against both commands where it applies.)
"""

import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from hzval.cli import main as cli

pytestmark = pytest.mark.hard


def _truncated_png(p):
    Image.fromarray(np.arange(64 * 64, dtype=np.uint16).reshape(64, 64)).save(p)
    data = p.read_bytes()
    p.write_bytes(data[: len(data) // 2])


def _huge_png(p):
    def chunk(kind, body):
        return len(body).to_bytes(4, "big") + kind + body + zlib.crc32(kind + body).to_bytes(4, "big")

    p.write_bytes(
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", (200000).to_bytes(4, "big") * 2 + bytes([16, 0, 0, 0, 0]))
        + chunk(b"IEND", b"")
    )


FILES = {
    "missing": (lambda p: None, "missing.png"),
    "empty": (lambda p: p.write_bytes(b""), "empty.png"),
    "truncated": (_truncated_png, "cut.png"),
    "corrupt": (lambda p: p.write_bytes(b"\x89PNG\r\n\x1a\n" + b"\x00garbage" * 20), "corrupt.png"),
    "text": (lambda p: p.write_text("hello"), "notes.txt"),
    "exr-garbage": (lambda p: p.write_bytes(b"v/1\x01" + b"\x00" * 40), "bad.exr"),
    "nan": (lambda p: np.save(p, np.array([[0.0, np.nan], [1.0, 0.5]])), "nan.npy"),
    "inf": (lambda p: np.save(p, np.array([[0.0, np.inf], [1.0, 0.5]])), "inf.npy"),
    "overflow": (lambda p: np.save(p, np.array([[0.0, 1e300], [1.0, 0.5]])), "big.npy"),
    "strings": (lambda p: np.save(p, np.array([["a", "b"], ["c", "d"]])), "str.npy"),
    "3 channels": (lambda p: np.save(p, np.zeros((4, 4, 3))), "rgb.npy"),
    "one pixel": (lambda p: Image.fromarray(np.zeros((1, 1), np.uint8)).save(p), "one.png"),
    "too big": (_huge_png, "huge.png"),
    "directory": (lambda p: p.mkdir(), "folder.png"),
}


def run(argv, capsys):
    code = cli.main([str(a) for a in argv])
    return code, capsys.readouterr().err


def assert_one_line(err, needle):
    assert err.startswith("hzval: error: ") and err.count("\n") == 1, err
    assert needle in err and "Traceback" not in err, err


@pytest.mark.parametrize("command", ["bake", "sweep"])
@pytest.mark.parametrize("case", sorted(FILES))
def test_bad_height_file(case, command, tmp_path, capsys):
    make, name = FILES[case]
    path = tmp_path / name
    make(path)
    out = tmp_path / "out"
    extra = ["--quiet", "--spp", "1", "--azimuths", "0"] if command == "sweep" else []
    code, err = run([command, path, *extra, "--out", out], capsys)
    assert code == 2
    assert_one_line(err, str(path))
    assert not out.exists()


BAKE_FLAGS = [
    (["--depth", "0"], "--depth"),
    (["--depth", "-1"], "--depth"),
    (["--depth", "nan"], "--depth"),
    (["--depth", "inf"], "--depth"),
    (["--radius", "1"], "--radius"),
    (["--radius", "100000"], "GiB"),
    (["--angles", "20"], "--angles"),
    (["--angles", "0"], "--angles"),
]


@pytest.mark.parametrize("flags,needle", BAKE_FLAGS, ids=[" ".join(f) for f, _ in BAKE_FLAGS])
def test_bad_bake_parameter(flags, needle, tmp_path, capsys):
    np.save(tmp_path / "h.npy", np.zeros((8, 8), np.float32))
    out = tmp_path / "out"
    code, err = run(["bake", tmp_path / "h.npy", *flags, "--out", out], capsys)
    assert code == 2
    assert_one_line(err, needle)
    assert not out.exists()


SWEEP_FLAGS = [
    (["--depth", "0"], "depth"),
    (["--depth", "nan"], "depth"),
    (["--elevation", "91"], "elevation"),
    (["--elevation", "nan"], "elevation"),
    (["--azimuths", "a:b"], "azimuths"),
    (["--azimuths", "0:1:0"], "azimuths"),
    (["--azimuths", "nan"], "azimuths"),
    (["--azimuths", "0,inf"], "azimuths"),
    (["--k", "0"], "--k"),
    (["--k", "inf"], "--k"),
    (["--effects", "glitter"], "effects"),
    (["--effects", ","], "effects"),
    (["--light", "soft", "--light-radius", "0"], "radius"),
    (["--light", "soft", "--light-radius", "nan"], "radius"),
    (["--spp", "0"], "spp"),
    (["--supersampling", "0"], "supersampling"),
    (["--seed", "-1"], "seed"),
    (["--radius", "1"], "--radius"),
    (["--angles", "24"], "--angles"),
    (["--size", "4"], "size"),
    (["--size", "1"], "size"),
]


@pytest.mark.parametrize("flags,needle", SWEEP_FLAGS, ids=[" ".join(f) for f, _ in SWEEP_FLAGS])
def test_bad_sweep_parameter(flags, needle, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "out"
    argv = ["sweep", "--size", "16", "--azimuths", "0", "--spp", "1", "--quiet", *flags, "--out", out]
    code, err = run(argv, capsys)
    assert code == 2
    assert_one_line(err, needle)
    assert not out.exists()


SCENES = {
    "depth is text": '[material]\ndepth = "deep"\n',
    "irradiance 0": "[light]\nirradiance = 0\n",
    "irradiance negative": "[light]\nirradiance = -1.0\n",
    "spp is text": '[samples]\nspp = "x"\n',
    "interreflection depth "
    "1": '[effects]\nlist = ["shadow", "diffuse", "interreflection"]\ninterreflection_depth = 1\n',
    "unknown key": "[light]\ncolour = 3\n",
    "not toml": "[light\n",
    "azimuth text": '[light]\nazimuths = ["a"]\n',
}


@pytest.mark.parametrize("case", sorted(SCENES))
def test_bad_scene_file(case, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    scene = tmp_path / "s.toml"
    scene.write_text(SCENES[case])
    out = tmp_path / "out"
    code, err = run(
        ["sweep", "--scene", scene, "--size", "16", "--azimuths", "0", "--spp", "1", "--quiet", "--out", out],
        capsys,
    )
    assert code == 2
    assert_one_line(err, str(scene))
    assert not out.exists()


def test_a_1xN_map_is_refused_and_a_missing_scene_is_refused(tmp_path, capsys, monkeypatch):
    """A 1xN map is refused in one line before anything is written (the input rule: at least 8 x 8
    texels); past that rule, the pipeline still takes it (the truth refused one once, after the
    sweep had written its bake: exit 2 with files left behind)."""
    np.save(tmp_path / "row.npy", np.random.default_rng(0).random((1, 16)).astype(np.float32))
    out = tmp_path / "out"
    argv = ["sweep", tmp_path / "row.npy", "--azimuths", "0,90", "--spp", "1", "--quiet", "--out", out]
    code, err = run(argv, capsys)
    assert code == 2 and not out.exists()
    assert_one_line(err, "row.npy")
    from hzval.io import heightmap

    monkeypatch.setattr(heightmap, "check_usable", lambda hm: hm)
    code, _ = run(argv, capsys)
    assert code == 0 and (out / "metrics.json").exists()
    code, err = run(["sweep", "--scene", tmp_path / "none.toml", "--out", tmp_path / "o2"], capsys)
    assert code == 2
    assert_one_line(err, "none.toml")
    assert not (tmp_path / "o2").exists()


@pytest.mark.parametrize(
    "argv",
    [
        ["bake"],
        ["bake", "--out"],
        ["sweep", "--boundary", "mirror"],
        ["frobnicate"],
        ["sweep", "--spp", "many"],
        [],
    ],
)
def test_usage_errors_exit_2_without_a_traceback(argv, capsys):
    with pytest.raises(SystemExit) as e:
        cli.main(argv)
    assert e.value.code == 2
    err = capsys.readouterr().err
    # one line and where to read more; the usage block buried the error (issue 41)
    assert err.startswith("hzval: error: ") and err.count("\n") == 1 and "--help'" in err
    assert "usage:" not in err and "Traceback" not in err


def test_bake_builtin_size_below_8_is_a_clear_error(tmp_path, capsys):
    code, err = run(["bake", "--size", "4", "--out", tmp_path / "out"], capsys)
    assert code == 2
    assert_one_line(err, "--size")


def test_bake_builtin_size_too_big_for_memory_is_a_clear_error(tmp_path, capsys):
    code, err = run(["bake", "--size", "200000", "--out", tmp_path / "out"], capsys)
    assert code == 2
    assert_one_line(err, "GiB")


def test_the_console_script_prints_one_line_and_no_traceback(tmp_path):
    script = Path(sys.executable).parent / "hzval"
    assert script.exists(), script
    bad = tmp_path / "nan.npy"
    np.save(bad, np.array([[0.0, np.nan], [1.0, 0.5]]))
    for argv in (
        ["bake", str(bad), "--out", str(tmp_path / "o1")],
        ["sweep", "--size", "16", "--azimuths", "nan", "--quiet", "--out", str(tmp_path / "o2")],
    ):
        proc = subprocess.run(
            [str(script), *argv],
            capture_output=True,
            text=True,
            timeout=300,
            # a bare environment but HOME: without it Dr.Jit warns on stderr that it keeps no kernel cache
            env={"HZVAL_VARIANT": "llvm_ad_rgb", "PATH": "/usr/bin:/bin", "HOME": str(tmp_path)},
        )
        assert proc.returncode == 2, proc.stderr
        assert "Traceback" not in proc.stderr and proc.stderr.count("\n") == 1, proc.stderr
        assert proc.stderr.startswith("hzval: error: ")
    assert not (tmp_path / "o1").exists() and not (tmp_path / "o2").exists()
