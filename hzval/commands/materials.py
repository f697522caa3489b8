"""``hzval materials``: the built-in materials, a line each (:mod:`hzval.materials`)."""

from __future__ import annotations

from hzval import materials

__all__ = ["table"]


def table() -> str:
    """Every built-in material's name, default depth and boundary, and what it is, a line each."""
    lines = [f"{'name':13s} {'depth':>6s}  {'boundary':8s}  what it is"]
    for name in materials.names():
        m = materials.get(name)
        lines.append(f"{name:13s} {m.depth:6g}  {m.boundary:8s}  {m.label}: {m.summary}")
    return "\n".join(lines)
