"""The path rule: a path read from a file resolves inside the folder it came from, or is refused.

Frame names, stored file paths (``metrics.json``'s ``files``), glTF buffer URIs, scene names and
``material.path`` all come from files a user may have been handed. hzval opens or writes through
such a path only when it names a place inside the folder that holds the file (symbolic links
resolved), and a name that becomes one path component (a frame, a scene) must be one: no separator,
no ``.`` or ``..``, no control character. Anything else is one line naming the file and the key,
before anything is opened (docs/reliability.md, "The path rule").
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from urllib.parse import unquote, urlsplit

from hzval.core.errors import InputError

__all__ = [
    "MAX_NAME_CHARS",
    "file_name",
    "inside",
    "resolved",
    "is_data_uri",
    "uri_path",
    "no_symlink_below",
    "stored_input",
]

#: The longest name hzval writes as one path component (most file systems allow 255 bytes).
MAX_NAME_CHARS = 200

_CONTROL = re.compile(r"[\x00-\x1f\x7f]")


def file_name(value, where: str | os.PathLike, key: str) -> str:
    r"""Return a name read from a file, checked to be usable as one path component.

    Parameters
    ----------
    value : object
        The name as the file holds it.
    where : str or path-like
        The file, named first in the error.
    key : str
        The key in that file (``frames[3].name``), named in the error.

    Returns
    -------
    str
        ``value``.

    Raises
    ------
    hzval.core.errors.InputError
        When ``value`` is not a string, is empty, ``.`` or ``..``, holds ``/``, ``\\`` or a control
        character, starts with ``-`` or is longer than :data:`MAX_NAME_CHARS`.

    Examples
    --------
    >>> file_name("az+45", "frames.json", "frames[1].name")
    'az+45'
    >>> file_name("../x", "frames.json", "frames[1].name")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    hzval.core.errors.InputError: frames.json: frames[1].name '../x' is not a file name ...
    """
    ok = (
        isinstance(value, str)
        and value not in ("", ".", "..")
        and "/" not in value
        and "\\" not in value
        and not _CONTROL.search(value)
        and not value.startswith("-")
        and len(value) <= MAX_NAME_CHARS
    )
    if not ok:
        shown = repr(value) if len(repr(value)) <= 80 else repr(value)[:77] + "..."
        raise InputError(where, f"{key} {shown} is not a file name (no '/', '\\\\', '.' or '..')")
    return value


def inside(folder: str | os.PathLike, rel, where: str | os.PathLike, key: str) -> Path:
    """``folder / rel`` if it resolves inside ``folder``, symbolic links followed; else refused.

    Parameters
    ----------
    folder : str or path-like
        The folder that holds the file ``rel`` was read from.
    rel : object
        The stored path: a relative path string.
    where, key : str or path-like, str
        The file and key named in the error.

    Returns
    -------
    pathlib.Path
        ``folder / rel``, as given (not resolved).

    Raises
    ------
    hzval.core.errors.InputError
        When ``rel`` is not a non-empty string, is absolute, or leads outside ``folder`` (through
        ``..`` or a link).

    Examples
    --------
    >>> inside("sweep", "frames/az+0/truth.exr", "metrics.json", "files.truth").as_posix()
    'sweep/frames/az+0/truth.exr'
    """
    if not isinstance(rel, str) or not rel or _CONTROL.search(rel):
        raise InputError(where, f"{key} must be a relative path inside {folder}, got {rel!r}")
    if os.path.isabs(rel) or Path(rel).drive:
        raise InputError(where, f"{key} {rel!r} is an absolute path: hzval reads only inside {folder}")
    base = Path(folder)
    path = base / rel
    root = resolved(base, where, key)
    target = resolved(path, where, key)
    if target != root and root not in target.parents:
        raise InputError(where, f"{key} {rel!r} leads outside {folder}: hzval reads only inside it")
    return path


def resolved(path: str | os.PathLike, where: str | os.PathLike | None = None, key: str = "") -> Path:
    """Return ``path`` with its links followed (:meth:`pathlib.Path.resolve`).

    A loop of links is one line naming ``where`` and ``key`` (default: the path itself), where Python raises a
    RuntimeError.

    Examples
    --------
    >>> resolved("/tmp/../tmp").as_posix()
    '/tmp'
    """
    try:
        return Path(path).resolve()
    except (RuntimeError, OSError):  # RuntimeError: a loop (Python 3.11); OSError: ELOOP
        what = f"{key} {os.fspath(path)!r}: " if key else ""
        raise InputError(where or path, f"{what}a loop of symbolic links") from None


def is_data_uri(uri) -> bool:
    """Whether a glTF URI embeds its bytes (``data:...``) rather than naming a file.

    Examples
    --------
    >>> is_data_uri("data:application/octet-stream;base64,AAAA"), is_data_uri("mesh.bin")
    (True, False)
    """
    return isinstance(uri, str) and uri[:5].lower() == "data:"


def uri_path(folder: str | os.PathLike, uri, where: str | os.PathLike, key: str) -> Path:
    """Return the file a relative URI reference names (glTF 2.0, "URIs"), checked by :func:`inside`.

    Parameters
    ----------
    folder : str or path-like
        The folder of the file that holds the URI.
    uri : object
        The URI: a relative reference, percent-encoded. A scheme (``file:``, ``http:``) is refused.
    where, key : str or path-like, str
        The file and key named in the error.

    Returns
    -------
    pathlib.Path

    Examples
    --------
    >>> uri_path("model", "a%20b.bin", "model/m.gltf", "buffers[0].uri").as_posix()
    'model/a b.bin'
    """
    if not isinstance(uri, str):
        raise InputError(where, f"{key} must be a string, got {uri!r}")
    parts = urlsplit(uri)
    if parts.scheme or parts.netloc:
        raise InputError(where, f"{key} {uri!r} is not a relative file name: hzval reads only beside {where}")
    return inside(folder, unquote(parts.path), where, key)


def no_symlink_below(out: str | os.PathLike, rel: str | os.PathLike) -> None:
    """Refuse to write ``out / rel`` through a symbolic link at or below ``out``.

    Parameters
    ----------
    out : str or path-like
        The output folder.
    rel : str or path-like
        The path to be written, relative to ``out``.

    Raises
    ------
    hzval.core.errors.InputError
        Naming the link.
    """
    path = Path(out)
    for part in Path(rel).parts:
        path = path / part
        if path.is_symlink():
            raise InputError(path, "is a symbolic link: hzval does not write through links in its output")


def stored_input(folder: str | os.PathLike, stored, where: str | os.PathLike, key: str) -> Path:
    """Return an input file a run recorded (``material.path``, ``parameters.mesh``), found from any folder.

    A run records its inputs relative to its own folder (:func:`hzval.io.staging.report_path`), so
    the path is resolved against ``folder``, not the current directory. Unlike the run's own files
    (:func:`inside`), an input may lie outside ``folder``: it is only read, and the caller checks
    that it is still the file the run read (the material's digest).

    Parameters
    ----------
    folder : str or path-like
        The folder of the file that recorded the path (the run's ``--out``).
    stored : object
        The path as recorded: relative to ``folder``, or absolute.
    where, key : str or path-like, str
        The file and key named in the error.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    hzval.core.errors.InputError
        When ``stored`` is not a string or names no file.
    """
    if not isinstance(stored, str) or not stored or _CONTROL.search(stored):
        raise InputError(where, f"{key} must be a file name, got {stored!r}")
    path = Path(folder) / stored  # an absolute ``stored`` stays itself
    if not path.is_file():
        raise InputError(where, f"{key} {stored!r}: no such file beside the run (moved since it ran?)")
    return path
