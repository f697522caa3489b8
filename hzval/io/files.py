"""Reading and writing hzval's files: EXR (OpenEXR), PNG (libpng through imagecodecs; palette images
and reading through Pillow), JSON.

Every writer is atomic: it writes to a hidden temporary name in the target
folder and renames it into place (``os.replace``), so a reader never sees a
partial file and a crash leaves no corrupt output behind. :class:`Staging`
extends that to a whole set of outputs: nothing appears in the output folder
until every file has been written.
"""

from __future__ import annotations

import contextlib
import dataclasses
import errno
import hashlib
import json
import os
import shutil
import socket
import tempfile
import time
from pathlib import Path
from typing import Iterator, Mapping, NamedTuple

import numpy as np

from hzval.core.errors import InputError

__all__ = [
    "atomic_path",
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
    "HALF_MAX",
    "write_exr",
    "is_grey",
    "read_exr",
    "read_exr_attributes",
    "read_rgb_exr",
    "rgb_of",
    "library_output",
    "run_writers",
    "Writers",
    "Indexed",
    "write_png",
    "PREVIEW_ABOVE_PX",
    "PREVIEW_PX",
    "write_figure",
    "preview_of",
    "write_png_with_preview",
    "unit_to_u8",
    "write_json",
    "first_line",
]


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it to ``path`` on success.

    On an exception the temporary file is removed and ``path`` is untouched.
    The file gets the permissions a plain ``open`` would give it (``0666``
    less the umask), not ``mkstemp``'s private ``0600``: reports are shared.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp" + path.suffix, dir=path.parent)
    os.close(fd)
    tmp = Path(tmp)
    try:
        yield tmp
        if tmp.exists():
            os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def _umask() -> int:
    """The process's umask (read by setting it and setting it back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


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
    """An open descriptor of ``path`` holding its exclusive ``flock``. A holder that left removed the
    file it locked: a lock on that unlinked file would hold nothing, so take the new one."""
    import fcntl

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
    """The files ``folder``'s marker lists (paths relative to it), or ``None`` without a readable marker."""
    from hzval.io import documents

    try:
        data = documents.read_json(folder / MARKER_NAME)
        return {str(p) for p in data["files"]}
    except (InputError, KeyError, TypeError):
        return None


def _walk_files(folder: Path) -> list[str]:
    """Every file under ``folder`` (relative POSIX paths), hzval's bookkeeping and the folders of other
    hzval runs (a subfolder with a marker of its own: a suite's or views' sweeps) left out."""
    found = []
    for root, dirs, names in os.walk(folder):
        here = Path(root)
        dirs[:] = [d for d in dirs if not _is_own(d) and not (here / d / MARKER_NAME).is_file()]
        found += [(here / n).relative_to(folder).as_posix() for n in names if not _is_own(n)]
    return sorted(found)


def foreign_files(folder: str | os.PathLike) -> list[str]:
    """The files under ``folder`` that hzval did not write (not listed in its marker), as relative paths."""
    folder = Path(folder)
    if not folder.is_dir():
        return []
    listed = _listed(folder) or set()
    return [p for p in _walk_files(folder) if p not in listed]


def _write_marker(folder: Path, foreign: set[str]) -> None:
    """List every file under ``folder`` but the ``foreign`` ones as hzval's (the folder's marker)."""
    own = [p for p in _walk_files(folder) if p not in foreign]
    write_json(
        folder / MARKER_NAME,
        {
            "format": "hzval folder 1",
            "note": "the files hzval wrote here; it replaces only these",
            "files": own,
        },
    )


