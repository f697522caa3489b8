"""Every script under benchmarks/ and studies/ (and the oracles' command lines) answers ``--help``, and
runs at a smoke size (most of them slow: each one is a whole measurement, made small).

The scripts run as a user runs them, ``python benchmarks/NAME.py ...`` from a folder of their own, in a
process of their own; hzval is found through ``PYTHONPATH`` as the suite's own process finds it.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPTS = sorted(
    [
        *(ROOT / "benchmarks").glob("*.py"),
        *(ROOT / "studies").glob("*.py"),
        ROOT / "tests/oracles/march_check.py",
    ]
)
NAMES = [str(p.relative_to(ROOT)) for p in SCRIPTS]


def _env() -> dict:
    path = os.pathsep.join([str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])
    return {**os.environ, "PYTHONPATH": path, "HZVAL_VARIANT": os.environ.get("HZVAL_VARIANT", "llvm_ad_rgb")}


def test_every_script_is_listed():
    """The index below and the READMEs cover every script: a new one needs its smoke run and its line."""
    assert set(NAMES) == set(SMOKE) | set(NO_SMOKE), set(NAMES) ^ (set(SMOKE) | set(NO_SMOKE))
    for folder in ("benchmarks", "studies"):
        readme = (ROOT / folder / "README.md").read_text()
        missing = [n for n in NAMES if n.startswith(folder + "/") and Path(n).name not in readme]
        assert not missing, f"{folder}/README.md does not index {missing}"


@pytest.fixture(scope="module")
def helps(tmp_path_factory):
    """``--help`` of every script, started all at once (each is a Python start-up and an import)."""
    cwd = tmp_path_factory.mktemp("help")
    procs = {
        name: subprocess.Popen(
            [sys.executable, str(ROOT / name), "--help"],
            cwd=cwd,
            env=_env(),
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for name in NAMES
    }
    out = {}
    for name, p in procs.items():
        try:
            stdout, stderr = p.communicate(timeout=120)
        except subprocess.TimeoutExpired:
            p.kill()
            stdout, stderr = p.communicate()
        out[name] = (p.returncode, stdout, stderr)
    return out


@pytest.mark.parametrize("name", NAMES)
def test_help(helps, name):
    """Exit 0, a usage line naming the script, what it does, and no side effect (no file in its cwd)."""
    rc, stdout, stderr = helps[name]
    assert rc == 0, stderr
    assert stdout.startswith("usage: ") and Path(name).stem in stdout.splitlines()[0], stdout
    assert len(stdout.splitlines()) > 2, stdout


#: Smoke-size arguments per script; ``{tmp}`` is a fresh folder holding ``h.png``, a 48 x 48 16-bit
#: photo-like height map. Scripts that need an input made by another command (a report, a models folder,
#: a baseline commit, a mesh file), a C compiler, OpenGL or a cluster are in NO_SMOKE with the reason;
#: their --help still runs.
SMOKE = {
    "benchmarks/bench_bake_radius.py": ["--size", "64", "--radii", "4", "--repeat", "1"],
    "benchmarks/bench_compare.py": ["--sizes", "64", "--tests", "1", "--repeat", "1"],
    "benchmarks/bench_fit.py": ["--size", "32", "--spp", "1", "--train-spp", "1"],
    "benchmarks/bench_fit_textures.py": ["--size", "24", "--spp", "1", "--techniques", "microshadow-hdrp"],
    "benchmarks/bench_horizon.py": ["--size", "64", "--spp", "1", "--paths", "exact", "--frames", "2"],
    "benchmarks/bench_horizon_methods.py": ["--sizes", "64", "--repeat", "1"],
    "benchmarks/bench_meshes.py": ["--size", "64"],
    "benchmarks/bench_ktx2.py": ["--size", "32", "--materials", "gravel"],
    "benchmarks/bench_mesh_memory.py": ["--cases", "32:0.05:0,32:0.2:auto"],
    "benchmarks/bench_models.py": ["--size", "64", "--triangles", "200", "--resolution", "64", "--spp", "1"],
    "benchmarks/bench_pom.py": [
        "--size",
        "64",
        "--frames",
        "2",
        "--spp",
        "1",
        "--truth-spp",
        "1",
        "--steps",
        "8",
    ],
    "benchmarks/bench_terrain.py": ["--size", "64", "--frames", "2", "--spp", "1"],
    "benchmarks/bench_engines.py": ["--repeat", "1", "--size", "32", "--spp", "1", "--azimuths", "0"],
    "benchmarks/bench_truth.py": ["--size", "64", "--spp", "1", "--frames", "2"],
    "benchmarks/memory_timeline.py": [
        "--",
        "--size",
        "64",
        "--spp",
        "1",
        "--azimuths=0",
        "--out",
        "{tmp}/sweep",
    ],
    "studies/curved_horizon.py": ["--size", "64", "--cases", "cap+1,flat"],
    "studies/external_bound.py": ["--size", "32"],
    "studies/figures.py": ["--check"],
    "studies/model_quads.py": ["--photo", "{tmp}/h.png", "--size", "32", "--spp", "1"],
    "studies/orientation_check.py": [
        *(
            "--out",
            "{tmp}/o",
            "--spp",
            "1",
            "--march-spp",
            "1",
            "--photos",
            "{tmp}/h.png",
            "--boundaries",
            "open",
        )
    ],
    "studies/study_fit.py": [
        *(
            "--size",
            "32",
            "--materials",
            "bricks",
            "--more",
            "bricks",
            "--more-variants",
            "u8",
            "--out",
            "{tmp}/s.json",
        )
    ],
    "studies/tangent_bugs.py": ["bricks", "--size", "32", "--spp", "1", "--resolution", "32"],
    "studies/truth_convergence.py": [
        "--out",
        "{tmp}/t",
        "--tolerances",
        "0.08,0.04",
        "--materials",
        "{tmp}/h.png",
    ],
    "studies/turned_techniques.py": ["--spp", "1"],
    "benchmarks/bench_mikktspace.py": ["--segments", "16", "--size", "32", "--repeat", "1"],
    "benchmarks/bench_flip.py": ["--baseline", str(ROOT), "--sizes", "40", "--repeat", "1"],
    "benchmarks/bench_png.py": ["--size", "16", "--frames", "1", "--repeat", "1"],
}
NO_SMOKE = {
    "benchmarks/bench_bake.py": "compiles the C seed peer (tests/bake/test_horizon_peer.py does, marker gcc)",
    "benchmarks/compare_runs.py": "runs five commands with each of two versions (minutes); its compare "
    "step is tested on two small sweeps below (test_compare_runs_finds_a_changed_score)",
    "benchmarks/bench_production.py": "sweeps two commits' trees side by side (a baseline checkout)",
    "benchmarks/bench_report.py": "needs Debian's chromium and a report (tests/report/test_pages.py)",
    "benchmarks/bench_suite_engines.py": "starts Dask (and Ray) clusters",
    "studies/frames_fit.py": "needs a photo and fits it for minutes",
    "studies/gl_agreement.py": "needs OpenGL (tests/techniques/gl/test_horizon_gl.py covers the comparison)",
    "studies/model_check.py": "needs a mesh file and a height map of a scanned model",
    "studies/models_tables.py": "needs the folders of `hzval models` runs",
    "tests/oracles/march_check.py": "needs a sweep's folder (tests/commands/test_views.py runs it on one)",
}


#: The smoke runs that take a second or two: the default run keeps them, so that a renamed API breaks a
#: test at once; the others are slow.
FAST = {
    "benchmarks/bench_flip.py",
    "benchmarks/bench_ktx2.py",
    "benchmarks/bench_horizon.py",
    "benchmarks/bench_horizon_methods.py",
    "benchmarks/bench_pom.py",
    "benchmarks/bench_terrain.py",
    "benchmarks/bench_truth.py",
    "studies/figures.py",
}
_SLOW = pytest.mark.slow(reason="a whole measurement at a smoke size: several seconds to half a minute")


@pytest.mark.parametrize("name", [n if n in FAST else pytest.param(n, marks=_SLOW) for n in sorted(SMOKE)])
def test_smoke(name, tmp_path):
    """A small run ends with exit 0 and prints something: the script still works against the package."""
    from PIL import Image

    from hzval import materials

    h = materials.generate("bricks", 64, seed=5).height[8:56, 8:56]
    Image.fromarray(((h - h.min()) / (h.max() - h.min()) * 65535).astype(np.uint16)).save(tmp_path / "h.png")
    args = [a.replace("{tmp}", str(tmp_path)) for a in SMOKE[name]]
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    done = subprocess.run(
        [sys.executable, str(ROOT / name), *args],
        cwd=cwd,
        env=_env(),
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert done.stdout.strip(), done.stderr[-3000:]
    shutil.rmtree(cwd)


def test_tests_import_nothing_from_the_scripts():
    """The tests' references live in tests/oracles/: no test imports a module of benchmarks/ or studies/,
    by name or by path (only this file runs them, as programs)."""
    import ast

    found = []
    for path in (ROOT / "tests").rglob("*.py"):
        # this file runs the scripts; test_structure names hzval's own subpackage hzval.studies
        if path in (Path(__file__).resolve(), ROOT / "tests" / "test_structure.py"):
            continue
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            elif isinstance(node, ast.Constant) and isinstance(node.value, str):
                if node.value in ("benchmarks", "studies") or node.value.startswith(
                    ("benchmarks/", "studies/")
                ):
                    if not node.value.endswith(".md"):
                        names = [node.value]
            found += [
                f"{path.relative_to(ROOT)}: {n}"
                for n in names
                if n.replace("/", ".").split(".")[0] in ("benchmarks", "studies")
            ]
    assert not found, found


def test_compare_runs_finds_a_changed_score(tmp_path):
    """benchmarks/compare_runs.py's compare: two runs of the same sweep are the same, bit for bit; a
    score changed in one, or an image's pixel, is found and named."""
    import json

    from hzval.cli import main as cli
    from hzval.io import codecs

    argv = ["sweep", "--size", "16", "--azimuths", "0", "--spp", "1", "--techniques", "horizon", "--quiet"]
    for run in ("a", "b"):
        assert cli.main([*argv, "--out", str(tmp_path / run / "sweep")]) == 0
    script = [sys.executable, str(ROOT / "benchmarks/compare_runs.py"), "compare"]
    same = subprocess.run([*script, str(tmp_path / "a"), str(tmp_path / "b")], capture_output=True, text=True)
    assert same.returncode == 0, same.stdout + same.stderr
    metrics = tmp_path / "b" / "sweep" / "metrics.json"
    data = json.loads(metrics.read_text())
    data["frames"][0]["techniques"]["horizon"]["flip_mean"] += 1e-9
    metrics.write_text(json.dumps(data))
    truth = tmp_path / "b" / "sweep" / "frames" / "az+0" / "truth.exr"
    layers = codecs.read_exr(truth)
    layers["Y"][0, 0] += 0.5
    codecs.write_exr(truth, layers)
    changed = subprocess.run(
        [*script, str(tmp_path / "a"), str(tmp_path / "b")], capture_output=True, text=True
    )
    assert changed.returncode == 1
    assert "flip_mean" in changed.stdout and "truth.exr Y: 1 pixels differ" in changed.stdout
