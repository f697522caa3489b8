"""``hzval materials``'s flags (:mod:`hzval.commands.materials`)."""

from __future__ import annotations

from hzval.commands import materials as materials_command
from hzval.core import errors


def add_parser(sub) -> None:
    """Add the ``materials`` command's parser to ``sub``."""
    p = sub.add_parser(
        "materials",
        help="list the built-in materials",
        description='List the built-in materials (--material NAME, [material] height = "NAME", '
        "hzval suite) with their default depth and boundary.",
    )
    p.set_defaults(run=run)


def run(args) -> int:
    """Print the built-in materials' table; return the exit code."""
    print(materials_command.table())
    return errors.EXIT_OK
