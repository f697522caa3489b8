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


def _defined_in(path: Path) -> set[str]:
    """The names ``path`` defines at its top level: not those it imports or aliases (``X = m.X``)."""
    names: set[str] = set()
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)) and not isinstance(
            node.value, (ast.Name, ast.Attribute)
        ):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names.update(t.id for t in targets if isinstance(t, ast.Name))
    return names


def owners(package: Path) -> dict[str, str | None]:
    """Return each public name of ``package``'s modules and the module it is re-exported from.

    A name several modules export is the one module's that defines it (the others import it from
    there); a name that more than one module defines (each command's ``run``) is ``None``: it is not
    re-exported, since the package could not say whose it is. A module's own name is never a name's.
    """
    modules = sorted(p.stem for p in package.glob("*.py") if p.stem != "__init__")
    taken = set(modules) | {p.parent.name for p in package.glob("*/__init__.py")}
    exporters: dict[str, list[str]] = {}
    for m in modules:
        for n in _all_of(package / f"{m}.py"):
            if n not in taken:
                exporters.setdefault(n, []).append(m)
    out: dict[str, str | None] = {}
    for n, ms in exporters.items():
        defining = [m for m in ms if n in _defined_in(package / f"{m}.py")]
        out[n] = ms[0] if len(ms) == 1 else (defining[0] if len(defining) == 1 else None)
    return out


def packages() -> list[Path]:
    """Every subpackage of hzval whose ``__init__`` re-exports through a stub."""
    return sorted(
        p.parent
        for p in PACKAGE.rglob("__init__.py")
        if p.parent != PACKAGE and "attach_stub" in p.read_text(encoding="utf-8")
    )


def stub(package: Path) -> str:
    """Return ``package``'s ``__init__.pyi``: its modules and subpackages, then each module's public
    names that :func:`owners` gives it.
    """
    modules = sorted(p.stem for p in package.glob("*.py") if p.stem != "__init__")
    subpackages = sorted(p.parent.name for p in package.glob("*/__init__.py"))
    lines = [HEAD, "from . import " + ", ".join(modules + subpackages) + "\n"]
    owner = owners(package)
    for m in modules:
        names = [n for n in _all_of(package / f"{m}.py") if owner.get(n) == m]
        if names:
            body = "".join(f"    {n} as {n},\n" for n in names)
            lines.append(f"from .{m} import (\n{body})\n")
    return "".join(lines)


def main() -> None:
    for package in packages():
        (package / "__init__.pyi").write_text(stub(package), encoding="utf-8")


if __name__ == "__main__":
    main()
