"""docs/ci.md's CI recipe, run as written: its `run:` steps pass on hzval's own techniques, and its
gated step fails (exit 1) when the horizon map regresses (--horizon-k 2)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
RECIPE = ROOT / "docs" / "ci.md"


def recipe_steps() -> list[dict]:
    """The steps of the recipe's one job (the first ```yaml block of docs/ci.md)."""
    block = re.search(r"```yaml\n(.*?)```", RECIPE.read_text(encoding="utf-8"), re.S).group(1)
    jobs = yaml.safe_load(block)["jobs"]
    (job,) = jobs.values()
    return job["steps"]


def test_the_recipe_is_a_github_actions_workflow():
    steps = recipe_steps()
    assert any("actions/checkout" in s.get("uses", "") for s in steps)
    runs = [s["run"] for s in steps if "run" in s]
    assert any("--fail-if" in r and "--baseline" in r for r in runs)
    assert any(s.get("if") == "failure()" and "upload-artifact" in s.get("uses", "") for s in steps)


def _shell(script: str, cwd: Path, bin_dir: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PATH": f"{bin_dir}{os.pathsep}{os.environ['PATH']}", "PYTHONPATH": str(ROOT)}
    return subprocess.run(
        ["bash", "-e", "-c", script], cwd=cwd, env=env, capture_output=True, text=True, timeout=600
    )


@pytest.mark.slow
def test_the_recipe_runs(tmp_path, variant):
    """Each `run:` step but the install (hzval is on PATH here) and the ones for main only, in order,
    in a fresh checkout folder: all pass; then the gated step with a softer horizon map fails."""
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    shim = bin_dir / "hzval"
    shim.write_text(f'#!/bin/sh\nexec {sys.executable} -m hzval "$@"\n')
    shim.chmod(0o755)
    work = tmp_path / "repo"
    work.mkdir()
    gated = None
    for step in recipe_steps():
        script = step.get("run")
        if (
            script is None
            or script.strip().startswith("pip install")
            or "github.ref" in str(step.get("if", ""))
        ):
            continue
        done = _shell(script, work, bin_dir)
        assert done.returncode == 0, (step.get("name"), done.stderr[-2000:])
        if "--fail-if" in script:
            gated = script
    assert (work / "baseline" / "bricks" / "metrics.json").is_file() and (
        work / "reports" / "bricks" / "index.html"
    ).is_file()
    worse = _shell(gated.strip() + " --horizon-k 2 --out reports/soft", work, bin_dir)
    assert worse.returncode == 1, worse.stderr[-2000:]
    assert "gate failed: --baseline: horizon." in worse.stderr
