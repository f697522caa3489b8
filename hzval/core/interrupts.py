"""Signals: SIGTERM unwinds like Ctrl-C, and a run's last step is not cut short.

:func:`terminate_as_interrupt` makes SIGTERM (``kill``, a batch system's
stop) raise :class:`hzval.core.errors.Interrupted`, a ``KeyboardInterrupt``, so that
a run stopped either way removes its staging folder, its lock, and any folder
it created (:func:`hzval.io.staging.output_folder`); by default SIGTERM ends the
process at once and leaves them behind.

:func:`held` holds SIGINT and SIGTERM from the moment a run's output is complete
(the last signal check is the moment it is entered: a signal before it raised
there and then) until the run has left its folder: the swap of the new report
into place (:meth:`hzval.io.staging.Staging.swap`) and the lock's removal are not
interrupted, and a signal that comes during them does not make a finished run
exit 130 over a report already in place. Python runs signal handlers in the
main thread only; elsewhere (a Dask worker's thread) nothing is held.

:func:`unwrapped` raises an interrupt that Dr.Jit passed on as the cause of its own error as
the interrupt it is.

:func:`command` is the extent of one command: a run whose output is in place holds its signals to
there, so a Ctrl-C while it prints its table neither cuts it short nor makes it exit 130.

:func:`cases` marks a loop of runs (``models``' cases, ``views``' sweeps): there a
signal held during one run's swap is raised as it ends, so the loop stops between
cases instead of going on with a Ctrl-C swallowed.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from typing import Iterator

from hzval.core import errors

__all__ = ["HELD", "terminate_as_interrupt", "unwrapped", "held", "cases", "command"]

#: The signals :func:`held` holds.
HELD = (signal.SIGINT, signal.SIGTERM)

#: How many :func:`cases` loops enclose the running code.
_loops = 0


def _raise_interrupted(signum, frame) -> None:
    raise errors.Interrupted(signum)


@contextlib.contextmanager
def terminate_as_interrupt() -> Iterator[None]:
    """Make SIGTERM raise :class:`hzval.core.errors.Interrupted` within the block.

    This holds in the main thread only; the previous handler is put back at its end, for a caller that runs
    commands in its own process.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_interrupted)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@contextlib.contextmanager
def unwrapped() -> Iterator[None]:
    """Raise an error caused by an interrupt as that interrupt, within the block.

    See :func:`hzval.core.errors.interruption`. A Ctrl-C or SIGTERM that lands while Dr.Jit traces a loop or
    records a frozen function then unwinds as one, through every handler that tells an interrupt from an error
    (a run's folder, a suite's overview), and exits 130 or 143, not 1 with a traceback.
    """
    try:
        yield
    except Exception as exc:
        stop = errors.interruption(exc)
        if stop is None:
            raise
        raise stop from None


class _Hold:
    """What :func:`held` yields: :meth:`start` begins holding; ``caught`` the signals held since."""

    def __init__(self) -> None:
        self.caught: list[int] = []
        self._saved: dict = {}

    def start(self) -> None:
        """From now until :func:`held` ends, SIGINT and SIGTERM are recorded, not raised."""
        if self._saved or threading.current_thread() is not threading.main_thread():
            return
        for s in HELD:
            self._saved[s] = signal.signal(s, lambda signum, frame: self.caught.append(signum))

    def restore(self) -> None:
        for s, handler in self._saved.items():
            signal.signal(s, handler)
        self._saved.clear()

    def take(self, other: "_Hold") -> None:
        """Go on holding what ``other`` holds, to this hold's end (a command's, :func:`command`)."""
        if self._saved:  # already holding: ``other`` replaced this hold's own recorder; put it back
            other.restore()
            self.caught += other.caught
        else:
            self._saved, other._saved = other._saved, {}
            self.caught = other.caught  # its recorder appends here


#: The hold of the command that runs now (:func:`command`), to which a finished run hands its own.
_command_hold: _Hold | None = None


def _dropped(caught: list[int]) -> None:
    print(
        f"hzval: {signal.Signals(caught[0]).name} came after the output was complete; it is kept",
        file=sys.stderr,
    )


@contextlib.contextmanager
def command() -> Iterator[None]:
    """Yield the extent of one command (``hzval.cli.main``).

    A run whose output is in place (a :func:`held` region that started holding) goes on holding SIGINT and
    SIGTERM to here, so that the command prints its table and exits with its own status; a signal held is
    dropped with one line.
    """
    global _command_hold
    outer, _command_hold = _command_hold, _Hold()
    try:
        yield
    finally:
        hold, _command_hold = _command_hold, outer
        hold.restore()
        if hold.caught:
            _dropped(hold.caught)


@contextlib.contextmanager
def held() -> Iterator[_Hold]:
    """Yield a region whose signals, once :meth:`_Hold.start` is called, wait for its end.

    They are then dropped with one line on stderr: the run they would have stopped had finished.
    """
    hold = _Hold()
    try:
        yield hold
    finally:
        if hold._saved and not _loops and _command_hold is not None:
            _command_hold.take(hold)  # the output is in place: hold on until the command ends
        else:
            hold.restore()
            if hold.caught and _loops:  # inside a loop of runs: this run is whole, the loop stops here
                raise errors.Interrupted(hold.caught[0])
            if hold.caught:
                _dropped(hold.caught)


@contextlib.contextmanager
def cases() -> Iterator[None]:
    """Yield a loop of runs, each with its own :func:`held` swap.

    A signal one of them held is raised (:class:`hzval.core.errors.Interrupted`) when that run has finished,
    so the loop stops between runs; the caller's own staging then leaves the earlier output as it was.
    """
    global _loops
    _loops += 1
    try:
        yield
    finally:
        _loops -= 1
