"""ruff keeps lint and format (pyproject.toml's [tool.ruff]): the whole tree passes both."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
RUFF = shutil.which("ruff", path=str(Path(sys.executable).parent)) or shutil.which("ruff")


@pytest.mark.skipif(RUFF is None, reason="ruff is not installed (setup.sh --test installs it)")
@pytest.mark.parametrize(
    "args", [["check", "--no-cache", "--output-format", "concise"], ["format", "--check"]]
)
def test_ruff_passes(args):
    run = subprocess.run([RUFF, *args, "."], cwd=ROOT, capture_output=True, text=True)
    assert run.returncode == 0, run.stdout[-4000:] + run.stderr[-2000:]
