"""Output folders written whole or not at all.

The module holds the folder's lock and marker, and :class:`Staging`, which moves a set of outputs into place
only once every file is written.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import os
import shlex
import shutil
import socket
import tempfile
import time
from pathlib import Path
from typing import Iterator

from hzval.core import interrupts
from hzval.core.errors import InputError, first_line
from hzval.io import documents

__all__ = [
    "LOCK_NAME",
    "MARKER_NAME",
    "folder_lock",
    "foreign_files",
    "os_error",
    "output_folder",
    "report_path",
    "portable_command",
    "swapped_in",
    "file_digest",
    "Staging",
]


#: The lock file of an output folder (:func:`folder_lock`).
LOCK_NAME = ".hzval-lock"
#: The marker of a folder hzval wrote: JSON that lists the files it wrote there (:func:`output_folder`).
MARKER_NAME = ".hzval"
#: Names of hzval's own bookkeeping in an output folder (never a user's file, never listed).
_OWN_PREFIXES = (".hzval-staging-", ".hzval-old-")
_OWN_NAMES = (LOCK_NAME, MARKER_NAME, ".hzval-suite")


@contextlib.contextmanager
def folder_lock(folder: str | os.PathLike, command: str = "") -> Iterator[Path]:
    """Hold ``folder`` for this run: an exclusive ``flock`` on ``folder/.hzval-lock``.

    A second run into the same folder fails at once with an :class:`InputError`
    naming the run that holds it (host, pid and start time, which the holder
    writes into the lock file; never its command line, which may hold private
    paths). The kernel drops the lock when its process ends, however it ends;
    the file is removed when the run leaves. A folder this creates and the run
    leaves empty is removed again. ``command`` is accepted and not written.
    """
    folder = Path(folder)
    created = not folder.exists()
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / LOCK_NAME
    fd = _take_lock(path, folder)
    try:
        os.ftruncate(fd, 0)
        os.pwrite(
            fd,
            (
                f"{socket.gethostname()} pid {os.getpid()}, since {time.strftime('%Y-%m-%d %H:%M:%S')}"
            ).encode(),
            0,
        )
        yield path
    finally:
        path.unlink(missing_ok=True)  # before the lock goes: a waiting run then makes a new file
        os.close(fd)  # releases the lock
        if created:
            with contextlib.suppress(OSError):
                folder.rmdir()  # only if empty


def _take_lock(path: Path, folder: Path) -> int:
    """Return an open descriptor of ``path`` holding its exclusive ``flock``.

    A holder that left removed the file it locked: a lock on that unlinked file would hold nothing, so take
    the new one.
    """
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
        except OSError as exc:  # a read-only folder: name it, not the lock file inside it
            raise InputError(folder, f"cannot be written ({exc.strerror or first_line(exc)})") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 4096, 0).decode("utf-8", "replace").strip() or "another run"
            os.close(fd)
            raise InputError(
                folder, f"in use by another hzval run ({holder}); wait for it or choose another --out"
            ) from None
        try:
            if os.fstat(fd).st_ino == os.stat(path).st_ino:
                return fd
        except FileNotFoundError:
            pass
        os.close(fd)


def _is_own(name: str) -> bool:
    """Whether an entry's name is hzval's bookkeeping (lock, marker, staging, an atomic write's temporary)."""
    return name in _OWN_NAMES or name.startswith(_OWN_PREFIXES) or (name.startswith(".") and ".tmp" in name)


def _listed(folder: Path) -> set[str] | None:
    """Return the files ``folder``'s marker lists (paths relative to it).

    It returns ``None`` without a readable marker.
    """
    try:
        data = documents.read_json(folder / MARKER_NAME)
        return {str(p) for p in data["files"]}
    except (InputError, KeyError, TypeError):
        return None


def _walk_files(folder: Path) -> list[str]:
    """Return every file under ``folder`` (relative POSIX paths) that is not hzval's bookkeeping.

    The folders of other hzval runs (a subfolder with a marker of its own: a suite's or views' sweeps) are
    left out too.
    """
    found = []
    for root, dirs, names in os.walk(folder):
        here = Path(root)
        dirs[:] = [d for d in dirs if not _is_own(d) and not (here / d / MARKER_NAME).is_file()]
        found += [(here / n).relative_to(folder).as_posix() for n in names if not _is_own(n)]
    return sorted(found)


def foreign_files(folder: str | os.PathLike) -> list[str]:
    """Return the files under ``folder`` that hzval did not write, as relative paths.

    They are the files not listed in its marker.
    """
    folder = Path(folder)
    if not folder.is_dir():
        return []
    listed = _listed(folder) or set()
    return [p for p in _walk_files(folder) if p not in listed]


def _write_marker(folder: Path, foreign: set[str]) -> None:
    """List every file under ``folder`` but the ``foreign`` ones as hzval's (the folder's marker)."""
    own = [p for p in _walk_files(folder) if p not in foreign]
    documents.write_json(
        folder / MARKER_NAME,
        {
            "format": "hzval folder 1",
            "note": "the files hzval wrote here; it replaces only these",
            "files": own,
        },
    )


def _first_missing(folder: Path) -> Path | None:
    """Return the outermost folder of ``folder`` and its parents that does not exist yet.

    It is what a run creates.
    """
    missing = None
    for p in [folder, *folder.parents]:
        if p.exists() or p.is_symlink():
            break
        missing = p
    return missing


def _check_folder(folder: Path) -> None:
    """Refuse an ``--out`` that is, or lies in, a file."""
    for p in [folder, *folder.parents]:
        if p.exists():
            if not p.is_dir():
                raise InputError(
                    folder, "is a file, not a folder" if p == folder else f"cannot be a folder: {p} is a file"
                )
            return


def os_error(exc: OSError, fallback: str | os.PathLike) -> InputError:
    """Return an :class:`OSError` as one line naming its path.

    The error may be a read-only or full disk, no permission, ...; the path named is the one the file would
    have had, its staging folders (:class:`Staging`) left out.

    >>> str(os_error(OSError(28, "No space left on device", "r/.hzval-staging-ab12/frames/x.exr"), "--out"))
    'r/frames/x.exr: No space left on device'
    """
    where = exc.filename if exc.filename is not None else fallback
    if isinstance(where, (str, os.PathLike)):
        parts = [p for p in Path(where).parts if not p.startswith(_OWN_PREFIXES[0])]
        where = Path(*parts) if parts else where
    return InputError(where, exc.strerror or first_line(exc))


@contextlib.contextmanager
def output_folder(
    folder: str | os.PathLike, *, force: bool = False, keep_on_interrupt: bool = False
) -> Iterator[Path]:
    """Hold an output folder for one run: refuse one that is not hzval's, lock it, clean up after.

    ``folder`` must be new, empty, or hzval's: every file in it listed in its
    marker (:data:`MARKER_NAME`, which a run writes as it leaves). A folder
    with other files is refused with one line naming some, unless ``force``;
    even then only hzval's files are replaced (:meth:`Staging.swap` keeps the
    others). The run holds :func:`folder_lock`. A run that fails or is
    interrupted leaves no folder it created (``keep_on_interrupt``: a Ctrl-C
    keeps what it wrote, for the suite's overview of what finished); an
    :class:`OSError` becomes one line naming the path (:func:`os_error`).
    """
    folder = Path(folder)
    _check_folder(folder)
    created = _first_missing(folder)
    done = False
    try:
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise os_error(exc, folder) from None
        with folder_lock(folder):
            foreign = foreign_files(folder)
            if foreign and not force:
                more = f" and {len(foreign) - 3} more" if len(foreign) > 3 else ""
                raise InputError(
                    folder,
                    f"holds files hzval did not write ({', '.join(foreign[:3])}{more}): "
                    "choose a new or empty folder, or --force to write beside them",
                )
            Staging.remove_leftovers(folder)
            try:
                yield folder
            except KeyboardInterrupt:
                if keep_on_interrupt:
                    _write_marker(folder, set(foreign))
                    done = True
                raise
            _write_marker(folder, set(foreign))
            done = True
    except OSError as exc:
        raise os_error(exc, folder) from None
    finally:
        if not done and created is not None:
            shutil.rmtree(created, ignore_errors=True)


def report_path(path: str | os.PathLike | None, report_dir: str | os.PathLike) -> str | None:
    """Return ``path`` as a report records it: relative to ``report_dir``.

    A file beside it is recorded as ``../maps/x.png``, so that a shared report does not carry the absolute
    folders (a home folder's user name) it was made in. Where no relative path exists (another drive), the
    path is kept as given.
    """
    if path is None:
        return None
    try:
        return Path(os.path.relpath(Path(path).resolve(), Path(report_dir).resolve())).as_posix()
    except (ValueError, RuntimeError, OSError):  # another drive; a loop of links
        return os.fspath(path)


def portable_command(command: str) -> str:
    """Return a command line as a report shows it: one that runs from the folder it was run in.

    Each absolute path in it (``/home/me/x.png``, ``--out=/home/me/r``) is made relative to the
    current directory (``../maps/x.png``), so the line carries no home folder's name and still
    names the same files from there; relative paths stay as typed.

    Parameters
    ----------
    command : str
        The command line, shell-quoted.

    Returns
    -------
    str
        The command line, shell-quoted; as given where it does not split into words.
    """
    try:
        words = shlex.split(command, comments=False)
    except ValueError:
        return command
    out = []
    for w in words:
        prefix, value = (
            ("", w)
            if not (w.startswith("--") and "=" in w)
            else (w.partition("=")[0] + "=", w.partition("=")[2])
        )
        if value.startswith("/"):
            value = report_path(value, os.getcwd())
        out.append(prefix + value)
    return " ".join(shlex.quote(w) if w != "#" else w for w in out)


def file_digest(path: str | os.PathLike) -> str:
    """``"sha256:<hex>"`` of a file's bytes."""
    with open(path, "rb") as f:
        return "sha256:" + hashlib.file_digest(f, "sha256").hexdigest()


@contextlib.contextmanager
def swapped_in(out: str | os.PathLike, *, force: bool = False) -> Iterator[Path]:
    """Yield a run's output, all or nothing, through a staging folder swapped in whole.

    It holds ``out`` (:func:`output_folder`), yields a staging folder inside it to write into, then swaps that
    in whole (:meth:`Staging.swap`) with signals held from the last moment
    (:func:`hzval.core.interrupts.held`). A failure or an interrupt before the swap leaves an earlier report
    byte for byte.

    Parameters
    ----------
    out : str or path-like
        The output folder.
    force : bool
        As :func:`output_folder`'s.

    Yields
    ------
    pathlib.Path
        The staging folder.
    """
    with interrupts.held() as hold, output_folder(out, force=force):
        with Staging(out) as stage:
            yield stage.dir
            hold.start()
            stage.swap()


class Staging:
    """Collect a set of output files, then move them into ``out`` together.

    Files are written under a hidden folder inside ``out`` (same file system,
    so the final moves are renames). :meth:`commit` moves each into place;
    leaving the ``with`` block without committing removes everything staged.
    ``out`` itself is created only on :meth:`commit`, or if it is needed to
    hold the staging folder.
    """

    def __init__(self, out: str | os.PathLike):
        self.out = Path(out)
        self._created_out = not self.out.exists()
        self.out.mkdir(parents=True, exist_ok=True)
        self.dir = Path(tempfile.mkdtemp(prefix=".hzval-staging-", dir=self.out))
        self._committed = False

    def path(self, name: str) -> Path:
        """Path in the staging folder for the output called ``name`` (may contain '/')."""
        p = self.dir / name
        p.parent.mkdir(parents=True, exist_ok=True)
        return p

    def commit(self) -> list[Path]:
        """Move every staged file to its place under ``out``; return the final paths."""
        final = []
        for src in sorted(p for p in self.dir.rglob("*") if p.is_file()):
            dst = self.out / src.relative_to(self.dir)
            dst.parent.mkdir(parents=True, exist_ok=True)
            os.replace(src, dst)
            final.append(dst)
        shutil.rmtree(self.dir, ignore_errors=True)
        self._committed = True
        return final

    def swap(self) -> None:
        """Put each staged top-level entry in place of ``out``'s entry of that name, whole.

        A folder replaces the old folder (none of hzval's old files in it survive), a file the old file. Each
        swap is two renames, so a reader sees the old entry or the new one. Files that hzval did not write
        (:func:`foreign_files`; there only with ``--force``) are moved into the new folder first: only hzval's
        own files are ever replaced.
        """
        foreign = foreign_files(self.out)
        for src in sorted(self.dir.iterdir()):
            dst = self.out / src.name
            if src.is_dir() and dst.is_dir():
                for rel in foreign:
                    if rel.startswith(src.name + "/") and not (self.out / rel).is_symlink():
                        keep = self.dir / rel
                        if not keep.exists():
                            keep.parent.mkdir(parents=True, exist_ok=True)
                            os.replace(self.out / rel, keep)
                old = Path(tempfile.mkdtemp(prefix=".hzval-old-", dir=self.out))
                os.replace(dst, old / src.name)
                os.replace(src, dst)
                shutil.rmtree(old, ignore_errors=True)
            else:
                if dst.is_dir() and not dst.is_symlink():
                    shutil.rmtree(dst)
                os.replace(src, dst)
        shutil.rmtree(self.dir, ignore_errors=True)
        self._committed = True

    @staticmethod
    def remove_leftovers(out: str | os.PathLike) -> None:
        """Remove the staging folders a killed run left in ``out`` (call it holding :func:`folder_lock`)."""
        for p in Path(out).glob(".hzval-staging-*"):
            shutil.rmtree(p, ignore_errors=True)
        for p in Path(out).glob(".hzval-old-*"):
            shutil.rmtree(p, ignore_errors=True)

    def __enter__(self) -> "Staging":
        """Enter the staging: the folder is removed on leaving unless committed."""
        return self

    def __exit__(self, *exc) -> None:
        """Remove the staging folder (and the output folder it created) unless committed."""
        if not self._committed:
            shutil.rmtree(self.dir, ignore_errors=True)
            if self._created_out:
                with contextlib.suppress(OSError):
                    self.out.rmdir()  # only if empty
