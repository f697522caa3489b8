"""``hzval check``: the shipped scenes against ``reference/``, the CI regression.

See :mod:`hzval.commands.check`.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from hzval.cli import flags
from hzval.core import errors


def add_parser(sub) -> None:
    """Add the ``check`` command's parser to ``sub``."""
    p = sub.add_parser(
        "check",
        help="render the shipped scenes and compare them with reference/ (CI)",
        description="Render every scene of scenes/ at its small [check] size and compare the "
        "truth (statistically) and the approximation (tightly) with the references. "
        "Exit 0 when all pass, 1 when any fails; a failure writes an HTML report.",
    )
    p.add_argument("--references", type=Path, default=None, help="reference folder (default: reference/)")
    p.add_argument("--scenes", type=Path, default=None, help="scene folder (default: scenes/)")
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        help="write the HTML report here (default: reports/check, and only on failure)",
    )
    p.add_argument("--report", dest="out", type=Path, default=argparse.SUPPRESS, help=argparse.SUPPRESS)
    p.add_argument(
        "--update",
        action="store_true",
        help="rewrite the references that are missing or failing, and say which",
    )
    p.add_argument(
        "--seed", type=int, default=None, help="render the truth with this seed instead of the scene's"
    )
    p.add_argument(
        "--only",
        dest="only",
        action="append",
        default=None,
        metavar="NAME",
        help="check only the scene of this name (repeatable)",
    )
    p.add_argument("--scene", dest="only", action="append", help=argparse.SUPPRESS)
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=run)


def run(args) -> int:
    """Run ``hzval check`` with the parsed ``args``; return its exit code."""
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.commands import check

    result = check.run(
        scenes_dir=args.scenes,
        references=args.references,
        update=args.update,
        seed=args.seed,
        progress=not args.quiet,
        only=args.only,
    )
    print(check.summary(result))
    for path in result.updated:
        print(f"updated {path}")
    failed = not result.passed and not args.update
    if failed or args.out:
        out = args.out or Path("reports") / "check"
        command = flags.command_line(args)
        index = check.write_report(result, out, command=command, force=args.force)
        print(f"report: {index}")
    return errors.EXIT_CHECK_FAILED if failed else errors.EXIT_OK
