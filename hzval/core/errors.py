"""Errors that the command line turns into one-line messages and exit codes."""

from __future__ import annotations

import os

__all__ = [
    "first_line",
    "EXIT_OK",
    "EXIT_CHECK_FAILED",
    "EXIT_BAD_INPUT",
    "EXIT_ENVIRONMENT",
    "HzvalError",
    "InputError",
    "EnvironmentProblem",
    "Interrupted",
    "interruption",
]

#: Exit status for a finished job or a passed check.
EXIT_OK = 0
#: Exit status for a regression check that failed.
EXIT_CHECK_FAILED = 1
#: Exit status for bad input or usage.
EXIT_BAD_INPUT = 2
#: Exit status for a machine that cannot run hzval (e.g. a broken LLVM).
EXIT_ENVIRONMENT = 3


class HzvalError(Exception):
    """Base class of the errors hzval reports without a traceback."""

    exit_code = EXIT_BAD_INPUT


class InputError(HzvalError):
    """Bad input: a file that cannot be read or a parameter out of range.

    The message names the offending file (or parameter) first, so that the
    command line can print it as a single line: ``hzval: <what>: <problem>``.
    """

    def __init__(self, what: str | os.PathLike, problem: str):
        self.what = os.fspath(what)
        self.problem = problem
        super().__init__(f"{self.what}: {problem}")


class EnvironmentProblem(HzvalError):
    """The machine cannot run hzval as it is; the message says what to do."""

    exit_code = EXIT_ENVIRONMENT


class Interrupted(KeyboardInterrupt):
    """SIGTERM (or another stop signal) as an interrupt.

    The run unwinds as on Ctrl-C; the command line exits ``128 + signum`` (:mod:`hzval.core.interrupts`).
    """

    def __init__(self, signum: int):
        self.signum = int(signum)
        super().__init__(f"signal {self.signum}")


def interruption(exc: BaseException) -> KeyboardInterrupt | None:
    """Return the interrupt (Ctrl-C, or SIGTERM as :class:`Interrupted`) behind an error, or ``None``.

    Dr.Jit raises what a traced or frozen function raised (a signal's interrupt among them: Python
    runs the handler wherever the main thread is) as a ``RuntimeError`` caused by it, so a stop
    that lands in a symbolic loop or a recording arrives as that error. The walk follows
    ``__cause__``, else ``__context__`` even where it is suppressed: an error re-raised ``from None``
    while an interrupt unwound (FLIP's refusal, :func:`hzval.metrics.compare.flip_error`) hides it
    there; a chain that loops ends the walk.

    Parameters
    ----------
    exc : BaseException
        The error.

    Returns
    -------
    KeyboardInterrupt or None
        ``exc`` itself if it is an interrupt, else the first interrupt in its chain.

    Examples
    --------
    >>> try:
    ...     try:
    ...         raise Interrupted(15)
    ...     except Interrupted as stop:
    ...         raise RuntimeError("dr.while_loop(): encountered an exception") from stop
    ... except RuntimeError as exc:
    ...     interruption(exc).signum
    15
    >>> interruption(ValueError("no")) is None
    True
    """
    seen: set[int] = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


def first_line(exc: BaseException) -> str:
    """Return the first line of an exception's message, for one-line errors."""
    text = str(exc).strip() or type(exc).__name__
    return text.splitlines()[0]
