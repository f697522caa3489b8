"""Strict reading of hzval's TOML files: every table, key and type is checked, nothing is coerced.

A scene (:mod:`hzval.scene.spec`), a sidecar or a horizon encoding
(:mod:`hzval.io.external`) is refused with one line for an unknown table or key
(``unknown key 'dpeth' in [material]; did you mean 'depth'?``, the nearest
known name by :func:`difflib.get_close_matches`) and for a value of the wrong
type (``samples.spp must be an integer, got 2.7``): a typo must not silently
sweep the built-in bricks, nor ``2.7`` samples become 2.

Types are those of the dataclass fields a table fills (:func:`schema_of`):
``int`` (a TOML integer, not a float, not a boolean), ``float`` (an integer or
a float), ``str``, ``bool``, ``tuple[T, ...]`` and ``tuple[T, T]`` (an array of
them), and unions of these (``str | float | None``: ``None`` is the default
and cannot be written in TOML).
"""

from __future__ import annotations

import dataclasses
import difflib
import os
import types
import typing
from typing import Mapping

from hzval.core.errors import InputError

__all__ = ["check_keys", "check_value", "check_table", "schema_of", "describe"]


def _nearest(key: str, known) -> str:
    near = difflib.get_close_matches(str(key), [str(k) for k in known], n=1, cutoff=0.6)
    return f"; did you mean {near[0]!r}?" if near else f" (known: {', '.join(sorted(map(str, known)))})"


def check_keys(table: Mapping, known, path: str | os.PathLike, where: str = "") -> None:
    """Refuse a key of ``table`` that ``known`` does not hold, with the nearest known name.

    ``unknown key 'dpeth' in [material]; did you mean 'depth'?`` (:func:`difflib.get_close_matches`);
    at the top level (``where`` empty) an unknown table is named as a table.

    Parameters
    ----------
    table : Mapping
        The TOML table as read.
    known : Mapping or collection of str
        Its allowed keys (a schema, :func:`schema_of`).
    path : str or path-like
        The file, named first in the error.
    where : str
        The table's name (``material``), or empty for the file's top level.

    Raises
    ------
    hzval.core.errors.InputError
        For an unknown key, or a ``table`` that is not a table.
    """
    if not isinstance(table, Mapping):
        raise InputError(path, f"[{where}] must be a table, got {table!r:.40}" if where else "is not a table")
    for key, value in table.items():
        if key in known:
            continue
        if not where and isinstance(value, dict):
            tables = [k for k in known if k != "name"]
            near = difflib.get_close_matches(str(key), tables, n=1, cutoff=0.6)
            hint = (
                f"; did you mean [{near[0]}]?" if near else f" (known: {', '.join(f'[{t}]' for t in tables)})"
            )
            raise InputError(path, f"unknown table [{key}]{hint}")
        place = f" in [{where}]" if where else ""
        raise InputError(path, f"unknown key {key!r}{place}{_nearest(key, known)}")


def describe(hint) -> str:
    """Return a type hint in words, for error messages.

    Parameters
    ----------
    hint : type or typing hint
        ``int``, ``float``, ``str``, ``bool``, ``tuple[T, ...]``, ``tuple[T, T]`` or a union of these.

    Returns
    -------
    str
        ``"an integer"``, ``"a number"``, ``"a list of 2 integers"``, ...

    Examples
    --------
    >>> describe(int), describe(tuple[float, ...]), describe(str | None)
    ('an integer', 'a list of numbers', 'a string')
    """
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        return " or ".join(describe(a) for a in args if a is not type(None))
    if origin is tuple:
        if len(args) == 2 and args[1] is Ellipsis:
            return f"a list of {describe(args[0]).split(' ', 1)[1]}s"
        return f"a list of {len(args)} {describe(args[0]).split(' ', 1)[1]}s"
    return {
        int: "an integer",
        float: "a number",
        str: "a string",
        bool: "a boolean (true or false)",
        dict: "a table",
    }.get(hint, f"a {getattr(hint, '__name__', hint)}")


def _matches(value, hint) -> bool:
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        return any(_matches(value, a) for a in args)
    if hint is type(None):
        return value is None
    if hint is bool:
        return isinstance(value, bool)
    if hint is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if hint is float:
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if hint is str:
        return isinstance(value, str)
    if hint is dict or origin is dict:
        return isinstance(value, dict)
    if origin is tuple:
        if not isinstance(value, (list, tuple)):
            return False
        if len(args) == 2 and args[1] is Ellipsis:
            return all(_matches(v, args[0]) for v in value)
        return len(value) == len(args) and all(_matches(v, a) for v, a in zip(value, args))
    return True  # a hint this does not know (Any): the dataclass checks it


def check_value(value, hint, path: str | os.PathLike, name: str) -> None:
    """Refuse ``value`` unless it is of type ``hint``, nothing coerced (``2.7`` is not an integer).

    Parameters
    ----------
    value : object
        The value as TOML read it.
    hint : type or typing hint
        Its field's type (:func:`describe` lists the kinds).
    path : str or path-like
        The file, named first in the error.
    name : str
        The key, as the error names it (``samples.spp``).

    Raises
    ------
    hzval.core.errors.InputError
        ``samples.spp must be an integer, got 2.7``.
    """
    if not _matches(value, hint):
        raise InputError(path, f"{name} must be {describe(hint)}, got {value!r}")


def schema_of(cls, rename: Mapping[str, str] | None = None, drop=()) -> dict:
    """Return the keys a TOML table may hold, from the dataclass it fills.

    Parameters
    ----------
    cls : type
        A dataclass.
    rename : Mapping of str to str, optional
        A field's key in the file, where it differs from the field's name.
    drop : collection of str
        Fields the file does not set.

    Returns
    -------
    dict
        ``{key: type hint}``.
    """
    hints = typing.get_type_hints(cls)
    rename = dict(rename or {})
    return {rename.get(f.name, f.name): hints[f.name] for f in dataclasses.fields(cls) if f.name not in drop}


def check_table(table, schema: Mapping, path: str | os.PathLike, where: str) -> dict:
    """Check a TOML table against a schema: only its keys (:func:`check_keys`), each of its type.

    Parameters
    ----------
    table : object
        The table as read.
    schema : Mapping
        ``{key: type hint}`` (:func:`schema_of`).
    path : str or path-like
        The file, named first in errors.
    where : str
        The table's name, or empty for the top level.

    Returns
    -------
    dict
        ``table``, unchanged.

    Raises
    ------
    hzval.core.errors.InputError
        For a table that is not a table, an unknown key or a value of another type.
    """
    if not isinstance(table, dict):
        raise InputError(path, f"{where} must be a table ([{where}]), got {table!r}")
    check_keys(table, schema, path, where)
    for key, value in table.items():
        check_value(value, schema[key], path, f"{where}.{key}" if where else key)
    return table
