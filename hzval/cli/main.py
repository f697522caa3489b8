"""The ``hzval`` command: its parser, built from one module per command, and :func:`main`.

Each command is a module of this package with ``add_parser(sub)``, which declares its flags
(the shared groups are :mod:`hzval.cli.flags`), and ``run(args)``, which builds the dataclasses
its stage takes (a scene: :func:`hzval.cli.scenes.scene_from_args`, the one way) and calls it.
:data:`COMMANDS` lists them in the order ``hzval --help`` shows; adding a command is a module
and a line there.

Exit status (docs/ARCHITECTURE.md): 0 done, 1 check failed, 2 bad input or usage,
3 a machine that cannot run hzval (e.g. a broken LLVM). Errors that the user
can act on are one line on stderr, ``hzval: error: <what>: <problem>``.
"""

from __future__ import annotations

import argparse
import difflib
import signal
import sys

import hzval
from hzval.cli import (
    bake,
    check,
    export_scene,
    export_textures,
    fit,
    materials,
    models,
    score,
    suite,
    sweep,
    tradeoff,
    views,
)
from hzval.core import backend, errors, interrupts
from hzval.io import staging

__all__ = ["COMMANDS", "build_parser", "typed_flags", "main"]

#: The commands, in the order of ``hzval --help``.
COMMANDS = (
    bake,
    sweep,
    check,
    tradeoff,
    views,
    models,
    export_scene,
    export_textures,
    score,
    suite,
    materials,
    fit,
)


def typed_flags(parser: argparse.ArgumentParser, argv: list[str]) -> dict[str, str]:
    """Return the spelling in ``argv`` of each flag of ``parser`` that ``argv`` uses under another name.

    The result is ``{canonical flag: the spelling in argv}``; another name is a hidden alias such as ``--k``
    for ``--horizon-k``, so that errors name what was typed.
    """
    canonical: dict[str, str] = {}
    for a in parser._actions:
        if a.option_strings and a.help != argparse.SUPPRESS:
            canonical.setdefault(a.dest, a.option_strings[-1])
    out = {}
    for a in parser._actions:
        for opt in a.option_strings:
            if (
                any(t == opt or t.startswith(opt + "=") for t in argv)
                and a.dest in canonical
                and opt != canonical[a.dest]
            ):
                out[canonical[a.dest]] = opt
    return out


def _common() -> argparse.ArgumentParser:
    """Return the flags every command takes, before or after its name (argparse ``parents=``)."""
    common = _Parser(add_help=False)
    common.add_argument(
        "--variant",
        default=argparse.SUPPRESS,
        help="Mitsuba variant (default: cuda_ad_rgb with a GPU, else llvm_ad_rgb; or $HZVAL_VARIANT)",
    )
    return common


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line naming the flag as typed, and where to read more.

    Argparse's usage block is left out (it buried the error under 35 lines).
    """

    def error(self, message: str):
        self.exit(
            errors.EXIT_BAD_INPUT,
            f"hzval: error: {message}{self._nearest(message)}; see '{self.prog} --help'\n",
        )

    def _nearest(self, message: str) -> str:
        """``; did you mean --elevation?`` for an unknown flag near a known one of any command."""
        if not message.startswith("unrecognized arguments:"):
            return ""
        known = {o for a in self._actions for o in a.option_strings}
        for a in self._actions:
            if isinstance(a, argparse._SubParsersAction):
                known |= {o for p in a.choices.values() for b in p._actions for o in b.option_strings}
        for word in message.split(":", 1)[1].split():
            if word.startswith("--"):
                near = difflib.get_close_matches(word.split("=")[0], sorted(known), n=1, cutoff=0.75)
                if near:
                    return f" (did you mean {near[0]}?)"
        return ""


class _Subcommands(argparse._SubParsersAction):
    """Every command's parser gets the common flags (:func:`_common`)."""

    def add_parser(self, name, **kwargs):
        p = super().add_parser(name, parents=[_common()], **kwargs)
        p.set_defaults(parser=p)
        return p


def build_parser() -> argparse.ArgumentParser:
    """Return the ``hzval`` parser with every command's flags.

    It has :func:`_common`'s flags, then each of :data:`COMMANDS`' own, and ``--force`` for every command that
    writes a folder.
    """
    parser = _Parser(
        prog="hzval",
        parents=[_common()],
        description="Validate horizon mapping and the self-shadowing techniques it competes with "
        "against ray-traced ground truth.",
    )
    parser.add_argument("--version", action="version", version=f"hzval {hzval.__version__}")
    parser.register("action", "parsers", _Subcommands)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for command in COMMANDS:
        command.add_parser(sub)
    for p in sub.choices.values():  # every command that writes a folder (hzval.io.staging.output_folder)
        if "--out" in p._option_string_actions or "--report" in p._option_string_actions:
            p.add_argument(
                "--force",
                action="store_true",
                help="write into an --out that holds files hzval did not write (they are kept)",
            )
    return parser


def _join_negative_values(argv: list[str]) -> list[str]:
    """``--azimuths -60:60:15`` as ``--azimuths=-60:60:15``.

    argparse takes a value that starts with ``-`` for an option unless it
    looks like a plain negative number, and the sweep's own default,
    ``-60:60:15``, does not.
    """
    out, it = [], iter(argv)
    for a in it:
        if a in ("--azimuths", "--elevation", "--azimuth"):
            nxt = next(it, None)
            out.append(a if nxt is None else f"{a}={nxt}")
        else:
            out.append(a)
    return out


def main(argv: list[str] | None = None) -> int:
    """Run the command ``argv`` (default ``sys.argv[1:]``); the exit status (module docstring)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    backend.prefer_working_llvm()  # before the parser imports the techniques, and so Dr.Jit
    args = build_parser().parse_args(_join_negative_values(argv))
    args.argv = argv
    args.typed = typed_flags(args.parser, argv)
    args.variant = getattr(args, "variant", None)
    # the LLVM is chosen above; the variant when the first renderer asks for it (hzval.core.backend.variant)
    backend.request(args.variant)
    try:
        # SIGTERM unwinds as Ctrl-C does, nothing left behind, even where it lands in Dr.Jit's tracing
        with interrupts.terminate_as_interrupt(), interrupts.unwrapped(), interrupts.command():
            return args.run(args)
    except errors.HzvalError as exc:
        print(f"hzval: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except OSError as exc:  # a read-only or full disk, no permission: one line, its path
        print(f"hzval: error: {staging.os_error(exc, '--out')}", file=sys.stderr)
        return errors.EXIT_BAD_INPUT
    except MemoryError:  # past every estimate (each refuses what it knows will not fit): one line
        print(
            f"hzval: error: {args.command}: ran out of memory beyond its estimate; nothing was kept "
            "(a smaller map, --depth or --spp fits)",
            file=sys.stderr,
        )
        return errors.EXIT_BAD_INPUT
    except KeyboardInterrupt as exc:
        print("hzval: interrupted", file=sys.stderr)
        return 128 + getattr(exc, "signum", signal.SIGINT)
