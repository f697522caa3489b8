"""Benchmark: production-size sweeps, where their time and memory go, and a side-by-side ratio.

Two modes, each running ``hzval sweep`` in child processes (fresh output folders, the bake
included) and reading what each run wrote (``metrics.json``: per-stage seconds, peak memory;
the bytes under ``frames/``):

``stages``
    The default sweep of the built-in bricks at each size (``--sizes 512,1024,2048,4096``),
    with the lights of ``--azimuths`` (default ``-60:60:120``, two lights), and a table of
    seconds per stage, wall and CPU (every thread's, ``metrics.json``'s ``timings.cpu_s``; a
    stage's CPU beyond its wall time is its use of the cores), peak resident memory (the child's
    own ``ru_maxrss``, beside the sweep's estimate) and the frame bytes, each with its growth from
    one size to the next (4x the pixels per step).

``side-by-side``
    The same sweep on this tree and on ``--baseline REV`` (a detached ``git worktree`` of it,
    run with this virtualenv), one after the other in one run: wall time, CPU time (user + sys of
    the child, less sensitive to a shared machine's load), peak memory and frame bytes of each, and
    the ratios. Options after ``--`` go to this tree's sweep only (e.g. ``-- --techniques
    horizon,terrain`` for the techniques an older tree ran, which had no such flag), or with
    ``--both`` to the baseline's as well.

Usage::

    python benchmarks/bench_production.py stages [--sizes 512,1024,2048,4096] [--azimuths=-60:60:120]
    python benchmarks/bench_production.py side-by-side --baseline 9219ded [--size 2048]
                                          [--azimuths=-60:60:30] [--both] [-- SWEEP OPTIONS]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

#: Stages of metrics.json's timings, in the order of a sweep, as (label, keys summed, its key in
#: ``timings.cpu_s``). The techniques' set-up and frames also sum every technique's own
#: ``<stem>_setup_s`` and ``<stem>_s`` (:func:`stage_seconds`).
STAGES = (
    ("bake", ("bake_s",), "bake"),
    ("truth set-up", ("truth_setup_s",), "truth_setup"),
    ("technique set-up", ("plain_setup_s",), "technique_setup"),
    ("truth frames", ("truth_s",), "truth_frames"),
    ("technique frames", ("plain_s",), "technique_frames"),
    ("compare", ("compare_s",), "compare"),
    ("write", ("write_s",), "write"),
    ("report", ("report_s",), "report"),
)
#: Timings that are not a technique's own.
_NOT_TECHNIQUES = {k for _, keys, _ in STAGES for k in keys} | {
    "total_s",
    "view_setup_s",
    "technique_frames_s",
}


def run_sweep(tree: Path, out: Path, args: list[str]) -> dict:
    """Run ``hzval sweep`` from ``tree`` (its own package first on the path) into ``out``;
    return wall seconds, the child's peak RSS, its metrics.json and the frame bytes."""
    cmd = [sys.executable, "-m", "hzval", "sweep", *args, "--out", str(out)]
    env = {**os.environ, "PYTHONPATH": str(tree)}
    t0 = time.perf_counter()
    with tempfile.TemporaryFile() as stderr:  # a file, not a pipe: a chatty child cannot fill it and stall
        child = subprocess.Popen(cmd, cwd=tree, env=env, stdout=subprocess.DEVNULL, stderr=stderr)
        _, status, usage = os.wait4(child.pid, 0)
        wall = time.perf_counter() - t0
        stderr.seek(0)
        err = stderr.read().decode(errors="replace").strip().splitlines()
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{' '.join(cmd)} (in {tree}) failed: {err[-1] if err else status}")
    metrics = json.loads((out / "metrics.json").read_text())
    frames = sum(p.stat().st_size for p in (out / "frames").rglob("*") if p.is_file())
    return {
        "wall_s": wall,
        "cpu_s": usage.ru_utime + usage.ru_stime,
        "peak_bytes": usage.ru_maxrss * 1024,
        "metrics": metrics,
        "frame_bytes": frames,
    }


