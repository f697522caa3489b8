"""Memory: what is available, and the one-line refusal of a run that would not fit.

Every command estimates its peak before it allocates, from :mod:`hzval.core.budget`'s figures (the bake:
:func:`hzval.bake.maps.estimate_bytes`; a sweep: :mod:`hzval.truth.memory`; a fit:
:func:`hzval.techniques.fitted.training.estimate_bytes`) and hands the estimate to :func:`refuse_over`,
which owns the wording users see:
``WHAT: TASK needs about X GiB of memory (estimated); Y GiB are available (ADVICE)``.
"""

from __future__ import annotations

import os

from hzval.core.errors import InputError

__all__ = ["GIB", "available_bytes", "refuse_over"]

#: Bytes in a GiB, the unit every refusal is written in.
GIB = 2**30


def available_bytes() -> int:
    """Memory available to this process now, in bytes.

    Linux's ``MemAvailable`` (free memory plus what the page cache can give back); where
    ``/proc/meminfo`` cannot be read, the machine's physical memory.

    Returns
    -------
    int
    """
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")


def refuse_over(what, need: float, task: str, advice: str, have: float | None = None) -> int:
    """Refuse in one line a run whose estimated peak ``need`` exceeds the memory available.

    Parameters
    ----------
    what : str or path-like
        The flag or file the error names first (``--size``, the height map).
    need : float
        The run's estimated peak, in bytes.
    task : str
        What would run, as the sentence's subject (``a 4096x4096 bake``).
    advice : str
        What to change, in the parentheses (``fewer --spp or a smaller map``).
    have : float, optional
        The bytes available (default :func:`available_bytes`, read now).

    Returns
    -------
    int
        ``need``, when it fits.

    Raises
    ------
    hzval.core.errors.InputError
        When it does not.

    Examples
    --------
    >>> refuse_over("--size", 3 * GIB, "a bake", "a smaller map", have=2 * GIB)
    Traceback (most recent call last):
    ...
    hzval.core.errors.InputError: --size: a bake needs about 3.0 GiB of memory (estimated); 2.0 GiB are available (a smaller map)
    """  # noqa: E501
    have = available_bytes() if have is None else have
    if need > have:
        raise InputError(
            what,
            f"{task} needs about {need / GIB:.1f} GiB of memory (estimated); {have / GIB:.1f} GiB are "
            f"available ({advice})",
        )
    return int(need)
