"""``hzval sweep`` end to end on small maps: metrics.json as docs/ARCHITECTURE.md fixes it, the frames it
points to, the bake cache, analytic answers for a flat map and a wall, and bad input."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from hzval.cli import main as cli
from hzval.core import resources
from hzval.io import codecs, staging
from hzval.pipeline import records as pipeline_records
from hzval.pipeline import sweep
from hzval.pipeline import writing as pipeline_writing
from hzval.techniques import registry as technique
from hzval.truth import memory

# docs/ARCHITECTURE.md, "metrics.json".
TOP_KEYS = {
    "schema_version",
    "material",
    "parameters",
    "versions",
    "timings",
    "simulated",
    "techniques",
    "frames",
}
FRAME_KEYS = {"name", "azimuth_deg", "elevation_deg", "truth_s", "files", "techniques", "truth", "no_shadows"}
SCORES = {
    "visibility_mae",
    "leak_fraction",
    "false_shadow_fraction",
    "flip_mean",
    "rmse",
    "psnr_db",
    "delta_e2000_mean",
    "seconds",
    "files",
}
FRAME_FILES = {"truth", "truth_variance", "visibility", "truth_png", "plain_png"}
#: What only --all-files adds (pipeline_writing.FrameWriter): files the others determine.
DERIVED_FILES = {"plain", "visibility_png"}


#: The techniques a sweep renders without --techniques (the GL ones are opt-in:
#: tests/techniques/gl/test_horizon_gl.py).
DEFAULT_TECHNIQUES = [n for n in technique.names() if technique.get(n).by_default]


def run(*argv) -> int:
    return cli.main([str(a) for a in argv])


@pytest.fixture(scope="module")
def bricks_sweep(tmp_path_factory):
    """The default sweep's shape on a 48x48 built-in brick wall, three lights; run twice."""
    out = tmp_path_factory.mktemp("sweep") / "bricks"
    argv = ("sweep", "--size", 48, "--azimuths", "-15:15:15", "--spp", 4, "--quiet", "--out", out)
    assert run(*argv) == 0
    first = json.loads((out / "metrics.json").read_text())
    assert run(*argv) == 0
    second = json.loads((out / "metrics.json").read_text())
    return out, first, second


def test_metrics_json_has_the_documented_shape(variant, bricks_sweep):
    out, m, _ = bricks_sweep
    assert TOP_KEYS <= set(m)
    assert [f["azimuth_deg"] for f in m["frames"]] == [-15.0, 0.0, 15.0]
    assert m["schema_version"] == sweep.SCHEMA_VERSION == 2
    for f in m["frames"]:
        assert set(f) - {"floor"} == FRAME_KEYS
        assert FRAME_FILES <= set(f["files"]) and not DERIVED_FILES & set(f["files"])
        assert f["elevation_deg"] == 30.0 and f["truth_s"] > 0
        for name, te in f["techniques"].items():
            assert SCORES <= set(te), name
            for key in ("visibility_mae", "leak_fraction", "false_shadow_fraction", "flip_mean"):
                assert 0.0 <= te[key] <= 1.0, key
            assert te["seconds"] > 0
    # the default scene: Figure 5.3's Lambertian wall with shadows, and only that
    assert m["simulated"] == {
        "truth": ["shadow", "diffuse"],
        **{name: ["shadow", "diffuse"] for name in DEFAULT_TECHNIQUES},
    }
    assert list(m["techniques"]) == DEFAULT_TECHNIQUES  # every technique applies, in registry order
    assert m["parameters"]["azimuths_deg"] == [-15.0, 0.0, 15.0]
    assert m["parameters"]["spp"] == 4
    assert m["memory"]["peak_rss_bytes"] > 2**20
    assert {"mitsuba", "drjit"} <= {k.lower() for k in m["versions"]}


