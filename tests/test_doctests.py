"""The examples in hzval's docstrings run and give what they say: every module with a ``>>>`` example
is a test case (the formula modules carry them: conventions, shading, the metrics, the techniques)."""

from __future__ import annotations

import doctest
import importlib
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "hzval"
MODULES = sorted(
    ".".join(p.relative_to(PACKAGE.parent).with_suffix("").parts)
    for p in PACKAGE.rglob("*.py")
    if ">>> " in p.read_text()
)


def test_the_formula_modules_have_examples():
    for name in ("hzval.core.conventions",):
        assert name in MODULES


@pytest.mark.parametrize("name", MODULES)
def test_examples(name):
    module = importlib.import_module(name)
    result = doctest.testmod(
        module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE, verbose=False
    )
    assert result.attempted > 0, f"{name}: no example ran"
    assert result.failed == 0, (
        f"{name}: {result.failed} of {result.attempted} examples failed "
        "(pytest --doctest-modules on the module's file shows them)"
    )