def stage_seconds(timings: dict) -> dict:
    """Wall seconds per stage of :data:`STAGES` from ``metrics.json``'s timings."""
    own = [k for k, v in timings.items() if k not in _NOT_TECHNIQUES and isinstance(v, (int, float))]
    own = [k for k in own if k.endswith("_s") and not k.startswith("truth_")]
    extra = {
        "technique set-up": [k for k in own if k.endswith("_setup_s")],
        "technique frames": [k for k in own if not k.endswith("_setup_s")],
    }
    out = {
        label: sum(float(timings.get(k) or 0.0) for k in (*keys, *extra.get(label, ())))
        for label, keys, _ in STAGES
    }
    if "technique_frames_s" in timings:  # the renders' wall time (older runs: each technique's own, summed)
        out["technique frames"] = float(timings["technique_frames_s"])
    return out


def stage_cpu_seconds(timings: dict) -> dict:
    """Process CPU seconds per stage (every thread's), where the sweep recorded them (``cpu_s``)."""
    cpu = timings.get("cpu_s") or {}
    return {label: cpu.get(key) for label, _, key in STAGES}


def gib(n: float) -> str:
    return f"{n / 2**30:.2f} GiB"


def stages(sizes: list[int], azimuths: str, extra: list[str], scratch: Path) -> None:
    runs = {}
    for n in sizes:
        print(f"size {n} ...", file=sys.stderr, flush=True)
        runs[n] = run_sweep(ROOT, scratch / f"s{n}", ["--size", str(n), f"--azimuths={azimuths}", *extra])
    head = ["stage"] + [f"{n}" for n in sizes] + [f"x {b}/{a}" for a, b in zip(sizes, sizes[1:])]
    rows = []
    secs = {n: stage_seconds(r["metrics"]["timings"]) for n, r in runs.items()}
    cpus = {n: stage_cpu_seconds(r["metrics"]["timings"]) for n, r in runs.items()}
    for label, _, _ in STAGES:
        vals = [secs[n][label] for n in sizes]
        rows.append([label] + [f"{v:.1f} s" for v in vals] + [_ratio(b, a) for a, b in zip(vals, vals[1:])])
        cpu = [cpus[n][label] for n in sizes]
        rows.append(
            ["  CPU"]
            + [f"{v:.1f} s" if v is not None else "-" for v in cpu]
            + [_ratio(b, a) if a and b else "" for a, b in zip(cpu, cpu[1:])]
        )
    total = [runs[n]["wall_s"] for n in sizes]
    rows.append(
        ["wall (whole run)"]
        + [f"{v:.1f} s" for v in total]
        + [_ratio(b, a) for a, b in zip(total, total[1:])]
    )
    cpu = [runs[n]["cpu_s"] for n in sizes]
    rows.append(
        ["  CPU user + sys"] + [f"{v:.1f} s" for v in cpu] + [_ratio(b, a) for a, b in zip(cpu, cpu[1:])]
    )
    peak = [runs[n]["peak_bytes"] for n in sizes]
    rows.append(["peak memory"] + [gib(v) for v in peak] + [_ratio(b, a) for a, b in zip(peak, peak[1:])])
    est = [runs[n]["metrics"].get("memory", {}).get("estimate_bytes", 0) for n in sizes]
    rows.append(["  estimate"] + [gib(v) for v in est] + [""] * (len(sizes) - 1))
    fb = [runs[n]["frame_bytes"] for n in sizes]
    rows.append(
        ["frame files"] + [f"{v / 1e6:.0f} MB" for v in fb] + [_ratio(b, a) for a, b in zip(fb, fb[1:])]
    )
    _print_table(head, rows)