def test_frame_files_exist_and_hold_what_they_say(variant, bricks_sweep):
    out, m, _ = bricks_sweep
    for f in m["frames"]:
        for rel in f["files"].values():
            assert not rel.startswith("/") and (out / rel).is_file(), rel
        V = codecs.read_exr(out / f["files"]["visibility"])
        F = codecs.read_exr(out / f["techniques"]["horizon"]["files"]["factor"])
        assert list(V) == ["Y"] and list(F) == ["Y"]  # one-channel
        assert V["Y"].shape == F["Y"].shape == (48, 48)  # one pixel per texel
        for layer in (V["Y"], F["Y"]):
            assert np.isfinite(layer).all() and layer.min() >= 0 and layer.max() <= 1
        # the metrics are those of the stored layers, which are half floats (the metrics were computed
        # in float32): each F within 2^-12 of its value in [0, 1] (V = k/4 is exact); measured 9e-7
        assert f["techniques"]["horizon"]["visibility_mae"] == pytest.approx(
            float(np.mean(np.abs(F["Y"] - V["Y"]))), abs=2**-12
        )
        # the bricks (2.4 texels of relief at this size) cast some shadows at 30 degrees
        assert 0.005 < (V["Y"] < 0.5).mean() < 0.5
    assert (out / "index.html").is_file()


def test_second_run_reuses_the_bake(variant, bricks_sweep):
    _, first, second = bricks_sweep
    assert first["timings"]["bake_cached"] is False
    assert second["timings"]["bake_cached"] is True
    # same scene, same seed: the same numbers
    for a, b in zip(first["frames"], second["frames"]):
        for name in a["techniques"]:
            ta, tb = a["techniques"][name], b["techniques"][name]
            assert ta["visibility_mae"] == tb["visibility_mae"] and ta["rmse"] == tb["rmse"]


def test_summary_table_has_a_row_per_technique_under_100_columns(bricks_sweep):
    _, m, _ = bricks_sweep
    table = pipeline_records.summary_table(m).splitlines()
    names = list(m["techniques"])
    rows = table[2 : 2 + len(names) + 1]
    assert [r.split()[0] for r in rows] == [*names, "no"]  # then the no-shadows baseline
    assert max(len(line) for line in table) <= 100
    assert table[-2].startswith("|F-V|, leaks and false shadows: means over the frames")
    lead = [f["techniques"]["horizon"]["visibility_mae_facing"] for f in m["frames"]]
    assert rows[0].split()[1] == f"{sum(lead) / len(lead):.4f}"
    none = [f["no_shadows"]["visibility_mae_facing"] for f in m["frames"]]
    assert rows[-1].split()[5] == f"{sum(none) / len(none):.4f}"  # "no shadows (F = 1)" is 5 words


def test_flat_map_truth_and_approximation_agree_exactly(variant, tmp_path, any_map):
    """A flat plane is fully lit, and normal mapping a flat plane is exact: no error at all."""
    np.save(tmp_path / "flat.npy", np.full((32, 32), 0.5, np.float32))
    out = tmp_path / "out"
    assert (
        run("sweep", tmp_path / "flat.npy", "--azimuths", "-60,0,45", "--spp", 2, "--quiet", "--out", out)
        == 0
    )
    m = json.loads((out / "metrics.json").read_text())
    assert m["material"]["name"] == "flat" or m["material"].get("path", "").endswith("flat.npy")
    for f in m["frames"]:
        for name, te in f["techniques"].items():
            assert te["visibility_mae"] == 0 and te["leak_fraction"] == 0 and te["false_shadow_fraction"] == 0
            assert te["rmse"] == pytest.approx(0, abs=1e-6), name
            assert te["psnr_db"] is None or te["psnr_db"] > 100  # infinite PSNR is written as null
            assert te["flip_mean"] == pytest.approx(0, abs=1e-6), name


