"""Choosing the Mitsuba 3 / Dr.Jit variant and checking that it can run.

hzval uses the ``*_ad_rgb`` variants: ``cuda_ad_rgb`` where a CUDA device is
present, ``llvm_ad_rgb`` (CPU) elsewhere. ``HZVAL_VARIANT`` overrides the
choice. Code elsewhere asks :func:`variant` and uses ``mi.Float`` and friends,
so that it runs unchanged on either backend.

Dr.Jit's LLVM backend crashes on Debian 12's default LLVM 15 at the first
kernel that uses ``min``/``max`` (``LLVM ERROR: Cannot select: ... fmaximum``,
docs/ARCHITECTURE.md, "Known pitfalls"): we refuse such an LLVM with a message that says what to
do, rather than let the process abort.

Host-side work that NumPy, colour-science, OpenEXR and Pillow do without
the GIL (colour conversions, image files) runs on :func:`host_pool`, a
thread per core this process may use (:func:`host_cores`).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import glob
import importlib
import os
import re
from concurrent.futures import ThreadPoolExecutor

import hzval
from hzval.core.errors import EnvironmentProblem, InputError

__all__ = [
    "VARIANTS",
    "dr",
    "mi",
    "MIN_LLVM_MAJOR",
    "request",
    "prefer_working_llvm",
    "check_llvm",
    "variant",
    "sync",
    "release_memory",
    "retain_freed_memory",
    "hand_back_freed_memory",
    "versions",
    "host_cores",
    "host_pool",
]


class _Module:
    """A module imported at the first use of one of its names, not where it is named.

    ``from hzval.core.backend import dr, mi`` at a module's top stands for ``import drjit as dr`` and
    ``import mitsuba as mi``: importing Dr.Jit initialises its backends (and reads
    ``DRJIT_LIBLLVM_PATH``), which the command line must do only after it has chosen the LLVM
    library and checked its input (:func:`prefer_working_llvm`; a bad file is one line, with no
    backend started).
    """

    def __init__(self, name: str, fixed: bool):
        self._name, self._fixed = name, fixed

    def __getattr__(self, attr: str):
        value = getattr(importlib.import_module(self._name), attr)
        if self._fixed:
            # Dr.Jit's names never change: later uses find it here, without this call. Mitsuba's
            # (mi.Float, ...) follow the variant set, so they are looked up every time
            setattr(self, attr, value)
        return value

    def __repr__(self) -> str:
        return f"<module {self._name!r}, imported at first use>"


dr = _Module("drjit", fixed=True)
mi = _Module("mitsuba", fixed=False)

#: The oldest LLVM major version known to work with Dr.Jit's LLVM backend here.
MIN_LLVM_MAJOR = 16

_FIX = (
    "install Debian's libllvm19 (apt-get install libllvm19) or point "
    "DRJIT_LIBLLVM_PATH at a libLLVM.so of version 16 or newer"
)

_chosen: str | None = None
_requested: str | None = None
#: The Mitsuba variants hzval renders with: vectorised (Dr.Jit's JIT) and RGB, on the CPU (LLVM) or
#: an NVIDIA GPU (CUDA); its kernels are written for no other.
VARIANTS = ("llvm_ad_rgb", "cuda_ad_rgb")


def request(name: str | None) -> None:
    """Name the variant :func:`variant` is to select when it is first called, without starting Dr.Jit.

    A command that fails on its input first then never starts a backend.

    Parameters
    ----------
    name : str or None
        A Mitsuba variant (the command line's ``--variant``), or ``None`` for the default choice.
    """
    global _requested
    _requested = name


def prefer_working_llvm() -> None:
    """Point Dr.Jit at the newest installed libLLVM >= 16, unless the user chose one.

    Dr.Jit loads the first libLLVM it finds, which on Debian 12 may be the
    broken LLVM 15 even when ``libllvm19`` is installed beside it. Must run
    before Dr.Jit initialises its LLVM backend; ``hzval/__init__`` calls it.
    """
    if os.environ.get("DRJIT_LIBLLVM_PATH"):
        return
    found = []
    for path in glob.glob("/usr/lib/*-linux-gnu/libLLVM*.so*") + glob.glob(
        "/usr/lib/llvm-*/lib/libLLVM*.so*"
    ):
        m = re.search(r"libLLVM[-.](?:so\.)?(\d+)", os.path.basename(path))
        if m and int(m.group(1)) >= MIN_LLVM_MAJOR:
            found.append((int(m.group(1)), path))
    if found:
        os.environ["DRJIT_LIBLLVM_PATH"] = max(found)[1]


def check_llvm() -> tuple[int, int, int]:
    """Return the LLVM version that Dr.Jit loaded; raise if it is missing or broken."""
    # Dr.Jit loads only once the LLVM is chosen (prefer_working_llvm)
    import drjit as dr

    version = tuple(dr.detail.llvm_version())
    if version[0] < 0 or not dr.has_backend(dr.JitBackend.LLVM):
        raise EnvironmentProblem(f"Dr.Jit found no usable LLVM library: {_FIX}")
    if version[0] < MIN_LLVM_MAJOR:
        raise EnvironmentProblem(
            f"Dr.Jit loaded LLVM {'.'.join(map(str, version))}, whose code generator "
            f"crashes on Dr.Jit's min/max kernels: {_FIX}"
        )
    return version  # type: ignore[return-value]


def variant(requested: str | None = None) -> str:
    """Select (once a process) and return the Mitsuba variant hzval renders with.

    Parameters
    ----------
    requested : str, optional
        A variant to use; else :func:`request`'s, else ``$HZVAL_VARIANT``, else CUDA where Dr.Jit sees
        a device and LLVM otherwise. The LLVM library is checked first.

    Returns
    -------
    str
        The variant's name (``llvm_ad_rgb``, ``cuda_ad_rgb``, ...).

    Raises
    ------
    hzval.core.errors.EnvironmentProblem
        When the variant cannot be set up on this machine, with what to do.
    """
    global _chosen
    # Dr.Jit loads only once the LLVM is chosen (prefer_working_llvm)
    import drjit as dr
    import mitsuba as mi

    name = requested or _requested or os.environ.get("HZVAL_VARIANT") or None
    if name is None and _chosen is not None:
        return _chosen
    what = "--variant" if (requested or _requested) else "$HZVAL_VARIANT"
    if name is None:
        name = "cuda_ad_rgb" if dr.has_backend(dr.JitBackend.CUDA) else "llvm_ad_rgb"
    if name not in VARIANTS:  # scalar, mono and spectral variants are Mitsuba's, not hzval's
        raise InputError(what, f"{name!r} is not a variant hzval renders with: {' or '.join(VARIANTS)}")
    if name not in mi.variants():
        raise EnvironmentProblem(
            f"Mitsuba variant {name!r} is not available; this build has {', '.join(mi.variants())}"
        )
    if name.startswith("cuda") and not dr.has_backend(dr.JitBackend.CUDA):
        raise InputError(
            what, f"{name} needs an NVIDIA GPU and its driver, and Dr.Jit sees none here: use llvm_ad_rgb"
        )
    if name.startswith("llvm"):
        check_llvm()
    mi.set_variant(name)
    _chosen = name
    return name


def sync() -> None:
    """Wait for queued kernels; Dr.Jit evaluates asynchronously, so time after this."""
    # Dr.Jit loads only once the LLVM is chosen (prefer_working_llvm)
    import drjit as dr

    dr.sync_thread()


def release_memory() -> None:
    """Hand Dr.Jit's cache of freed buffers back to the system (``dr.flush_malloc_cache``).

    A sweep's set-up and each frame's renders leave gigabytes of them at 4096 x 4096, which would otherwise
    stay resident beside the NumPy images of the comparison (about 1.5 GB of a 4096 sweep's peak).
    """
    # Dr.Jit loads only once the LLVM is chosen (prefer_working_llvm)
    import drjit as dr

    dr.sync_thread()
    dr.flush_malloc_cache()


#: glibc's ``mallopt`` parameters (``<malloc.h>``): the heap's top kept up to this many bytes, the
#: size from which a chunk is mapped on its own, and how many chunks may be.
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD, _M_MMAP_MAX = -1, -3, -4
#: What :func:`hand_back_freed_memory` restores: glibc's mapped-chunk limit, and its threshold and trim
#: size as its own adjustment leaves them after large arrays have been freed (32 MB, twice that).
_GLIBC_MMAP_MAX, _GLIBC_MMAP_THRESHOLD_MAX = 65536, 32 * 2**20

_retaining = False


def _mallopt():
    """Glibc's ``mallopt`` (and ``malloc_trim``) through ctypes, or ``None`` off glibc."""
    try:
        if "glibc" not in (os.confstr("CS_GNU_LIBC_VERSION") or ""):
            return None
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        return libc.mallopt, libc.malloc_trim
    except (AttributeError, OSError, ValueError):
        return None


def retain_freed_memory() -> bool:
    """Keep memory this process frees for its next allocations, rather than hand it back to the system.

    This uses glibc's ``mallopt`` (no chunk mapped on its own, the heap's top not trimmed below 2 GB), until
    :func:`hand_back_freed_memory`. Returns ``True`` where that took effect (glibc), ``False`` elsewhere.

    Why: glibc maps every allocation above 32 MB (a 2048 x 2048 RGB image in float32 is 48 MB) on
    its own and unmaps it when freed, so the next one is pages new to the process, which the kernel
    zeroes (and a virtual machine's host may have to provide) at 1-3 s of system time per GB here.
    A sweep makes and drops such images in every frame; keeping them saves about a tenth of a large
    sweep for more peak memory (docs/internals.md, "Measurements the code rests on").
    :func:`hzval.pipeline.sweep.run` asks for it where its
    estimated peak is a small part of what is available (:data:`hzval.core.budget.RETAIN_BELOW_SHARE`).
    """
    global _retaining
    fns = _mallopt()
    if fns is None:
        return False
    mallopt, _ = fns
    _retaining = bool(mallopt(_M_MMAP_MAX, 0)) and bool(mallopt(_M_TRIM_THRESHOLD, 2**31 - 1))
    return _retaining


def hand_back_freed_memory() -> None:
    """Undo :func:`retain_freed_memory` and hand the memory it kept back to the system.

    The undo applies if it took effect; the memory is handed back with ``malloc_trim``, so that what runs next
    in this process, another sweep's peak included, starts from what it uses itself.
    """
    global _retaining
    if not _retaining:
        return
    mallopt, malloc_trim = _mallopt()
    mallopt(_M_MMAP_MAX, _GLIBC_MMAP_MAX)
    mallopt(_M_MMAP_THRESHOLD, _GLIBC_MMAP_THRESHOLD_MAX)
    mallopt(_M_TRIM_THRESHOLD, 2 * _GLIBC_MMAP_THRESHOLD_MAX)
    malloc_trim(0)
    _retaining = False


def versions() -> dict[str, str]:
    """Versions of hzval, Mitsuba, Dr.Jit and the LLVM in use, for reports."""
    # Dr.Jit loads only once the LLVM is chosen (prefer_working_llvm)
    import drjit as dr
    import mitsuba as mi

    out = {"hzval": hzval.__version__, "mitsuba": mi.__version__, "drjit": dr.__version__}
    llvm = tuple(dr.detail.llvm_version())
    if llvm[0] >= 0:
        out["llvm"] = ".".join(map(str, llvm))
    if _chosen:
        out["variant"] = _chosen
    return out


def host_cores() -> int:
    """CPU cores this process may run on (its affinity where the OS says, else the count)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # macOS, Windows
        return os.cpu_count() or 1


_pools: dict = {}


def host_pool(workers: int | None = None):
    """Return the process's thread pool for host-side work (NumPy and colour-science release the GIL).

    Parameters
    ----------
    workers : int, optional
        Threads (default :func:`host_cores`).

    Returns
    -------
    concurrent.futures.ThreadPoolExecutor
        Made once per process and size, then reused.
    """
    n = max(1, int(workers or host_cores()))
    if n not in _pools:
        _pools[n] = ThreadPoolExecutor(max_workers=n, thread_name_prefix="hzval-host")
    return _pools[n]
