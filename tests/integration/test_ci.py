"""docs/ci.md's CI recipe, run as written: its install step installs hzval into a new virtualenv, its
`run:` steps pass on hzval's own techniques, and its gated step fails (exit 1) when the horizon map
regresses (--horizon-k 2)."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

from tests.helpers import ROOT, recipe_steps


def test_the_recipe_is_a_github_actions_workflow():
    steps = recipe_steps()
    assert any("actions/checkout" in s.get("uses", "") for s in steps)
    runs = [s["run"] for s in steps if "run" in s]
    assert any("--fail-if" in r and "--baseline" in r for r in runs)
    assert any(s.get("if") == "failure()" and "upload-artifact" in s.get("uses", "") for s in steps)


def _shell(script: str, cwd: Path, path: list, github_path: Path) -> subprocess.CompletedProcess:
    """A step's script as a runner runs it: ``path`` (what earlier steps added to ``$GITHUB_PATH``)
    first on PATH, none of this process's virtualenv or PYTHONPATH."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    system = [p for p in os.environ["PATH"].split(os.pathsep) if ".venv" not in p]
    env.update(PATH=os.pathsep.join([*map(str, path), *system]), GITHUB_PATH=str(github_path))
    return subprocess.run(
        ["bash", "-e", "-c", script], cwd=cwd, env=env, capture_output=True, text=True, timeout=900
    )


@pytest.mark.slow(reason="installs hzval into a new virtualenv and sweeps twice: minutes")
def test_the_recipe_runs(tmp_path, variant):
    """Each `run:` step but the ones for main only, in order, in a fresh folder: the install step as
    written, on a clean clone of this repository where the recipe checks hzval out (a new virtualenv,
    its `bin/` on PATH through `$GITHUB_PATH`), then the sweeps with that hzval: all pass; then the
    gated step with a softer horizon map fails."""
    work = tmp_path / "repo"
    work.mkdir()
    subprocess.run(["git", "clone", "-q", "--depth", "1", f"file://{ROOT}", str(work / "hzval")], check=True)
    github_path = tmp_path / "github_path"
    github_path.write_text("")
    gated = None
    for step in recipe_steps():
        script = step.get("run")
        if script is None or "github.ref" in str(step.get("if", "")):
            continue
        extra = [p for p in github_path.read_text().splitlines() if p]
        done = _shell(script, work, extra, github_path)
        assert done.returncode == 0, (step.get("name"), done.stdout[-1000:], done.stderr[-2000:])
        if "--fail-if" in script:
            gated = script
    installed = [p for p in github_path.read_text().splitlines() if p]
    assert installed == [str(work / "hzval" / ".venv" / "bin")]
    assert (work / "baseline" / "bricks" / "metrics.json").is_file() and (
        work / "reports" / "bricks" / "index.html"
    ).is_file()
    worse = _shell(gated.strip() + " --horizon-k 2 --out reports/soft", work, installed, github_path)
    assert worse.returncode == 1, worse.stderr[-2000:]
    assert "gate failed: --baseline: horizon." in worse.stderr