def test_wall_shadow_is_seen_by_both(variant, tmp_path):
    """A wall 8 texels high at 30 degrees shadows about 8 / tan(30) = 13.9 texels behind it;
    both the truth and the horizon factor see that shadow (the technique's error is elsewhere)."""
    h = np.zeros((32, 48), np.float32)
    h[:, 10] = 1.0
    np.save(tmp_path / "wall.npy", h)
    out = tmp_path / "out"
    # depth in image widths: 8 texels / 48 texels
    assert (
        run(
            "sweep",
            tmp_path / "wall.npy",
            "--depth",
            8 / 48,
            "--boundary",
            "open",
            "--azimuths",
            "180",
            "--effects",
            "shadow",
            "--spp",
            4,
            "--quiet",
            "--out",
            out,
        )
        == 0
    )
    m = json.loads((out / "metrics.json").read_text())
    (f,) = m["frames"]
    V = codecs.read_exr(out / f["files"]["visibility"])["Y"]
    F = codecs.read_exr(out / f["techniques"]["horizon"]["files"]["factor"])["Y"]
    length = 8 / math.tan(math.radians(30))
    # light from -x (azimuth 180): the shadow falls on +x of the wall, columns 11 .. 10 + length
    row = 16
    assert V[row, 11 : 10 + int(length)].max() < 0.5
    assert V[row, 10 + int(length) + 2 :].min() > 0.5
    assert V[row, :10].min() > 0.5
    assert F[row, 11:16].max() < 0.5  # the horizon map sees the wall right behind it


