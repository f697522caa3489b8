"""``hzval score`` as a comparison: frames of an independent NumPy shader, rendered from frames.json alone,
scored beside the sweep's own techniques, with F images, a sidecar, and the brightness slips."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from hzval import materials
from hzval.cli import main as cli
from hzval.io import codecs

SIZE, DEPTH = 32, 0.1


@pytest.fixture(scope="module")
def sweep_dir(tmp_path_factory, variant):
    out = tmp_path_factory.mktemp("engine") / "sweep"
    assert (
        cli.main(
            [
                "sweep",
                "--material",
                "bricks",
                "--size",
                str(SIZE),
                "--depth",
                str(DEPTH),
                "--azimuths=-60,0,60",
                "--spp",
                "4",
                "--quiet",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    return out


def shade(height: np.ndarray, depth: float, L, albedo: float, irradiance: float):
    """A toy engine: one sample at each pixel's centre, central-difference normals, Lambert, and a shadow
    ray marched over the height map in half-texel steps (nearest texel, wrapping). Not hzval's code."""
    rows, cols = height.shape
    h = height * depth * cols  # texels
    gx = (np.roll(h, -1, 1) - np.roll(h, 1, 1)) / 2  # d/dx, +x = columns
    gy = -(np.roll(h, -1, 0) - np.roll(h, 1, 0)) / 2  # d/dy, +y = up the image = -rows
    n = np.stack([-gx, -gy, np.ones_like(h)], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    cos = np.clip(n @ np.asarray(L), 0, None)
    r, c = np.mgrid[0:rows, 0:cols].astype(np.float64)
    x, y, z = c + 0.5, rows - r - 0.5, h + 1e-3
    lit = np.ones_like(h, bool)
    step = 0.5 / math.hypot(L[0], L[1])
    for k in range(1, int(4 * cols)):
        t = k * step
        px, py, pz = x + L[0] * t, y + L[1] * t, z + L[2] * t
        ci, ri = np.floor(px).astype(int) % cols, (rows - 1 - np.floor(py).astype(int)) % rows
        lit &= h[ri, ci] <= pz
    F = (lit & (cos > 0)).astype(np.float32)
    image = albedo / math.pi * irradiance * cos * F
    return np.repeat(image[..., None], 3, -1).astype(np.float32), F


def render(sweep_dir, folder, factor: float = 1.0, with_f: bool = True):
    spec = json.loads((sweep_dir / "frames.json").read_text())
    assert spec["albedo"]["kind"] == "constant" and spec["samples"]["spp"] == 4 and "rule" in spec["samples"]
    assert set(spec["exposure_meaning"]) >= {"exr", "png"} and "radiance" in spec["light"]
    height = materials.generate("bricks", SIZE).height
    folder.mkdir()
    for f in spec["frames"]:
        img, F = shade(
            height, DEPTH, f["light_direction"], spec["albedo"]["linear"], spec["light"]["irradiance"]
        )
        codecs.write_exr(folder / f"{f['name']}.exr", {"RGB": img * factor})
        if with_f:
            codecs.write_exr(folder / f"f_{f['name']}.exr", {"Y": F})
    return folder


def test_an_independent_shader_beside_hzvals_techniques(sweep_dir, tmp_path, capsys):
    frames = render(sweep_dir, tmp_path / "frames")
    (frames / "engine.toml").write_text('[engine]\nlabel = "toy engine"\n[parameters]\nshadow_steps = 128\n')
    out = tmp_path / "score"
    assert (
        cli.main(
            [
                "score",
                str(frames),
                "--against",
                str(sweep_dir),
                "--out",
                str(out),
                "--fail-if",
                "engine.visibility_mae>0.5",
            ]
        )
        == 0
    )
    m = json.loads((out / "metrics.json").read_text())
    swept = json.loads((sweep_dir / "metrics.json").read_text())
    assert list(m["techniques"]) == ["engine", *swept["techniques"]]
    assert m["techniques"]["engine"]["label"] == "toy engine"
    assert m["techniques"]["engine"]["parameters"] == {"shadow_steps": 128}  # only what the sidecar says
    assert m["techniques"]["horizon"]["parameters"] == swept["techniques"]["horizon"]["parameters"]
    for mine, theirs in zip(m["frames"], swept["frames"]):
        e = mine["techniques"]["engine"]
        for key in (
            "visibility_mae",
            "leak_fraction",
            "false_shadow_fraction",
            "visibility_mae_facing",
            "flip_mean",
            "rmse",
            "psnr_db",
            "delta_e2000_mean",
        ):
            assert key in e, key
        assert 0 < e["visibility_mae"] < 0.2 and e["flip_mean"] < 0.2
        assert mine["techniques"]["horizon"]["flip_mean"] == theirs["techniques"]["horizon"]["flip_mean"]
        assert (out / e["files"]["visdiff_png"]).is_file() and (
            out / mine["techniques"]["horizon"]["files"]["png"]
        ).is_file()
    html = (out / "index.html").read_text(encoding="utf-8")
    assert "toy engine" in html and "horizon map" in html
    table = capsys.readouterr().out
    rows = [line.split()[0] for line in table.splitlines()[2:]]
    assert rows[:4] == ["engine", "horizon", "terrain", "pom"]
    # one sample per pixel against the sweep's four: the engine's FLIP is above the horizon map's in
    # every frame, and a gate comparing the two names them all
    worse = [
        f
        for f in m["frames"]
        if f["techniques"]["engine"]["flip_mean"] > f["techniques"]["horizon"]["flip_mean"]
    ]
    code = cli.main(
        [
            "score",
            str(frames),
            "--against",
            str(sweep_dir),
            "--out",
            str(tmp_path / "gated"),
            "--fail-if",
            "engine.flip_mean>horizon.flip_mean",
        ]
    )
    assert code == (1 if worse else 0)
    if worse:
        assert f"{len(worse)} of 3 frames" in capsys.readouterr().err


def test_frames_pi_times_too_bright_are_named(sweep_dir, tmp_path, capsys):
    frames = render(sweep_dir, tmp_path / "bright", factor=math.pi, with_f=False)
    assert cli.main(["score", str(frames), "--against", str(sweep_dir), "--out", str(tmp_path / "o")]) == 0
    err = capsys.readouterr().err
    assert "3 frame(s)" in err and "pi times too bright" in err and "1/pi" in err
    m = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert "visibility_mae" not in m["frames"][0]["techniques"]["engine"]  # no F given: none measured


def test_bad_sidecars_and_partial_factors_are_one_line(sweep_dir, tmp_path, capsys):
    frames = render(sweep_dir, tmp_path / "f")
    (frames / "f_az+0.exr").unlink()
    assert cli.main(["score", str(frames), "--against", str(sweep_dir), "--out", str(tmp_path / "a")]) == 2
    assert "f_az+0.exr: missing: F is given for 2 of 3 lights" in capsys.readouterr().err
    frames = render(sweep_dir, tmp_path / "g")
    (frames / "engine.toml").write_text('[engine]\nlabl = "x"\n')
    assert cli.main(["score", str(frames), "--against", str(sweep_dir), "--out", str(tmp_path / "b")]) == 2
    assert "unknown key 'labl' in [engine]; did you mean 'label'?" in capsys.readouterr().err
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()
