"""``hzval sweep``'s flags (:mod:`hzval.commands.sweep`)."""

from __future__ import annotations

import sys
from pathlib import Path

from hzval.cli import flags, scenes


def add_parser(sub) -> None:
    """Add the ``sweep`` command's parser to ``sub``."""
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.techniques import registry as technique

    labels = ", ".join(technique.get(n).label for n in technique.names())
    p = sub.add_parser(
        "sweep",
        help="render the truth and every technique over a light sweep and report",
        description=f"Render the ground truth and every self-shadowing technique ({labels}: "
        "--techniques) for every light of the sweep (Lengyel's Figure 5.3 by "
        "default), compare them, and write metrics.json and an HTML report.",
    )
    flags.add_material_args(p)
    p.add_argument(
        "--scene",
        type=Path,
        default=None,
        help="scene description (TOML); the flags below override it (default: built-in bricks)",
    )
    flags.add_sweep_flags(p)
    p.add_argument("--out", type=Path, default=None, help="output folder (default reports/<scene name>)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    flags.add_gate_flags(p)
    p.set_defaults(run=run)


def run(args) -> int:
    """Sweep the scene of ``args``; print its table and one line of times. Exit 1 on a failed gate."""
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.commands import sweep as sweep_command
    from hzval.pipeline import records

    scene = scenes.scene_from_args(args)
    options = flags.sweep_options(args)
    out = args.out or Path("reports") / scene.name
    flags.check_technique_flags(args, sweep_command.selected(scene, options))
    result = sweep_command.run(
        scene,
        out,
        options=options,
        gates=flags.gates(args),
        command=flags.command_line(args),
        progress=not args.quiet,
        force=args.force,
    )
    flags.print_notes(args)
    for w in result.get("warnings", []):
        print(f"hzval: warning: {w}", file=sys.stderr)
    print(records.summary_table(result))
    print(sweep_command.run_line(result, out))
    return flags.gate_exit(result.get("gates"))
