"""``hzval sweep``: the truth and every technique over a light sweep (:func:`hzval.pipeline.sweep.run`)."""

from __future__ import annotations

import sys
from pathlib import Path

from hzval.cli import flags, scenes


def add_parser(sub) -> None:
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
    from hzval.pipeline import records, sweep
    from hzval.techniques import registry as technique

    scene = scenes.scene_from_args(args)
    options = flags.sweep_options(args)
    out = args.out or Path("reports") / scene.name
    command = flags.command_line(args)
    gates = flags.gates(args)
    requested = None if options.techniques is None else list(options.techniques)
    names = [t.name for t in technique.select(requested, scene, exclude=options.exclude)]
    flags.check_technique_flags(args, names)
    if gates:  # every name and the baseline's settings, before anything renders
        gates.check_before(names, records.scene_parameters(scene, out, names))
    result = sweep.run(
        scene, out, options=options, command=command, progress=not args.quiet, force=args.force, gates=gates
    )
    flags.print_notes(args)
    for w in result.get("warnings", []):
        print(f"hzval: warning: {w}", file=sys.stderr)
    print(records.summary_table(result))
    print(run_line(result, out))
    return flags.gate_exit(result.get("gates"))


def run_line(result: dict, out: Path) -> str:
    """The line under the table: frames, the run's total time (the report's own) and where it went,
    the peak memory, and where the report is."""
    t = result["timings"]
    setup = t.get("plain_setup_s", 0.0) + sum(t.get(f"{s}_setup_s", 0.0) for s in _stems(result))
    parts = [
        f"bake {t['bake_s']:.2f} s{', cached' if t['bake_cached'] else ''}",
        f"truth {t['truth_setup_s'] + t['truth_s']:.2f} s",
        f"techniques {setup + t['technique_frames_s']:.2f} s",  # the renders' wall time
        f"scoring {t.get('compare_s', 0.0):.2f} s",
        f"writing {t.get('write_s', 0.0) + t.get('report_s', 0.0):.2f} s",
    ]
    return (
        f"\n{len(result['frames'])} frames in {t['total_s']:.1f} s ({', '.join(parts)}; peak memory "
        f"{result['memory']['peak_rss_bytes'] / 2**30:.2f} GiB); report: {out / 'index.html'}"
    )


def _stems(result: dict) -> set[str]:
    return {info["file_stem"] for info in result["techniques"].values()}
