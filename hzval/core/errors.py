"""Errors that the command line turns into one-line messages and exit codes."""

from __future__ import annotations

import os

__all__ = [
    "EXIT_OK",
    "EXIT_CHECK_FAILED",
    "EXIT_BAD_INPUT",
    "EXIT_ENVIRONMENT",
    "HzvalError",
    "InputError",
    "EnvironmentProblem",
    "Interrupted",
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
    """SIGTERM (or another stop signal) as an interrupt: the run unwinds as on Ctrl-C; the command
    line exits ``128 + signum`` (:mod:`hzval.core.interrupts`)."""

    def __init__(self, signum: int):
        self.signum = int(signum)
        super().__init__(f"signal {self.signum}")
