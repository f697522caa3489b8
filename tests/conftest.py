import os
import subprocess
from pathlib import Path

import pytest

# Tests must not pick a GPU by accident, nor depend on the caller's choice.
os.environ.setdefault("HZVAL_VARIANT", "llvm_ad_rgb")

# Dr.Jit reads DRJIT_LIBLLVM_PATH when it is first imported, which the test modules do: point it at a
# working LLVM first, as hzval.cli.main.main does (hzval.init)
from hzval.core import backend as _backend  # noqa: E402

_backend.prefer_working_llvm()

from tests.helpers import GCC, SOURCE  # noqa: E402 - after the LLVM is chosen


@pytest.fixture(scope="session")
def variant():
    """Select hzval's Mitsuba variant once for the whole session."""
    from hzval.core import backend

    return backend.variant()


@pytest.fixture
def any_map(monkeypatch):
    """Lift the command line's input rule (hzval.io.heightmap.check_usable: at least 8 x 8 texels,
    some height variation) for the tests that sweep a flat or a 1 x N map on purpose: the analytic
    cases (a flat map has no shadow and no error) and the pipeline's own robustness."""
    from hzval.io import heightmap

    monkeypatch.setattr(heightmap, "check_usable", lambda hm: hm)


@pytest.fixture(scope="session")
def seed_peer(tmp_path_factory) -> Path:
    """The seed peer, compiled once per session (no -march=native: portable rounding)."""
    exe = tmp_path_factory.mktemp("seed_peer") / "seed_bake"
    cmd = [GCC, "-O2", "-fopenmp", "-o", str(exe), str(SOURCE), "-lm"]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    assert proc.returncode == 0, f"{' '.join(cmd)} failed:\n{proc.stderr}"
    return exe


@pytest.fixture(scope="session")
def seed_peer_hoisted(tmp_path_factory) -> Path:
    """The seed peer's -DHOISTED_TABLE variant (offset table computed once), compiled once."""
    exe = tmp_path_factory.mktemp("seed_peer_hoisted") / "seed_bake_hoisted"
    cmd = [GCC, "-O2", "-fopenmp", "-DHOISTED_TABLE", "-o", str(exe), str(SOURCE), "-lm"]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    assert proc.returncode == 0, f"{' '.join(cmd)} failed:\n{proc.stderr}"
    return exe
