"""hzval.core.interrupts: held signals wait for a run's end; inside a loop of runs they stop the loop."""

from __future__ import annotations

import os
import signal

import pytest

from hzval.core import errors, interrupts


@pytest.fixture(autouse=True)
def python_sigint():
    """Python's own SIGINT handler for each test: a process started in the background by a shell
    without job control inherits SIGINT ignored, and Python then leaves it ignored."""
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)


def _held_signal():
    with interrupts.held() as hold:
        hold.start()
        os.kill(os.getpid(), signal.SIGINT)  # recorded, not raised: the run's output is complete
        assert hold.caught == [signal.SIGINT]


def test_a_held_signal_is_dropped_with_one_line_after_a_single_run(capsys):
    _held_signal()
    assert "SIGINT came after the output was complete" in capsys.readouterr().err


def test_a_held_signal_stops_a_loop_of_runs_when_its_run_has_ended():
    ran = []
    with pytest.raises(errors.Interrupted) as exc, interrupts.cases():
        for case in range(3):
            _held_signal()
            ran.append(case)
    assert ran == [] and exc.value.signum == signal.SIGINT
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    _held_signal()  # the loop is over: a single run keeps its output again


def test_a_signal_before_the_hold_raises_at_once():
    with pytest.raises(KeyboardInterrupt), interrupts.held():
        os.kill(os.getpid(), signal.SIGINT)
