"""Each subpackage's ``__init__.pyi``: what its ``__init__`` re-exports, lazily (lazy_loader), from
its modules' ``__all__``. ``python -m tests.stubs`` writes them; tests/test_structure.py checks that
they are current.
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "hzval"
HEAD = "# Written by tests/stubs.py from each module's __all__ (python -m tests.stubs); do not edit.\n"


def _all_of(path: Path) -> list[str]:
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "__all__" for t in node.targets):
            return [e.value for e in node.value.elts if isinstance(e, ast.Constant)]
    return []


def packages() -> list[Path]:
    """Every subpackage of hzval whose ``__init__`` re-exports through a stub."""
    return sorted(
        p.parent
        for p in PACKAGE.rglob("__init__.py")
        if p.parent != PACKAGE and "attach_stub" in p.read_text(encoding="utf-8")
    )


def stub(package: Path) -> str:
    """``package``'s ``__init__.pyi``: its modules and subpackages, then each public name of each
    module, the first module that names it winning, a name a module has taken left to the module."""
    modules = sorted(p.stem for p in package.glob("*.py") if p.stem != "__init__")
    subpackages = sorted(p.parent.name for p in package.glob("*/__init__.py"))
    lines = [HEAD, "from . import " + ", ".join(modules + subpackages) + "\n"]
    taken: set[str] = set(modules + subpackages)  # a module's name is the module's, not a function's
    for m in modules:
        names = [n for n in _all_of(package / f"{m}.py") if n not in taken]
        taken.update(names)
        if names:
            body = "".join(f"    {n} as {n},\n" for n in names)
            lines.append(f"from .{m} import (\n{body})\n")
    return "".join(lines)


def main() -> None:
    for package in packages():
        (package / "__init__.pyi").write_text(stub(package), encoding="utf-8")


if __name__ == "__main__":
    main()