def side_by_side(
    baseline: str, size: int, azimuths: str, extra: list[str], scratch: Path, both: bool = False
) -> None:
    tree = scratch / "baseline"
    subprocess.run(
        ["git", "-C", str(ROOT), "worktree", "add", "--detach", str(tree), baseline],
        check=True,
        capture_output=True,
    )
    try:
        args = ["--size", str(size), f"--azimuths={azimuths}"]
        print(f"{baseline} ...", file=sys.stderr, flush=True)
        old = run_sweep(tree, scratch / "old", args + (extra if both else []))
        print("this tree ...", file=sys.stderr, flush=True)
        new = run_sweep(ROOT, scratch / "new", args + extra)
    finally:
        subprocess.run(
            ["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)], capture_output=True
        )
    so, sn = stage_seconds(old["metrics"]["timings"]), stage_seconds(new["metrics"]["timings"])
    rows = [
        [label, f"{so[label]:.1f} s", f"{sn[label]:.1f} s", _ratio(sn[label], so[label])]
        for label, _, _ in STAGES
    ]
    rows.append(
        [
            "wall (whole run)",
            f"{old['wall_s']:.1f} s",
            f"{new['wall_s']:.1f} s",
            _ratio(new["wall_s"], old["wall_s"]),
        ]
    )
    rows.append(
        [
            "CPU user + sys",
            f"{old['cpu_s']:.1f} s",
            f"{new['cpu_s']:.1f} s",
            _ratio(new["cpu_s"], old["cpu_s"]),
        ]
    )
    rows.append(
        [
            "peak memory",
            gib(old["peak_bytes"]),
            gib(new["peak_bytes"]),
            _ratio(new["peak_bytes"], old["peak_bytes"]),
        ]
    )
    rows.append(
        [
            "frame files",
            f"{old['frame_bytes'] / 1e6:.0f} MB",
            f"{new['frame_bytes'] / 1e6:.0f} MB",
            _ratio(new["frame_bytes"], old["frame_bytes"]),
        ]
    )
    print(
        f"hzval sweep {' '.join(args)}   ({'both' if both else 'this tree'}: + "
        f"{' '.join(extra) or 'nothing'}; "
        f"techniques: {baseline}: "
        f"{', '.join(old['metrics'].get('techniques', {})) or 'horizon, terrain'}; this tree: "
        f"{', '.join(new['metrics'].get('techniques', {}))})"
    )
    _print_table(["stage", baseline, "this tree", "ratio"], rows)


def _ratio(new: float, old: float) -> str:
    return f"{new / old:.2f}x" if old else "-"


def _print_table(head: list[str], rows: list[list[str]]) -> None:
    widths = [max(len(str(r[i])) for r in [head] + rows) for i in range(len(head))]
    for r in [head, ["-" * w for w in widths]] + rows:
        print(
            "  ".join(
                str(c).ljust(w) if i == 0 else str(c).rjust(w) for i, (c, w) in enumerate(zip(r, widths))
            )
        )


def main(argv=None) -> None:
    argv = list(sys.argv[1:] if argv is None else argv)
    extra = argv[argv.index("--") + 1 :] if "--" in argv else []
    argv = argv[: argv.index("--")] if "--" in argv else argv
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="mode", required=True)
    s = sub.add_parser("stages")
    s.add_argument("--sizes", default="512,1024,2048,4096")
    s.add_argument("--azimuths", default="-60:60:120")
    b = sub.add_parser("side-by-side")
    b.add_argument("--baseline", default="9219ded")
    b.add_argument("--size", type=int, default=2048)
    b.add_argument("--azimuths", default="-60:60:30")
    b.add_argument("--both", action="store_true", help="the options after -- go to the baseline's sweep too")
    a = p.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="hzval-bench-") as scratch:
        if a.mode == "stages":
            stages([int(x) for x in a.sizes.split(",")], a.azimuths, extra, Path(scratch))
        else:
            side_by_side(a.baseline, a.size, a.azimuths, extra, Path(scratch), both=a.both)


if __name__ == "__main__":
    main()
