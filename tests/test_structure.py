"""The package's shape: no import cycle (imports inside functions counted), and no module but a
technique's own and the registry names a particular technique."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "hzval"


def _module_name(path: Path) -> str:
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def import_graph() -> dict[str, set[str]]:
    """Every hzval module's hzval imports, wherever they stand in the file (module top or inside a
    function), resolved to modules: ``from hzval import x`` is ``hzval.x`` when that is a module."""
    modules = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        deps: set[str] = set()
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    base = ".".join(
                        package.split(".")[: len(package.split(".")) - node.level + 1] + [base]
                    ).strip(".")
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base for a in node.names]
            else:
                continue
            deps |= {t for t in targets if t in modules and t != name}
        # a package's __init__ is imported with any of its modules, but that is Python's doing, not a cycle
        graph[name] = {d for d in deps if not name.startswith(d + ".")}
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """A cycle of ``graph`` as a list of modules (first == last), or ``None``."""
    colour: dict[str, int] = {}
    stack: list[str] = []

    def visit(n: str):
        colour[n] = 1
        stack.append(n)
        for d in sorted(graph.get(n, ())):
            if colour.get(d) == 1:
                return stack[stack.index(d) :] + [d]
            if d not in colour and (found := visit(d)):
                return found
        stack.pop()
        colour[n] = 2
        return None

    for n in sorted(graph):
        if n not in colour and (found := visit(n)):
            return found
    return None


def test_the_checker_finds_a_cycle():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": set()}) is None


def test_no_import_cycle():
    cycle = find_cycle(import_graph())
    assert cycle is None, " -> ".join(cycle)


def test_the_graph_sees_imports_inside_functions():
    # hzval.cli.sweep imports its command inside its run function: the graph sees that edge too
    assert "hzval.commands.sweep" in import_graph()["hzval.cli.sweep"]


def _string_constants(path: Path) -> set[str]:
    """The module's whole string literals (the pieces of an f-string, ``f"horizon{i}.exr"``, are not)."""
    tree = ast.parse(path.read_text(), str(path))
    pieces = {id(v) for n in ast.walk(tree) if isinstance(n, ast.JoinedStr) for v in n.values}
    return {
        n.value
        for n in ast.walk(tree)
        if isinstance(n, ast.Constant) and isinstance(n.value, str) and id(n) not in pieces
    }


def test_no_module_but_a_techniques_own_names_it():
    """The registry is the one place that names the techniques: no other module of the package, and
    no template, holds a technique's name as a string (docstrings aside: they may cite one)."""
    from hzval.techniques import registry as technique

    own = {f"{technique.REGISTRY[n].split(':')[0].replace('.', '/')}.py" for n in technique.names()}
    names = set(technique.names())
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE.parent).as_posix()
        # A package's __init__ lists its modules by name, and a module may share a technique's name.
        if rel in own or rel == "hzval/techniques/registry.py" or path.name == "__init__.py":
            continue
        docstrings = {
            ast.get_docstring(n, clean=False)
            for n in ast.walk(ast.parse(path.read_text()))
            if isinstance(n, (ast.Module, ast.ClassDef, ast.FunctionDef))
        }
        named = (_string_constants(path) - docstrings) & names
        assert not named, f"{rel} names {sorted(named)}"
    for path in sorted((PACKAGE / "report" / "templates").iterdir()):
        text = path.read_text()
        assert not [n for n in names if f"'{n}'" in text or f'"{n}"' in text], path


def test_version_is_the_installed_packages(capsys):
    """``hzval --version`` prints the version of pyproject.toml, read from the installed metadata."""
    import tomllib

    from hzval.cli import main as cli

    want = tomllib.loads((PACKAGE.parent / "pyproject.toml").read_text())["project"]["version"]
    with pytest.raises(SystemExit) as exc:
        cli.main(["--version"])
    assert exc.value.code == 0 and capsys.readouterr().out.strip() == f"hzval {want}"


