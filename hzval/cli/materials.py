"""``hzval materials``: the built-in materials, a line each (:mod:`hzval.materials`)."""

from __future__ import annotations

from hzval.core import errors


def add_parser(sub) -> None:
    p = sub.add_parser(
        "materials",
        help="list the built-in materials",
        description='List the built-in materials (--material NAME, [material] height = "NAME", '
        "hzval suite) with their default depth and boundary.",
    )
    p.set_defaults(run=run)


def run(args) -> int:
    from hzval import materials

    print(f"{'name':13s} {'depth':>6s}  {'boundary':8s}  what it is")
    for name in materials.names():
        m = materials.get(name)
        print(f"{name:13s} {m.depth:6g}  {m.boundary:8s}  {m.label}: {m.summary}")
    return errors.EXIT_OK
