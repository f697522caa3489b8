"""Each subpackage re-exports its modules' public names on first use (lazy_loader, from its
``__init__.pyi``), and a submodule asked of its package is imported alone."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from hzval import geometry, truth
from tests import stubs

PACKAGE = Path(__file__).resolve().parents[1] / "hzval"


def test_a_public_name_is_found_in_its_module():
    from hzval.truth.plane import Truth

    assert truth.Truth is Truth
    with pytest.raises(AttributeError):
        geometry.no_such_name  # noqa: B018


def test_a_name_two_modules_define_is_not_re_exported():
    """Two modules' ``VARIANTS`` are different tuples: the package names neither rather than the
    first alphabetically; a name one module defines and another aliases is the defining module's."""
    from hzval import techniques
    from hzval.techniques import pom
    from hzval.techniques.fitted import fit, model

    owner = stubs.owners(PACKAGE / "techniques")
    assert owner["VARIANTS"] is None and not hasattr(techniques, "VARIANTS")
    assert pom.VARIANTS != techniques.bent_cone.VARIANTS
    assert stubs.owners(PACKAGE / "techniques" / "fitted")["HALVINGS"] == "model"
    assert techniques.fitted.HALVINGS is model.HALVINGS is fit.HALVINGS


def test_every_stub_is_current():
    """Each ``__init__.pyi`` is what tests/stubs.py writes from the modules' ``__all__`` now."""
    stale = [
        str(p.relative_to(PACKAGE))
        for p in stubs.packages()
        if (p / "__init__.pyi").read_text() != stubs.stub(p)
    ]
    assert stale == [], "run python -m tests.stubs"


def test_a_submodule_is_imported_alone():
    """``from hzval.geometry import mikktspace`` (a module the package does not list) imports that
    module, not every module the package re-exports from: those import it in turn (a cycle)."""
    probe = (
        "import sys; from hzval.geometry import mikktspace; "
        "print(sorted(m for m in sys.modules if m.startswith('hzval.geometry.')))"
    )
    run = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert run.stdout.strip() == "['hzval.geometry.mikktspace']"


@pytest.mark.slow(reason="a fresh interpreter for each of hzval's modules: about 25 s")
@pytest.mark.parametrize(
    "package", sorted(p.name for p in PACKAGE.iterdir() if (p / "__init__.py").is_file())
)
def test_every_module_imports_first_through_its_package(package):
    """Each module of ``package``, the first of hzval's to be imported in a fresh interpreter, through
    ``from hzval.PACKAGE import MODULE``: no import order meets a module half initialised."""
    for name in sorted(p.stem for p in (PACKAGE / package).glob("*.py") if p.stem != "__init__"):
        code = f"from hzval.{package} import {name}"
        run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
        assert run.returncode == 0, f"{code}: {run.stderr[-800:]}"
