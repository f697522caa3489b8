"""``hzval score``: an engine's frames scored against a sweep's truth (:mod:`hzval.commands.score`)."""

from __future__ import annotations

import sys
from pathlib import Path

from hzval.cli import flags
from hzval.metrics.results import SweepResult


def add_parser(sub) -> None:
    """Add the ``score`` command's parser to ``sub``."""
    p = sub.add_parser(
        "score",
        help="score your engine's frames of a sweep against its truth",
        description="Read one image per light of SWEEP_DIR (named after its frame folders: "
        "az+0.exr linear, or az+0.png sRGB; SWEEP_DIR/frames.json says how to render "
        "them; f_az+0.exr, the shadow factor F, optional), score each against the "
        "sweep's truth with every metric of the sweep, beside the sweep's own "
        "techniques, and write metrics.json and a report (FRAMES_DIR/engine.toml: "
        "your engine's label and parameters).",
    )
    p.add_argument("frames", type=Path, metavar="FRAMES_DIR", help="folder of your renderer's frames")
    p.add_argument(
        "--against", required=True, type=Path, metavar="SWEEP_DIR", help="a folder hzval sweep wrote"
    )
    p.add_argument("--out", type=Path, default=None, help="output folder (default FRAMES_DIR/score)")
    flags.add_gate_flags(p, strict=False)
    p.add_argument(
        "--strict",
        action="store_true",
        help="exit 2 on a file in FRAMES_DIR that matches no frame's name (default: a warning naming it)",
    )
    p.set_defaults(run=run)


def run(args) -> int:
    """Run ``hzval score`` with the parsed ``args``; return its exit code."""
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.commands import score
    from hzval.pipeline import records

    gates = flags.gates(args)
    result, maps = score.score(args.frames, args.against, strict=args.strict)
    if gates:  # the engine and the sweep's techniques, before the report is written
        gates.check_before(SweepResult.of(result).techniques)
    out = args.out or args.frames / "score"
    command = flags.command_line(args)
    index = score.write(result, maps, out, command=command, force=args.force, gates=gates)
    for w in result.get("warnings", []):
        print(f"hzval: warning: {w}", file=sys.stderr)
    print(records.summary_table(result))
    print(f"report: {index}")
    return flags.gate_exit(result.get("gates"))