def test_importing_hzval_changes_no_environment():
    """``import hzval`` leaves DRJIT_LIBLLVM_PATH alone: the LLVM is chosen by hzval.init or the CLI."""
    import subprocess
    import sys

    code = "import os; before = dict(os.environ); import hzval; print(before == dict(os.environ))"
    env = {k: v for k, v in __import__("os").environ.items() if k != "DRJIT_LIBLLVM_PATH"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    assert out.stdout.strip() == "True"


def test_the_package_map_names_every_module():
    """``hzval/__init__``'s docstring is the map a newcomer reads (README, "Layout"): a new module
    is listed there."""
    doc = ast.get_docstring(ast.parse((PACKAGE / "__init__.py").read_text()))
    missing = [
        p.stem
        for p in PACKAGE.glob("*.py")
        if p.stem not in ("__init__", "__main__") and f"``{p.stem}``" not in doc
    ]
    missing += [
        p.name for p in PACKAGE.iterdir() if (p / "__init__.py").is_file() and f"``{p.name}``" not in doc
    ]
    assert not missing, f"hzval/__init__.py's module map lacks {missing}"


def test_every_package_docstring_names_its_modules():
    """Each subpackage's ``__init__`` says what it holds: a module added is listed there
    (the materials, which a registry lists, aside)."""
    missing = []
    for init in PACKAGE.rglob("__init__.py"):
        package = init.parent
        if package in (PACKAGE, PACKAGE / "materials"):
            continue
        doc = ast.get_docstring(ast.parse(init.read_text()))
        names = [p.stem for p in package.glob("*.py") if p.stem != "__init__"]
        names += [p.name for p in package.iterdir() if (p / "__init__.py").is_file()]
        missing += [
            f"{package.relative_to(PACKAGE)}: {n}"
            for n in names
            if f"``{n}``" not in doc and f"``{n}/``" not in doc
        ]
    assert missing == []


#: docs/ARCHITECTURE.md's "Layout": each subpackage's layer. A module imports only layers below its
#: own, or its own subpackage.
LAYERS = {
    "cli": 10,
    "commands": 9,
    "studies": 8,
    "pipeline": 7,
    "report": 6,
    "techniques": 5,
    "truth": 4,
    "metrics": 4,
    "bake": 3,
    "scene": 2,
    "geometry": 1,
    "io": 0,
    "materials": 0,
    "core": -1,
}


def _subpackage(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if len(parts) > 2 or (len(parts) == 2 and parts[1] in LAYERS) else None


def test_every_subpackage_has_a_layer():
    found = {p.name for p in PACKAGE.iterdir() if (p / "__init__.py").is_file()}
    assert found == set(LAYERS)


def test_no_import_climbs_a_layer():
    climbs = []
    for module, deps in import_graph().items():
        a = _subpackage(module)
        for dep in deps:
            b = _subpackage(dep)
            if a and b and a != b and not LAYERS[b] < LAYERS[a]:
                climbs.append(f"{module} -> {dep}")
    assert climbs == []


def underscore_uses(root: Path) -> list[str]:
    """Uses of another module's underscore names under ``root``: ``alias._name`` where ``alias`` is an
    imported hzval module, and ``from hzval.x import _name``."""
    found = []
    for path in sorted(root.rglob("*.py")):
        tree = ast.parse(path.read_text(), str(path))
        aliases = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("hzval"):
                for a in node.names:
                    if a.name.startswith("_") and not a.name.startswith("__"):
                        found.append(f"{path.name}:{node.lineno}: from {node.module} import {a.name}")
                    aliases.add(a.asname or a.name)
            elif isinstance(node, ast.Import):
                aliases |= {
                    a.asname or a.name.split(".")[0] for a in node.names if a.name.startswith("hzval")
                }
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.Attribute)
                and node.attr.startswith("_")
                and not node.attr.startswith("__")
                and isinstance(node.value, ast.Name)
                and node.value.id in aliases
            ):
                found.append(f"{path.name}:{node.lineno}: {node.value.id}.{node.attr}")
    return found


#: Every folder of Python code beside the tests: the package and the scripts that use it.
CODE_FOLDERS = sorted(
    p.name
    for p in PACKAGE.parent.iterdir()
    if p.is_dir() and p.name != "tests" and not p.name.startswith(".") and any(p.glob("*.py"))
)  # hidden ones (.venv, .git) aside


def test_the_code_folders_are_found():
    assert (
        "hzval" in CODE_FOLDERS
        and len(CODE_FOLDERS) >= 3
        and not any(f.startswith(".") for f in CODE_FOLDERS)
    )


@pytest.mark.parametrize("folder", CODE_FOLDERS)
def test_nothing_reaches_into_another_modules_underscore_names(folder):
    assert underscore_uses(PACKAGE.parent / folder) == []


