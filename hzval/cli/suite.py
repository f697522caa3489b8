"""``hzval suite``: many materials swept alike, and an overview (:mod:`hzval.commands.suite`).

Each material's scene is built by :func:`hzval.commands.suite.entries` from its own scene file or
sidecar, with the flags' :func:`hzval.cli.scenes.scene_overrides` on top, as a sweep's is.
"""

from __future__ import annotations

import sys
from pathlib import Path

from hzval import materials
from hzval.cli import flags, scenes
from hzval.core import errors


def add_parser(sub) -> None:
    """Add the ``suite`` command's parser to ``sub``."""
    p = sub.add_parser(
        "suite",
        help="sweep many materials (the built-in ones by default) and write an overview",
        description="Sweep every material (the built-in ones, or scene TOMLs, height maps - each "
        "with an optional sidecar <stem>.toml - folders of them, or built-in names) "
        "with the same options, on a pool of worker processes or a Dask cluster; "
        "write each material's report under DIR, and DIR/index.html and "
        "DIR/suite.json with every material's mean errors and times.",
    )
    p.add_argument(
        "inputs",
        nargs="*",
        metavar="SCENE.toml|HEIGHT|FOLDER|NAME",
        help="materials to sweep (default: every built-in material)",
    )
    p.add_argument("--depth", type=float, default=None, help="override every material's depth")
    p.add_argument(
        "--boundary", choices=["wrap", "open"], default=None, help="override every material's boundary"
    )
    p.add_argument(
        "--size",
        type=int,
        default=None,
        metavar="N",
        help=f"size of the built-in materials (default {materials.DEFAULT_SIZE})",
    )
    flags.add_sweep_flags(p)
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="worker processes on this machine, each sweeping one material at a time (default: "
        "1 per core, as many as fit in memory, at most the number of materials, at least 1); "
        "0 sweeps them in this process, where a crash ends the suite",
    )
    p.add_argument(
        "--cluster",
        default=None,
        metavar="ADDRESS",
        help="run on the Dask scheduler at ADDRESS (tcp://host:8786) instead; its workers need "
        "hzval and DIR and the inputs at the same paths",
    )
    p.add_argument(
        "--out",
        type=Path,
        default=Path("reports") / "suite",
        metavar="DIR",
        help="output folder (default reports/suite)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    flags.add_gate_flags(p)
    p.set_defaults(run=run)


def run(args) -> int:
    """Sweep every material of ``args``; print the overview. Exit 1 if one failed or a gate did."""
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.commands import suite
    from hzval.report import overview
    from hzval.techniques import registry as technique

    items = suite.entries(args.inputs, **scenes.scene_overrides(args))
    _size_note(args.size, items)
    workers = args.workers if args.workers is not None else suite.default_workers(items)
    command = flags.command_line(args)
    gates = flags.gates(args)
    if gates:  # every metric's name, and each material's baseline, before anything renders
        gates.check_before(technique.names())
        for e in items:
            if gates.baseline_path is not None and (gates.baseline_path / e.name / "metrics.json").is_file():
                suite.material_baseline(gates, e.name)
    result = suite.run(
        items,
        args.out,
        options=flags.sweep_options(args),
        workers=workers,
        cluster=args.cluster,
        variant=args.variant,
        command=command,
        progress=not args.quiet,
        force=args.force,
        gates=gates,
    )
    print(overview.summary_table(result))
    s = result["suite"]
    print(
        f"\n{s['materials']} materials ({s['failed']} failed) in {s['seconds']:.1f} s on {s['engine']}; "
        f"overview: {args.out / 'index.html'}"
    )
    gated = flags.gate_exit(result.get("gates"))
    if gated == errors.EXIT_BAD_INPUT:
        return gated
    return errors.EXIT_OK if not s["failed"] and not gated else errors.EXIT_CHECK_FAILED


def _size_note(size: int | None, items) -> None:
    """Check ``--size``, which names the built-in materials' size.

    It is refused when every material is a file; otherwise a note names the files.
    """
    if size is None:
        return
    own = [e for e in items if not scenes.builtin(e.scene.material.height)]
    if own and len(own) == len(items):
        scenes.refuse_size(size, own[0].scene.material.height)
    if own:
        more = " ..." if len(own) > 4 else ""
        print(
            f"hzval: note: --size {size} applies to the built-in materials only; "
            f"{', '.join(e.name for e in own[:4])}{more} keep their own size",
            file=sys.stderr,
        )
