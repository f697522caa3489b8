"""A subpackage's public names, re-exported from its modules at their first use.

Each subpackage's ``__init__`` lists its modules; ``from hzval.truth import Truth`` then finds
``Truth`` in whichever of them names it in ``__all__``. Nothing is imported until a name is asked
for, so importing ``hzval.core.errors`` does not import the rendering stack, and the order in which
subpackages import one another cannot form a cycle through an ``__init__``.
"""

from __future__ import annotations

import importlib
import importlib.util
from collections.abc import Callable, Sequence

__all__ = ["exports"]


def exports(package: str, modules: Sequence[str]) -> tuple[Callable, Callable]:
    """The ``__getattr__`` and ``__dir__`` of a package that re-exports its modules' ``__all__``.

    Parameters
    ----------
    package
        The package's ``__name__``.
    modules
        Its modules' names, relative to the package (``"plane"``, ``"fitted.fit"``), in the order
        their names are looked up.

    Returns
    -------
    tuple
        ``(__getattr__, __dir__)`` for the package's namespace (PEP 562). ``__all__`` is answered
        by ``__getattr__`` too: every module's ``__all__``, in order, each name once.
    """
    if isinstance(modules, str):
        raise TypeError("modules: a sequence of module names, not one string")
    table: dict[str, str] = {}

    def load() -> dict[str, str]:
        if not table:
            for name in modules:
                module = importlib.import_module(f"{package}.{name}")
                for public in module.__all__:
                    table.setdefault(public, module.__name__)
        return table

    def __getattr__(name: str):
        if name == "__all__":
            return list(load())
        if name.startswith("__"):
            raise AttributeError(name)
        if name in modules or importlib.util.find_spec(f"{package}.{name}") is not None:
            # ``from hzval.truth import plane``: that module alone, whether it re-exports or not
            return importlib.import_module(f"{package}.{name}")
        where = load().get(name)
        if where is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(where), name)

    def __dir__() -> list[str]:
        return sorted(set(load()) | set(modules))

    return __getattr__, __dir__