def _first_missing(folder: Path) -> Path | None:
    """The outermost folder of ``folder`` and its parents that does not exist yet (what a run creates)."""
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
    """An :class:`OSError` (read-only or full disk, no permission, ...) as one line naming its path: the
    path the file would have had, its staging folders (:class:`Staging`) left out.

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
    """``path`` as a report records it: relative to ``report_dir`` (``../maps/x.png`` for a file
    beside it), so that a shared report does not carry the absolute folders (a home folder's user
    name) it was made in; the path as given where no relative one exists (another drive)."""
    if path is None:
        return None
    try:
        return Path(os.path.relpath(Path(path).resolve(), Path(report_dir).resolve())).as_posix()
    except (ValueError, RuntimeError, OSError):  # another drive; a loop of links
        return os.fspath(path)


def portable_command(command: str) -> str:
    """A command line as a report shows it: one that runs from the folder it was run in.

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
    import shlex

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
    """A run's output, all or nothing: hold ``out`` (:func:`output_folder`), yield a staging folder
    inside it to write into, then swap that in whole (:meth:`Staging.swap`) with signals held from
    the last moment (:func:`hzval.core.interrupts.held`). A failure or an interrupt before the swap
    leaves an earlier report byte for byte.

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
    from hzval.core import interrupts

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
        """Put each staged top-level entry in place of ``out``'s entry of that name, whole: a folder
        replaces the old folder (none of hzval's old files in it survive), a file the old file. Each
        swap is two renames, so a reader sees the old entry or the new one. Files that hzval did not
        write (:func:`foreign_files`; there only with ``--force``) are moved into the new folder
        first: only hzval's own files are ever replaced."""
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
        return self

    def __exit__(self, *exc) -> None:
        if not self._committed:
            shutil.rmtree(self.dir, ignore_errors=True)
            if self._created_out:
                with contextlib.suppress(OSError):
                    self.out.rmdir()  # only if empty


# --------------------------------------------------------------------------
# EXR
# --------------------------------------------------------------------------

#: The largest finite OpenEXR HALF (float16): a larger value would be stored as infinity.
HALF_MAX = 65504.0


def write_exr(
    path: str | os.PathLike,
    channels: Mapping[str, np.ndarray],
    *,
    atomic: bool = True,
    compression: str = "zip",
    half: bool = False,
    grey: bool = False,
    attributes: Mapping[str, str] | None = None,
) -> None:
    """Write channels ``{name: (rows, cols)}`` to a scanline EXR, float32 or half.

    Channel names ``R, G, B, A`` are written as such; an ``(rows, cols, 3|4)``
    array under the key ``"RGB"``/``"RGBA"`` is split into them.
    ``compression``: ``"zip"``, ``"none"`` (float32 bake data compresses
    by under 10%, at five times the writing time) or ``"pxr24"`` (OpenEXR's
    24-bit float: float32's range with 2^-16 relative precision, the lowest
    8 bits of a float32 rounded away; 35% fewer bytes than ZIP on noisy
    float32 data; lossless on half).

    ``half``: each channel as OpenEXR HALF (11 significant bits: 2^-11
    relative from 6.1e-5 up; below that steps of 6e-8), about half the bytes
    and time; a channel with a finite value beyond :data:`HALF_MAX` stays
    float32 rather than turn infinite. The default, float32, is for data that
    is read back as it was computed (the bake cache, the check's references).
    ``grey``: an ``"RGB"``/``"RGBA"`` array whose R, G and B are bitwise equal
    is written as one ``Y`` channel (and ``A``): lossless, a third of the
    bytes; :func:`read_rgb_exr` reads either back as RGB.
    ``attributes``: string attributes for the header (:func:`read_exr_attributes` reads them back).
    """
    import OpenEXR

    chans: dict[str, np.ndarray] = {}
    for name, arr in channels.items():
        arr = np.asarray(arr, dtype=np.float32)
        if name in ("RGB", "RGBA"):
            chans.update(_split_colour(name, arr, grey))
        else:
            chans[name] = np.ascontiguousarray(arr)
    if half:
        chans = {name: _as_half(arr) for name, arr in chans.items()}
    codec = {
        "zip": OpenEXR.ZIP_COMPRESSION,
        "none": OpenEXR.NO_COMPRESSION,
        "pxr24": OpenEXR.PXR24_COMPRESSION,
    }[compression]
    header = {**dict(attributes or {}), "compression": codec, "type": OpenEXR.scanlineimage}
    target = Path(path)
    ctx = atomic_path(target) if atomic else contextlib.nullcontext(target)
    with ctx as tmp:
        try:
            with OpenEXR.File(header, chans) as f:
                f.write(str(tmp))
        except RuntimeError as exc:  # OpenEXR's text for what the OS said
            raise _write_error(exc, target) from None


#: The OS errors an EXR write reports in its own words, by their text (OpenEXR raises RuntimeError).
_WRITE_ERRNOS = (errno.ENOSPC, errno.EFBIG, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EIO)


def _write_error(exc: RuntimeError, target: Path) -> Exception:
    """The :class:`OSError` a library's write error stands for (a full disk: ENOSPC; a file too large:
    EFBIG), naming ``target`` rather than its temporary name; else one line naming ``target``."""
    text = str(exc)
    for code in _WRITE_ERRNOS:
        if os.strerror(code) in text:
            return OSError(code, os.strerror(code), str(target))
    return InputError(target, f"cannot be written ({first_line(exc)})")


def _split_colour(name: str, arr: np.ndarray, grey: bool) -> dict[str, np.ndarray]:
    """``{"R": .., "G": .., "B": ..[, "A": ..]}`` of an ``(rows, cols, 3|4)`` float32 array, or
    ``{"Y": ..[, "A": ..]}`` with ``grey`` when R, G and B are bitwise equal (NaNs and signed zeros
    included, so nothing is lost)."""
    planes = {c: np.ascontiguousarray(arr[..., k]) for k, c in enumerate(name)}
    if grey and is_grey(arr[..., :3]):
        return {"Y": planes["R"], **({"A": planes["A"]} if "A" in planes else {})}
    return planes


def is_grey(rgb: np.ndarray) -> bool:
    """Whether the channels of an ``(..., 3)`` array are bitwise equal everywhere (floats compared as
    their bits: NaNs and signed zeros included)."""
    rgb = np.asarray(rgb)
    if rgb.shape[-1:] != (3,):
        return False
    bits = rgb.view(f"u{rgb.itemsize}") if rgb.dtype.kind == "f" else rgb
    return bool(np.array_equal(bits[..., 0], bits[..., 1]) and np.array_equal(bits[..., 1], bits[..., 2]))


def _as_half(arr: np.ndarray) -> np.ndarray:
    """A float32 channel as float16 (rounded to nearest), unless a finite value would become infinite
    (beyond :data:`HALF_MAX` and its rounding margin)."""
    with np.errstate(over="ignore"):
        h = arr.astype(np.float16)
    overflow = np.isinf(h)
    if overflow.any() and np.isfinite(arr[overflow]).any():
        return arr
    return h


def read_exr(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Read every channel of the first part of an EXR as float32 ``(rows, cols)`` arrays.

    Raises :class:`InputError` naming the file if it cannot be read.
    """
    import OpenEXR

    if not Path(path).is_file():  # the library would call a missing file "0 parts"
        raise InputError(path, "no such file" if not Path(path).exists() else "not a file")
    with library_output() as printed:
        try:
            with OpenEXR.File(str(path), separate_channels=True) as f:
                return {name: np.asarray(ch.pixels, dtype=np.float32) for name, ch in f.channels().items()}
        except Exception as exc:  # OpenEXR raises bare RuntimeErrors with library text
            error = exc
    # the C library's own diagnosis (e.g. a corrupt chunk) is more telling
    # than the binding's exception, which may only say "0 parts"
    lines = [ln for ln in printed() if "EXR_ERR" in ln] or printed() or [first_line(error)]
    detail = lines[-1].removeprefix(f"{path}: ")
    raise InputError(path, f"truncated or corrupt EXR file: {detail}")


def read_exr_attributes(path: str | os.PathLike) -> dict[str, str]:
    """The string attributes of an EXR's first header (those :func:`write_exr` was given, and any
    other writer's); ``{}`` for a file that cannot be read (:func:`read_exr` names its problem)."""
    import OpenEXR

    with library_output():
        try:
            with OpenEXR.File(str(path), header_only=True) as f:
                return {k: v for k, v in f.header().items() if isinstance(v, str)}
        except Exception:  # the caller reads the channels too, which reports the damage
            return {}


def read_rgb_exr(path: str | os.PathLike) -> np.ndarray:
    """An EXR's colour as ``(rows, cols, 3)`` float32: its ``R, G, B`` channels, or its grey ``Y``
    channel repeated (:func:`write_exr` with ``grey`` stores an image with R == G == B so; the
    sweep's frames are written that way). Half channels come back as float32, exactly.

    Raises :class:`InputError` naming the file if it has neither.
    """
    return rgb_of(read_exr(path), path)


def rgb_of(channels: Mapping[str, np.ndarray], path: str | os.PathLike) -> np.ndarray:
    """``(rows, cols, 3)`` float32 of channels read by :func:`read_exr`: R, G, B, else Y as grey."""
    if all(c in channels for c in "RGB"):
        return np.stack([channels[c] for c in "RGB"], axis=-1)
    if "Y" in channels:
        return np.repeat(channels["Y"][..., None], 3, axis=-1)
    raise InputError(path, f"no R, G, B or Y channel (has {', '.join(sorted(channels))})")


@contextlib.contextmanager
def library_output() -> Iterator:
    """Capture what C/C++ libraries print on stdout and stderr (file descriptors 1, 2).

    OpenEXR reports a corrupt file by printing to both before it raises; a
    command line that promises one-line errors must not let that through.
    Yields a function that returns the captured lines.
    """
    import sys

    for stream in (sys.stdout, sys.stderr):
        stream.flush()
    lines: list[str] = []
    with tempfile.TemporaryFile(mode="w+b") as sink:
        saved = [os.dup(1), os.dup(2)]
        try:
            os.dup2(sink.fileno(), 1)
            os.dup2(sink.fileno(), 2)
            yield lambda: lines
        finally:
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)
            sink.seek(0)
            lines[:] = [ln.strip() for ln in sink.read().decode(errors="replace").splitlines() if ln.strip()]


def run_writers(jobs) -> None:
    """Run the callables ``jobs`` (each writes a file) on the host pool and wait for every one
    (:class:`Writers`)."""
    with Writers() as writers:
        for job in jobs:
            writers.submit(job)


class Writers:
    """File writers started as they are given (:meth:`submit`), on the host pool, a thread per core
    (the image encoders release the GIL), and awaited when the ``with`` block ends. A writer's error
    is raised there; on it, or on an error or Ctrl-C in the block, the writers not yet started are
    cancelled and the running ones awaited, so that none puts a file into a folder after its caller
    has removed it."""

    def __enter__(self) -> "Writers":
        self.pending: list = []
        return self

    def submit(self, job) -> None:
        """Start the callable ``job`` (it writes a file) on the host pool."""
        from hzval.core import backend

        self.pending.append(backend.host_pool().submit(job))

    def wait(self) -> None:
        """Wait for every writer started so far; a writer's error is raised here."""
        for done in self.pending:
            done.result()

    def __exit__(self, kind, error, trace) -> bool:
        import concurrent.futures

        try:
            if kind is None:
                self.wait()
        except BaseException:
            kind = BaseException
            raise
        finally:
            if kind is not None:
                for p in self.pending:
                    p.cancel()
                concurrent.futures.wait(self.pending)
        return False


# --------------------------------------------------------------------------
# PNG
# --------------------------------------------------------------------------


class Indexed(NamedTuple):
    """An 8-bit palette image: ``index`` uint8 ``(rows, cols)`` into ``palette`` uint8 ``(n, 3)``
    sRGB colours, ``n <= 256``. Exact for an image of at most 256 colours (a colour map's, a
    legend's), at about a third of an RGB PNG's bytes; it decodes to ``palette[index]``."""

    index: np.ndarray
    palette: np.ndarray

    def rgb(self) -> np.ndarray:
        """The image as uint8 ``(rows, cols, 3)``."""
        return self.palette[self.index]


def write_png(
    path: str | os.PathLike,
    pixels: np.ndarray | Indexed,
    *,
    atomic: bool = True,
    compress_level: int = 6,
    grey: bool = False,
    runs: bool = False,
) -> None:
    """Write 8-bit grey/RGB/RGBA, 16-bit grey or palette pixels to a PNG.

    ``pixels`` is ``uint8 (rows, cols[, 3|4])``, ``uint16 (rows, cols)`` or an
    :class:`Indexed` image (a PNG of colour type 3, Pillow's mode ``"P"``).
    Values are written as they are: encode them before calling.
    ``compress_level`` is zlib's, 0 (stored) to 9. ``grey``: an 8-bit RGB
    image whose channels are equal everywhere is written as 8-bit grey
    (``"L"``): lossless, a third of the bytes to compress; it decodes (e.g.
    Pillow's ``convert("RGB")``) to the same RGB pixels. ``runs``: zlib's
    run-length strategy (``Z_RLE``), which looks for repeats of the previous
    byte only: on filtered renders and palette maps at level 1 it is faster
    than the default search and about as small (``benchmarks/bench_png.py``).
    """
    import zlib

    target = Path(path)
    ctx = atomic_path(target) if atomic else contextlib.nullcontext(target)
    if isinstance(pixels, Indexed):
        img = _palette_image(pixels)
        with ctx as tmp:  # without runs, Pillow's own strategy
            img.save(
                tmp,
                format="PNG",
                compress_level=compress_level,
                **({"compress_type": zlib.Z_RLE} if runs else {}),
            )
        return
    import imagecodecs

    # libpng through imagecodecs, each row Paeth-filtered: Pillow tries five filters on every row
    # and keeps the best, 1.7x the time for 1.4% fewer bytes on a rendered frame
    data = imagecodecs.png_encode(
        _png_pixels(pixels, grey),
        level=compress_level,
        strategy=zlib.Z_RLE if runs else None,
        filter=PNG_FILTER,
    )
    with ctx as tmp:
        Path(tmp).write_bytes(data)


#: The PNG row filter :func:`write_png` uses for grey and RGB images (PNG's filter type 4, Paeth):
#: the fewest bytes of the single filters on the sweep's renders (``imagecodecs.PNG.FILTER``).
PNG_FILTER = 128


def _png_pixels(pixels: np.ndarray, grey: bool) -> np.ndarray:
    """The pixels :func:`write_png` encodes: uint8 or uint16, grey RGB as one channel with ``grey``."""
    pixels = np.ascontiguousarray(pixels)
    if pixels.dtype not in (np.uint8, np.uint16):
        raise TypeError(f"write_png needs uint8 or uint16 pixels, got {pixels.dtype}")
    if pixels.ndim not in (2, 3) or (pixels.ndim == 3 and pixels.shape[-1] not in (3, 4)):
        raise ValueError(f"write_png needs (rows, cols[, 3|4]) pixels, got {pixels.shape}")
    if pixels.dtype == np.uint16 and pixels.ndim != 2:
        raise ValueError(f"16-bit pixels are written as grey only, got {pixels.shape}")
    if grey and pixels.dtype == np.uint8 and pixels.ndim == 3 and pixels.shape[-1] == 3 and is_grey(pixels):
        pixels = np.ascontiguousarray(pixels[..., 0])
    return pixels


def _palette_image(pixels: Indexed):
    """The Pillow image of a palette image (mode ``"P"``), which :func:`write_png` saves."""
    from PIL import Image

    index, palette = np.ascontiguousarray(pixels.index, np.uint8), np.asarray(pixels.palette, np.uint8)
    if index.ndim != 2 or palette.ndim != 2 or palette.shape[1] != 3 or not 1 <= len(palette) <= 256:
        raise ValueError(
            f"an Indexed image needs (rows, cols) indices and 1-256 RGB colours, "
            f"got {index.shape} and {palette.shape}"
        )
    img = Image.frombytes("P", (index.shape[1], index.shape[0]), index.tobytes())
    img.putpalette(palette.tobytes(), rawmode="RGB")
    return img


#: A PNG with more pixels than this on its longer side also gets a preview (:func:`preview_of`)
#: for the report's pages, which a 4096 x 4096 sweep's full images (126 of 8-20 MB) would stall.
PREVIEW_ABOVE_PX = 2048
#: The preview's longer side at most, in pixels: the full image box-filtered by a whole factor.
PREVIEW_PX = 1024


def write_figure(path: str | os.PathLike, fig, **savefig) -> None:
    """A matplotlib figure as a PNG at ``path``, atomically (:func:`atomic_path`, which makes the
    folder); ``savefig``: matplotlib's own options (``dpi``, ``facecolor``, ...)."""
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", **savefig)


def preview_of(rel: str) -> str:
    """Where the preview of the PNG ``rel`` lives: ``frames/az+0/truth.png`` ->
    ``frames/az+0/previews/truth.png`` (the writer's and the report's one convention)."""
    head, _, name = rel.replace("\\", "/").rpartition("/")
    return f"{head}/previews/{name}" if head else f"previews/{name}"


def write_png_with_preview(path: str | os.PathLike, pixels: np.ndarray | Indexed, **kw) -> bool:
    """:func:`write_png`, and, for an image larger than :data:`PREVIEW_ABOVE_PX`, its preview at
    :func:`preview_of` (every channel box-averaged over ``f x f`` pixels, ``f`` the smallest whole
    factor that brings it to :data:`PREVIEW_PX`; edges repeated to a multiple of ``f``). Returns
    whether a preview was written."""
    write_png(path, pixels, **kw)
    rows, cols = (pixels.index if isinstance(pixels, Indexed) else np.asarray(pixels)).shape[:2]
    if max(rows, cols) <= PREVIEW_ABOVE_PX:
        return False
    rgb = pixels.rgb() if isinstance(pixels, Indexed) else np.asarray(pixels)
    f = -(-max(rows, cols) // PREVIEW_PX)
    pad = [(0, -rows % f), (0, -cols % f)] + [(0, 0)] * (rgb.ndim - 2)
    block = np.pad(rgb, pad, mode="edge").astype(np.float32)
    block = block.reshape(block.shape[0] // f, f, block.shape[1] // f, f, *rgb.shape[2:]).mean(axis=(1, 3))
    small = np.clip(np.rint(block), 0, 255).astype(np.uint8)
    target = Path(path)
    write_png(target.parent / "previews" / target.name, small, **kw)
    return True


def unit_to_u8(values: np.ndarray) -> np.ndarray:
    """Quantise values in [0, 1] to 8 bits, rounding to nearest (as a GPU upload does); NaN (a pixel
    that sees no surface) is 0."""
    # the float32 product, then rounded and clipped in place: one temporary, not four
    out = np.multiply(values, np.float32(255.0), dtype=np.float32)
    np.nan_to_num(out, copy=False, nan=0.0)
    np.rint(out, out=out)
    np.clip(out, 0, 255, out=out)
    return out.astype(np.uint8)


# --------------------------------------------------------------------------
# JSON
# --------------------------------------------------------------------------


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
    """The first key path (``frames[0].flip_mean``) of ``data`` that holds a NaN or infinity."""
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


def first_line(exc: BaseException) -> str:
    """The first line of an exception's message, for one-line errors."""
    text = str(exc).strip() or type(exc).__name__
    return text.splitlines()[0]
