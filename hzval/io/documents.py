"""JSON and TOML read as documents: one line naming the file, never a traceback.

Every JSON or TOML file hzval reads (``frames.json``, ``metrics.json``, ``--baseline``,
``engine.toml``, ``--scene``, ``--horizon-encoding``) goes through :func:`read_json` or
:func:`read_toml`: unreadable, malformed or too deeply nested content (:data:`MAX_DEPTH`) is an
:class:`hzval.core.errors.InputError` naming the file, and the caller checks the shape it needs.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import tomllib
from pathlib import Path

import numpy as np

from hzval.core.errors import InputError
from hzval.io.atomic import atomic_path

__all__ = ["MAX_DEPTH", "depth", "read_json", "read_toml", "loads_json", "loads_toml", "write_json"]

#: The deepest nesting of arrays and tables hzval accepts; its own files nest at most 8 deep.
MAX_DEPTH = 64


def depth(value) -> int:
    """Return the nesting depth of lists and dicts in ``value``, walked without recursion.

    Parameters
    ----------
    value : object
        A parsed JSON or TOML document.

    Returns
    -------
    int
        0 for a scalar, 1 for a flat list or dict, and so on.

    Examples
    --------
    >>> depth(1), depth([]), depth({"a": [1, {"b": 2}]})
    (0, 1, 3)
    """
    deepest, stack = 0, [(value, 1)]
    while stack:
        v, d = stack.pop()
        if isinstance(v, dict):
            deepest = max(deepest, d)
            stack.extend((x, d + 1) for x in v.values())
        elif isinstance(v, list):
            deepest = max(deepest, d)
            stack.extend((x, d + 1) for x in v)
    return deepest


def _checked(data, where):
    if depth(data) > MAX_DEPTH:
        raise InputError(where, f"nests deeper than {MAX_DEPTH} levels: not a file hzval reads")
    return data


def loads_json(text: str, where: str | os.PathLike):
    """Parse JSON text; malformed or too deep content is one line naming ``where``."""
    try:
        return _checked(json.loads(text), where)
    except RecursionError:
        raise InputError(where, f"nests deeper than {MAX_DEPTH} levels: not a file hzval reads") from None
    except ValueError as exc:
        raise InputError(where, f"is not valid JSON ({str(exc).splitlines()[0]})") from None


def loads_toml(text: str, where: str | os.PathLike):
    """Parse TOML text; malformed or too deep content is one line naming ``where``."""
    try:
        return _checked(tomllib.loads(text), where)
    except RecursionError:
        raise InputError(where, f"nests deeper than {MAX_DEPTH} levels: not a file hzval reads") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(where, f"is not valid TOML ({str(exc).splitlines()[0]})") from None


def _text(path: Path) -> str:
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except UnicodeDecodeError:
        raise InputError(path, "is not UTF-8 text") from None
    except OSError as exc:
        raise InputError(path, f"cannot be read ({exc.strerror or exc})") from None


def read_json(path: str | os.PathLike):
    """Return a JSON file's content (:func:`loads_json`); a missing or unreadable file is one line."""
    return loads_json(_text(Path(path)), path)


def read_toml(path: str | os.PathLike):
    """Return a TOML file's content (:func:`loads_toml`); a missing or unreadable file is one line."""
    return loads_toml(_text(Path(path)), path)


def write_json(path: str | os.PathLike, data, *, atomic: bool = True) -> None:
    """Write ``data`` as indented strict JSON, atomically.

    Strict: JSON has no NaN or infinity, and a value that is not finite is
    refused with one line naming the file and the key (a caller writes
    ``null`` for what it knows may be undefined), never written as ``NaN``.
    """
    try:
        text = json.dumps(data, indent=2, sort_keys=False, default=_json_default, allow_nan=False) + "\n"
    except ValueError:
        raise InputError(
            path,
            f"{_non_finite_key(data) or 'a value'} is not a finite number; "
            "strict JSON has no NaN or infinity, so nothing was written",
        ) from None
    target = Path(path)
    ctx = atomic_path(target) if atomic else contextlib.nullcontext(target)
    with ctx as tmp:
        tmp.write_text(text, encoding="utf-8")


def _non_finite_key(data, where: str = "") -> str | None:
    """Return the first key path (``frames[0].flip_mean``) of ``data`` that holds a NaN or infinity."""
    if isinstance(data, (float, np.floating)):
        return None if np.isfinite(data) else (where or "the value")
    items = (
        data.items() if isinstance(data, dict) else enumerate(data) if isinstance(data, (list, tuple)) else ()
    )
    for k, v in items:
        found = _non_finite_key(v, f"{where}[{k}]" if isinstance(k, int) else f"{where}.{k}".lstrip("."))
        if found:
            return found
    return None


def _json_default(obj):
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return dataclasses.asdict(obj)
    raise TypeError(f"cannot serialise {type(obj).__name__}")
