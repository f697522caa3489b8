"""Helpers that several test modules share (tests import nothing from one another's modules)."""

from __future__ import annotations


def interrupt_material(monkeypatch, name: str) -> None:
    """Make a suite stop with Ctrl-C when it reaches material ``name`` (every other one sweeps)."""
    from hzval.commands import suite

    real = suite.sweep_material

    def interrupt(task):
        if task.entry.name == name:
            raise KeyboardInterrupt
        return real(task)

    monkeypatch.setattr(suite, "sweep_material", interrupt)