@pytest.mark.parametrize(
    "argv, needle",
    [
        (("sweep", "MISSING.png"), "MISSING.png"),
        (("sweep", "--size", "24", "--azimuths", "a:b"), "azimuths"),
        (("sweep", "--size", "24", "--depth", "-1"), "depth"),
        (("sweep", "--size", "24", "--k", "0"), "--k"),
        (("sweep", "--size", "24", "--effects", "glitter"), "effects"),
        (("sweep", "--size", "200000"), "GiB"),  # estimated before the map is generated
        (("sweep", "--size", "24", "--directions", "12"), "--directions"),
        (("sweep", "--size", "24", "--directions", "16", "--path", "gpu"), "--path"),
        (("sweep", "--size", "24", "--directions", "16", "--method", "exact"), "--directions"),
    ],
)
def test_bad_input_is_one_line_exit_2_and_no_output(argv, needle, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "out"
    assert run(*argv, "--quiet", "--out", out) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("hzval: error:") and needle in err and "\n" not in err
    assert not out.exists()


def test_negative_azimuth_ranges_parse_as_values(variant, tmp_path):
    """``--azimuths -30:30:30`` (a value that starts with '-') is taken as the option's value."""
    out = tmp_path / "out"
    assert (
        run(
            "sweep",
            "--size",
            24,
            "--azimuths",
            "-30:30:30",
            "--effects",
            "shadow",
            "--spp",
            1,
            "--quiet",
            "--out",
            out,
        )
        == 0
    )
    m = json.loads((out / "metrics.json").read_text())
    assert [f["azimuth_deg"] for f in m["frames"]] == [-30.0, 0.0, 30.0]


@pytest.mark.parametrize("name", DEFAULT_TECHNIQUES)
def test_every_technique_is_compared_on_the_same_sweep(variant, bricks_sweep, name):
    """Each technique of the registry: its metrics under frames[i]["techniques"][name], its images beside
    the others', the docs/ARCHITECTURE.md keys of a frame unchanged, and its columns in the report and the
    table."""
    from PIL import Image

    out, m, _ = bricks_sweep
    assert m["simulated"][name] == ["shadow", "diffuse"]
    stem = m["techniques"][name]["file_stem"]
    for f in m["frames"]:
        te = f["techniques"][name]
        for key in ("visibility_mae", "leak_fraction", "false_shadow_fraction", "flip_mean"):
            assert 0.0 <= te[key] <= 1.0, key
        assert math.isfinite(te["rmse"]) and math.isfinite(te["delta_e2000_mean"]) and te["seconds"] > 0
        assert {"png", "factor", "visdiff_png", "flip_png"} <= set(te["files"])
        assert not {"image", "factor_png"} & set(te["files"])  # --all-files only
        for rel in te["files"].values():
            assert (out / rel).is_file(), rel
        V = codecs.read_exr(out / f["files"]["visibility"])["Y"]
        TF = codecs.read_exr(out / te["files"]["factor"])["Y"]
        assert TF.shape == (48, 48) and np.isfinite(TF).all() and 0 <= TF.min() and TF.max() <= 1
        assert te["visibility_mae"] == pytest.approx(float(np.mean(np.abs(TF - V))), abs=2**-12)  # half files
        with Image.open(out / te["files"]["png"]) as img:
            assert img.size == (48, 48)
    html = (out / "index.html").read_text()
    assert f"{name} |F−V|" in html and f"{stem}_visdiff.png" in html and f"{stem}.png" in html
    assert m["techniques"][name]["label"] in html
    rows = pipeline_records.summary_table(m).splitlines()[2:]
    assert any(r.split()[:1] == [name] for r in rows)
    assert m["timings"][f"{stem}_s"] > 0


def test_no_key_or_file_is_named_approx(bricks_sweep):
    """Schema 2: no technique is special; nothing in metrics.json or under frames/ says "approx"."""
    out, m, _ = bricks_sweep

    def keys(x):
        if isinstance(x, dict):
            for k, v in x.items():
                yield k
                yield from keys(v)
        elif isinstance(x, list):
            for v in x:
                yield from keys(v)

    assert not [k for k in keys(m) if "approx" in k]
    assert not [p for p in (out / "frames").rglob("*") if "approx" in p.name]


def test_a_sweep_without_the_horizon_map_bakes_none_and_records_none(variant, tmp_path):
    """--techniques terrain: the bake holds the normal map alone, and no horizon setting is recorded."""
    out = tmp_path / "out"
    assert (
        run(
            "sweep",
            "--size",
            24,
            "--azimuths",
            "0",
            "--spp",
            1,
            "--techniques",
            "terrain",
            "--quiet",
            "--out",
            out,
        )
        == 0
    )
    m = json.loads((out / "metrics.json").read_text())
    assert sorted(p.name for p in (out / "bake").iterdir()) == ["bake.json", "normal.exr", "normal.png"]
    assert m["bake"]["contents"] == ["normal"] and list(m["techniques"]) == ["terrain"]
    text = json.dumps(
        {k: v for k, v in m.items() if k not in ("versions", "material")}
    )  # material.path: the file
    for setting in (
        '"k"',
        '"path"',
        '"ambient"',
        '"radius"',
        '"angles"',
        '"method"',
        '"directions"',
        "horizon",
    ):
        assert setting not in text, setting
    # a later sweep that needs the horizon map bakes it then, into the same cache
    assert run("sweep", "--size", 24, "--azimuths", "0", "--spp", 1, "--quiet", "--out", out) == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["timings"]["bake_cached"] is False and "horizon_map" in m["bake"]["contents"]
    assert (out / "bake" / "horizon0.exr").is_file()
    # and one that does not reuses it
    assert (
        run(
            "sweep",
            "--size",
            24,
            "--azimuths",
            "0",
            "--spp",
            1,
            "--techniques",
            "terrain",
            "--quiet",
            "--out",
            out,
        )
        == 0
    )
    assert json.loads((out / "metrics.json").read_text())["timings"]["bake_cached"] is True


def test_no_terrain_leaves_it_out(variant, tmp_path):
    out = tmp_path / "out"
    assert (
        run("sweep", "--size", 24, "--azimuths", "0", "--spp", 1, "--no-terrain", "--quiet", "--out", out)
        == 0
    )
    m = json.loads((out / "metrics.json").read_text())
    assert "terrain" not in m["frames"][0]["techniques"] and "terrain" not in m["simulated"]
    assert not (out / "frames" / "az+0" / "terrain.png").exists()
    assert "terrain |F-V|" not in pipeline_records.summary_table(m)


def test_techniques_selects_and_orders(variant, tmp_path):
    out = tmp_path / "out"
    assert (
        run(
            "sweep",
            "--size",
            24,
            "--azimuths",
            "0",
            "--spp",
            1,
            "--techniques",
            "terrain,horizon",
            "--terrain-ramp",
            0.5,
            "--quiet",
            "--out",
            out,
        )
        == 0
    )
    m = json.loads((out / "metrics.json").read_text())
    assert list(m["techniques"]) == ["horizon", "terrain"]  # registry order
    assert m["techniques"]["terrain"]["parameters"]["ramp_texels"] == 0.5
    assert set(m["frames"][0]["techniques"]) == {"horizon", "terrain"}


@pytest.mark.parametrize(
    "argv, needle",
    [
        (("--techniques", "nope"), "nope"),
        (("--techniques", "terrain", "--effects", "diffuse"), "shadow"),
        (("--terrain-ramp", "0"), "ramp"),
    ],
)
def test_bad_technique_choices_are_one_line_errors(argv, needle, tmp_path, capsys):
    out = tmp_path / "out"
    assert run("sweep", "--size", 24, "--azimuths", "0", "--spp", 1, *argv, "--quiet", "--out", out) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("hzval: error:") and needle in err and "\n" not in err
    assert not out.exists()


def test_reflection_occlusion_is_measured_when_declared(variant, tmp_path, bricks_sweep, any_map):
    """Flat: the fade and the truth's lobe both see the whole environment, |o - R| = 0;
    bricks: a number in [0, 1] and a report column; absent where undeclared."""
    np.save(tmp_path / "flat.npy", np.full((16, 16), 0.5, np.float32))
    for height, out in ((tmp_path / "flat.npy", tmp_path / "flat"), ("--size=24", tmp_path / "bricks")):
        assert (
            run(
                "sweep",
                height,
                "--azimuths",
                "0",
                "--spp",
                2,
                "--effects",
                "shadow,diffuse,reflection_occlusion",
                "--no-terrain",
                "--quiet",
                "--out",
                out,
            )
            == 0
        )
        m = json.loads((out / "metrics.json").read_text())
        assert (
            "reflection_occlusion" in m["simulated"]["truth"]
            and "reflection_occlusion" in m["simulated"]["horizon"]
        )
        r = m["frames"][0]["techniques"]["horizon"]["reflection_mae"]
        # flat: 0 (exactly on LLVM; on CUDA to float32 rounding: its division and square root are
        # approximate)
        zero = 1e-6 if variant.startswith("cuda") else 0.0
        assert r <= zero if out.name == "flat" else 0.0 < r < 1.0
        assert "|o−R|" in (out / "index.html").read_text(encoding="utf-8")
    _, first, _ = bricks_sweep
    assert all("reflection_mae" not in te for f in first["frames"] for te in f["techniques"].values())


def test_sixteen_directions_sweep_records_them(variant, tmp_path):
    out = tmp_path / "out"
    assert (
        run(
            "sweep",
            "--size",
            32,
            "--azimuths",
            "0,22.5",
            "--spp",
            2,
            "--directions",
            16,
            "--no-terrain",
            "--quiet",
            "--out",
            out,
        )
        == 0
    )
    m = json.loads((out / "metrics.json").read_text())
    assert m["techniques"]["horizon"]["parameters"]["directions"] == 16
    assert sorted(p.name for p in (out / "bake").glob("horizon*.exr")) == [
        f"horizon{i}.exr" for i in range(4)
    ]
    assert all(0 <= f["techniques"]["horizon"]["visibility_mae"] < 0.2 for f in m["frames"])


def test_a_truncated_bake_cache_is_rebaked_and_the_sweep_says_so(variant, tmp_path, capsys):
    """A sweep into a folder whose cached bake was cut short rebakes it, with one warning line, and
    exits 0 (it used to fail with exit 2 on every later run)."""
    from hzval.cli import main as cli

    argv = [
        "sweep",
        "--size",
        "24",
        "--azimuths",
        "0",
        "--spp",
        "4",
        "--techniques",
        "horizon",
        "--out",
        str(tmp_path),
        "--quiet",
    ]
    assert cli.main(argv) == 0
    victim = tmp_path / "bake" / "horizon1.exr"
    victim.write_bytes(victim.read_bytes()[:100])
    capsys.readouterr()
    assert cli.main(argv) == 0
    err = capsys.readouterr().err
    warnings = [line for line in err.splitlines() if "damaged" in line]
    assert len(warnings) == 1 and "horizon1.exr" in warnings[0] and warnings[0].startswith("hzval: warning:")


SMALL_SWEEP = [
    "sweep",
    "--size",
    "24",
    "--azimuths",
    "-30,0,30",
    "--spp",
    "4",
    "--techniques",
    "horizon",
    "--quiet",
]


def _tree(folder):
    """Every file under ``folder`` with its bytes (the lock file aside)."""
    return {
        p.relative_to(folder).as_posix(): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and p.name != ".hzval-lock"
    }


@pytest.mark.parametrize("stage", ["render", "_finish"])
def test_ctrl_c_leaves_the_folder_as_it_was(variant, tmp_path, capsys, monkeypatch, stage):
    """Interrupted at its second light, a sweep into a folder with an earlier report leaves every file of
    that report as it was, and nothing of its own but the (whole) bake cache; one line, exit 130.
    ``render``: the truth's; ``_finish``: while the light is compared and its files written."""
    from hzval.cli import main as cli
    from hzval.pipeline import renders
    from hzval.truth import plane as truth

    owner = truth.Truth if stage == "render" else renders

    out = tmp_path / "out"
    assert cli.main(SMALL_SWEEP + ["--out", str(out)]) == 0
    before = _tree(out)
    calls = {"n": 0}
    real = getattr(owner, stage)

    def interrupted(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 2:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(owner, stage, interrupted)
    capsys.readouterr()
    assert cli.main(SMALL_SWEEP + ["--elevation", "20", "--out", str(out)]) == 130
    assert capsys.readouterr().err.strip() == "hzval: interrupted"
    after = _tree(out)
    assert {k: v for k, v in after.items() if not k.startswith("bake/")} == {
        k: v for k, v in before.items() if not k.startswith("bake/")
    }
    assert not [p for p in out.iterdir() if p.name.startswith(".hzval-") and p.name != ".hzval-lock"]


def test_a_finished_sweep_replaces_the_old_report_whole(variant, tmp_path):
    from hzval.cli import main as cli

    out = tmp_path / "out"
    assert cli.main(SMALL_SWEEP + ["--azimuths", "-30,0,30,60", "--out", str(out)]) == 0
    assert (out / "frames" / "az+60").is_dir()
    assert cli.main(SMALL_SWEEP + ["--out", str(out)]) == 0
    assert not (out / "frames" / "az+60").exists()  # no frame of the old run survives
    assert sorted(p.name for p in (out / "frames").iterdir()) == ["az+0", "az+30", "az-30"]


def test_a_second_sweep_into_a_busy_folder_names_the_first(variant, tmp_path, capsys):
    from hzval.cli import main as cli

    out = tmp_path / "out"
    with staging.folder_lock(out, "hzval sweep (the first run)"):
        assert cli.main(SMALL_SWEEP + ["--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    # the holder's pid, not its command line (which may hold private paths: issue 33)
    assert (
        "\n" not in err
        and "in use by another hzval run" in err
        and "pid" in err
        and "the first run" not in err
    )
    assert not (out / "index.html").exists()
    assert cli.main(SMALL_SWEEP + ["--out", str(out)]) == 0  # free again once it is done


def test_a_sweep_that_would_not_fit_is_refused_before_it_allocates(variant, tmp_path, capsys, monkeypatch):
    """The estimate (hzval.truth.memory.estimate_peak_bytes) against the memory available: over it, one line
    naming the input and the estimate, exit 2, nothing written; under it, recorded beside the peak."""
    from hzval.cli import main as cli
    from hzval.scene import spec as sc

    scene = sc.override(sc.Scene(), size=1024)
    whole = memory.estimate_peak_bytes(scene, 1024, 1024)
    assert 2.0 * 2**30 < whole < 3.0 * 2**30  # measured: 2.35 GiB (benchmarks/README.md)
    # before the map is read, what is sure to be needed: the sweep without the truth's mesh, which
    # could be built in bands
    need = memory.estimate_peak_bytes(scene, 1024, 1024, 0, keeps=False)
    monkeypatch.setattr(resources, "available_bytes", lambda: need - 1)
    out = tmp_path / "o"
    assert cli.main(["sweep", "--size", "1024", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("hzval: error: --size:") and "GiB" in err and "estimated" in err and "\n" not in err
    assert not out.exists()
    monkeypatch.undo()
    # in a process of its own, as a user runs it: this one's memory holds every earlier test's
    import json
    import subprocess
    import sys

    subprocess.run(
        [sys.executable, "-m", "hzval", *SMALL_SWEEP, "--out", str(out)], check=True, capture_output=True
    )
    recorded = json.loads((out / "metrics.json").read_text())["memory"]
    assert 0.5 < recorded["estimate_bytes"] / recorded["peak_rss_bytes"] < 2.0


def test_ctrl_c_while_frames_are_written_leaves_no_staged_file(variant, tmp_path, monkeypatch):
    """Interrupted while its writer threads are busy, a sweep waits for them before it clears its
    staging folder: no file of the interrupted run is left behind. The Ctrl-C is raised where it
    lands, in the main thread's wait for the first writer (a real SIGINT reaches that wait only when
    the kernel hands it to the main thread)."""
    import concurrent.futures
    import threading
    import time as _time

    from hzval.cli import main as cli

    out = tmp_path / "out"
    real_png, real_result = pipeline_writing._write_png_of, concurrent.futures.Future.result
    fired = threading.Event()

    def slow_png(path, make, *args):
        _time.sleep(0.2)  # the writers are still at work ...
        real_png(path, make, *args)

    def result(self, timeout=None):
        if threading.current_thread() is threading.main_thread() and not fired.is_set():
            fired.set()
            raise KeyboardInterrupt  # ... when Ctrl-C reaches the main thread
        return real_result(self, timeout)

    monkeypatch.setattr(pipeline_writing, "_write_png_of", slow_png)
    monkeypatch.setattr(concurrent.futures.Future, "result", result)
    assert cli.main(SMALL_SWEEP + ["--out", str(out)]) == 130
    assert fired.is_set()
    _time.sleep(0.5)  # a straggler would have written by now
    assert [p for p in out.rglob("*") if p.is_file() and ".hzval-staging" in str(p)] == []


def _rss_bytes() -> int:
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) * 1024 for line in f if line.startswith("VmRSS:"))


def test_freed_memory_is_kept_while_retained_and_handed_back_after():
    """hzval.core.backend.retain_freed_memory: a freed 256 MB array stays with the process (its pages are
    the next allocation's); hand_back_freed_memory gives them back, and a later one is unmapped
    again as glibc does."""
    from hzval.core import backend

    if not backend.retain_freed_memory():
        pytest.skip("not glibc: nothing to retain")
    try:
        base = _rss_bytes()
        big = np.ones(256 * 2**20, np.uint8)
        del big
        assert _rss_bytes() > base + 200 * 2**20  # kept
    finally:
        backend.hand_back_freed_memory()
    assert _rss_bytes() < base + 64 * 2**20  # handed back
    after = _rss_bytes()
    big = np.ones(256 * 2**20, np.uint8)
    del big
    assert _rss_bytes() < after + 64 * 2**20  # glibc's own way again
    backend.hand_back_freed_memory()  # a second call does nothing


def test_a_sweep_that_fits_keeps_freed_memory_and_hands_it_back(variant, tmp_path, monkeypatch):
    """A sweep far below the memory available retains what it frees (metrics.json says so) and hands
    it back when it ends; one near the limit does not retain."""
    from hzval.core import backend

    calls = []
    real = backend.hand_back_freed_memory
    monkeypatch.setattr(backend, "hand_back_freed_memory", lambda: calls.append(backend._retaining) or real())
    out = tmp_path / "o"
    assert run("sweep", "--size", 24, "--azimuths", 0, "--spp", 2, "--quiet", "--out", out) == 0
    retains = json.loads((out / "metrics.json").read_text())["memory"]["retains_freed"]
    assert retains is (backend._mallopt() is not None) and calls == [retains] and not backend._retaining
    monkeypatch.setattr(
        resources,
        "available_bytes",
        lambda: int(
            1.5 * memory.estimate_peak_bytes(sweep.sc.override(sweep.sc.Scene(), size=24, spp=2), 24, 24)
        ),
    )
    assert run("sweep", "--size", 24, "--azimuths", 0, "--spp", 2, "--quiet", "--out", tmp_path / "p") == 0
    assert json.loads((tmp_path / "p" / "metrics.json").read_text())["memory"]["retains_freed"] is False
