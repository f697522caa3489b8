"""A new user's trial of hzval (issue 55): one |F - V|, gates checked before the run, what fit writes
passes --strict, a flat map is a null test, and the smaller items. One test (or a few) per item."""

from __future__ import annotations

from pathlib import Path

import pytest

from hzval.cli import main as cli
from tests.integration.test_faults import one_line

ROOT = Path(__file__).resolve().parents[2]


# 3. a map written by fit passes --strict --------------------------------------------------------------


@pytest.mark.parametrize("material", ["gravel", "cobblestones"])
def test_a_fitted_map_passes_strict(tmp_path, capsys, variant, material):
    """Fitted to render well, the map lies closer to the exact sines read as tangents, yet shadows
    worse so read: no convention is suggested (it was, and --strict failed: exit 1)."""
    fit = tmp_path / "fit"
    assert cli.main(["fit", "--material", material, "--size", "128", "--out", str(fit)]) == 0
    layers = f"{fit / 'horizon0.exr'},{fit / 'horizon1.exr'}"
    argv = ["sweep", "--material", material, "--size", "128", "--techniques", "horizon", "--spp", "2"]
    argv += ["--horizon-map", layers, "--strict", "--quiet", "--out", str(tmp_path / "s")]
    capsys.readouterr()
    assert cli.main(argv) == 0
    assert "horizon map:" not in capsys.readouterr().err
