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


def _loop_that_is_stopped(signum):
    """A Dr.Jit symbolic loop whose body is interrupted, as a signal handler raising in it does."""
    import drjit as dr
    import mitsuba as mi

    def body(i):
        raise errors.Interrupted(signum)

    i = dr.arange(mi.UInt32, 4)
    return dr.while_loop((i,), lambda i: i < 2, body)


def test_dr_jit_passes_an_interrupt_on_as_the_cause_of_its_own_error(variant):
    with pytest.raises(RuntimeError) as caught:
        _loop_that_is_stopped(signal.SIGTERM)
    assert errors.interruption(caught.value).signum == signal.SIGTERM


def test_an_interrupt_inside_dr_jit_tracing_unwinds_as_itself(variant):
    with pytest.raises(errors.Interrupted) as caught, interrupts.unwrapped():
        _loop_that_is_stopped(signal.SIGTERM)
    assert caught.value.signum == signal.SIGTERM


def test_other_errors_pass_through_unwrapped_as_they_are():
    with pytest.raises(ValueError, match="not a stop"), interrupts.unwrapped():
        raise ValueError("not a stop")


def test_an_errors_chain_that_loops_has_no_interrupt_and_ends():
    first, second = RuntimeError("a"), ValueError("b")
    first.__cause__, second.__context__ = second, first
    assert errors.interruption(first) is None
    second.__context__ = KeyboardInterrupt()  # found behind a suppressed context too
    second.__suppress_context__ = True
    assert isinstance(errors.interruption(first), KeyboardInterrupt)
