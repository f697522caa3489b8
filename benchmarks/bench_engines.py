"""What the engines' techniques cost a sweep: the default sweep (every default technique) and the
same sweep with ``--techniques horizon,terrain,pom``, run alternately in fresh processes, and the
ratio of their median wall times (issue 39's bound: at most 1.25x), with each run's stages from
``metrics.json`` (render, scoring, writing), so that a reader sees where the added time goes.

A shared machine's speed drifts by more than the gap a ratio is read against, so it also prints
each pair's own ratio (a default run over the run beside it): their median and range say how far
one pass of the benchmark can be trusted.

    .venv/bin/python benchmarks/bench_engines.py [--repeat 3] [SWEEP ARGS ...]
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

#: The two sweeps, by name: every default technique, and the three before the engines' five.
RUNS = {"default": [], "horizon,terrain,pom": ["--techniques", "horizon,terrain,pom"]}


def sweep(extra: list[str], out: Path) -> tuple[float, dict]:
    """One sweep in a fresh process: its wall time and its ``metrics.json`` timings."""
    cmd = [sys.executable, "-m", "hzval", "sweep", *extra, "--quiet", "--force", "--out", str(out)]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, capture_output=True)
    wall = time.perf_counter() - t0
    return wall, json.loads((out / "metrics.json").read_text())["timings"]


def stages(t: dict) -> dict[str, float]:
    """A run's time by stage: set-up (bake, truth, techniques), renders (the truth's and the
    techniques' frames, wall time), scoring, writing."""
    return {
        "set-up": sum(v for k, v in t.items() if k.endswith("setup_s") or k == "bake_s"),
        "renders": t.get("truth_s", 0.0) + t.get("technique_frames_s", 0.0),
        "scoring": t.get("compare_s", 0.0),
        "writing": t.get("write_s", 0.0) + t.get("report_s", 0.0),
        "total": t.get("total_s", 0.0),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=3, help="runs of each, alternating (default 3)")
    args, extra = parser.parse_known_args(argv)
    walls: dict[str, list[float]] = {k: [] for k in RUNS}
    parts: dict[str, list[dict]] = {k: [] for k in RUNS}
    with tempfile.TemporaryDirectory() as tmp:
        for flags in RUNS.values():  # once each to warm the kernel cache: not timed
            sweep([*extra, *flags], Path(tmp) / "warm")
        for _ in range(args.repeat):
            for name, flags in RUNS.items():
                out = Path(tmp) / name.replace(",", "-")
                wall, t = sweep([*extra, *flags], out)
                walls[name].append(wall)
                parts[name].append(stages(t))
    med = {k: statistics.median(v) for k, v in walls.items()}
    print(f"hzval sweep {' '.join(extra)}: {args.repeat} runs of each, alternating, warm kernel cache")
    head = ["set-up", "renders", "scoring", "writing", "total"]
    print(f"  {'techniques':22s} {'wall s':>7s} " + " ".join(f"{h:>8s}" for h in head))
    for k in RUNS:
        s = {h: statistics.median(p[h] for p in parts[k]) for h in head}
        print(f"  {k:22s} {med[k]:7.2f} " + " ".join(f"{s[h]:8.2f}" for h in head))
    base = "horizon,terrain,pom"
    print(f"default / {base}: {med['default'] / med[base]:.3f}x (wall time, median)")
    pairs = sorted(d / b for d, b in zip(walls["default"], walls[base]))
    print(
        f"  each pair: {' '.join(f'{r:.3f}' for r in pairs)} "
        f"(median {statistics.median(pairs):.3f}x, {pairs[0]:.3f}-{pairs[-1]:.3f})"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