def test_the_underscore_check_finds_one(tmp_path):
    (tmp_path / "m.py").write_text("from hzval.truth import plane\nplane._bands(1, 2, 3)\n")
    assert underscore_uses(tmp_path) == ["m.py:2: plane._bands"]


def test_pages_are_rendered_by_jinja_templates_only():
    """HTML lives in hzval/report/templates; no module writes markup of its own."""
    markup = ("<!doctype", "<html", "<table", "<tr>", "<td", "<h1", "<h2")
    found = [
        f"{p.relative_to(PACKAGE)}: {m}"
        for p in sorted(PACKAGE.rglob("*.py"))
        for m in markup
        if m in p.read_text().lower()
    ]
    assert found == []


#: Issue 54's bounds: a file of hzval/ holds one job in at most this many lines, and its module
#: docstring says what it holds in at most this many (the design notes are in docs/internals.md).
MAX_LINES, MAX_DOCSTRING_LINES = 800, 40


def _modules() -> list[Path]:
    return sorted(PACKAGE.rglob("*.py"))


def test_no_file_is_over_its_bound():
    long = [
        f"{p.relative_to(PACKAGE)}: {n}"
        for p in _modules()
        if (n := len(p.read_text().splitlines())) > MAX_LINES
    ]
    assert long == []


def test_no_module_docstring_is_an_essay():
    long = []
    for p in _modules():
        doc = ast.get_docstring(ast.parse(p.read_text()), clean=False) or ""
        if doc.count("\n") + 1 > MAX_DOCSTRING_LINES:
            long.append(f"{p.relative_to(PACKAGE)}: {doc.count(chr(10)) + 1} lines")
    assert long == []


def test_only_the_records_module_reads_a_techniques_object_by_its_key():
    """Scores are read through hzval.metrics.results's records, not by string keys."""
    import re

    key = re.compile(r"""\[["']techniques["']\]|\.get\(["']techniques["']""")
    owner = PACKAGE / "metrics" / "results.py"
    found = [str(p.relative_to(PACKAGE)) for p in _modules() if p != owner and key.search(p.read_text())]
    assert found == []


def test_every_command_has_its_module_under_commands():
    """hzval/cli/NAME.py parses NAME's flags; its work is hzval/commands/NAME.py's."""
    from hzval.cli import main as cli

    names = [c.__name__.rsplit(".", 1)[1] for c in cli.COMMANDS]
    missing = [n for n in names if not (PACKAGE / "commands" / f"{n}.py").is_file()]
    assert missing == []


def _late_imports() -> tuple[int, list[tuple[Path, int, bool]]]:
    """Every import statement of hzval/, and those inside functions: (file, line, has a reason)."""
    total, late = 0, []
    for p in _modules():
        lines = p.read_text().splitlines()
        tree = ast.parse("\n".join(lines))
        total += sum(isinstance(n, (ast.Import, ast.ImportFrom)) for n in ast.walk(tree))
        inner = sorted(
            {
                n.lineno
                for f in ast.walk(tree)
                if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef))
                for n in ast.walk(f)
                if isinstance(n, (ast.Import, ast.ImportFrom))
            }
        )
        for ln in inner:
            above = lines[ln - 2].strip()
            # a block of imports shares the reason its first one gives
            reason = "#" in lines[ln - 1] or above.startswith("#") or (ln - 1 in inner and late[-1][2])
            late.append((p, ln, reason))
    return total, late


def test_imports_sit_at_the_top_and_a_late_one_says_why():
    """Issue 54: under a tenth of the imports inside functions (Dr.Jit after the LLVM is chosen, the
    CLI's commands on use, the slow optional packages where used), each with its reason."""
    total, late = _late_imports()
    assert len(late) < 0.1 * total, f"{len(late)} of {total} imports are inside functions"
    silent = [f"{p.relative_to(PACKAGE)}:{ln}" for p, ln, reason in late if not reason]
    assert silent == []


def test_the_cli_imports_no_renderer_before_it_chooses_the_llvm():
    """Dr.Jit reads DRJIT_LIBLLVM_PATH when first imported: importing the CLI, or the library's modules
    (hzval.core.backend's dr and mi load it at first use), must not load it."""
    import subprocess
    import sys

    probe = (
        "import sys, hzval.cli.main, hzval.scene.spec, hzval.bake.maps, hzval.metrics.compare, "
        "hzval.truth.plane; print(sorted({'drjit', 'mitsuba', 'matplotlib'} & set(sys.modules)))"
    )
    run = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert run.stdout.strip() == "[]"
