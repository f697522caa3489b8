"""Seed against exact horizon bake: time and accuracy, side by side in one run.

For each size (default 512 and 2048) this bakes ``hzval.materials.bricks.bricks(size)``
(depth 0.05, wrap) in-process with both methods, kernels warm (one untimed
run each first), alternating seed and exact, and prints the best of
``--repeat`` of each, with their ratio:

* ``seed``: :func:`hzval.bake.horizon.horizon_map` (radius 16, 32 bins, Lengyel);
* ``exact``: :func:`hzval.bake.exact.exact_horizon_map` (unlimited radius, line
  sweeps with a convex-hull stack, Timonen and Westerholm 2010), Dr.Jit
  engine, and, at the smallest size only, its NumPy engine.

Accuracy, taking the exact bake as the truth: per channel (azimuth ``45 k``
degrees) the mean and max of ``|seed - exact|`` in sine, the mean signed
difference, and the fraction of texels where the seed under-reports the
horizon by more than 0.05 in sine (``exact - seed > 0.05``: light leaks
where the seed's radius misses an occluder), and over-reports it by more
than 0.05.

Run from the repository root::

    .venv/bin/python benchmarks/bench_horizon_methods.py [--sizes 512,2048] [--repeat 3]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import hzval.bake as B  # noqa: E402
from hzval.core import backend  # noqa: E402
from hzval.core import conventions as cv  # noqa: E402
from hzval.materials.bricks import bricks


def timed(fn):
    t0 = time.perf_counter()
    result = fn()
    return time.perf_counter() - t0, result


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="512,2048", help="comma-separated map sizes (default 512,2048)")
    ap.add_argument("--repeat", type=int, default=3, help="timed runs of each, best reported (default 3)")
    ap.add_argument("--depth", type=float, default=0.05)
    ap.add_argument("--boundary", default="wrap", choices=["wrap", "open"])
    args = ap.parse_args(argv)
    sizes = [int(s) for s in args.sizes.split(",")]

    variant = backend.variant()
    load = os.getloadavg()[0]
    print(
        f"seed vs exact horizon bake: hzval.materials.bricks.bricks(N), depth {args.depth:g}, "
        f"{args.boundary}; "
        f"variant {variant}; {os.cpu_count()} CPUs, load average {load:.2f} at start; best of {args.repeat}, "
        f"kernels warm, in-process"
    )
    print()
    print(f"{'size':>5} {'method':<32} {'best s':>8}  all runs, s")
    accuracy = {}
    for n in sizes:
        h = cv.heights_in_texels(bricks(n), args.depth)
        runs = {
            "seed (radius 16, 32 bins)": lambda h=h: B.horizon_map(h, 16, 32, args.boundary),
            "exact (Dr.Jit)": lambda h=h: B.exact_horizon_map(h, args.boundary, engine="drjit"),
        }
        if n == min(sizes):
            runs["exact (NumPy)"] = lambda h=h: B.exact_horizon_map(h, args.boundary, engine="numpy")
        results = {name: fn() for name, fn in runs.items()}  # warm the kernels
        times = {name: [] for name in runs}
        for _ in range(args.repeat):
            for name, fn in runs.items():  # alternate: same conditions
                times[name].append(timed(fn)[0])
        for name, ts in times.items():
            print(f"{n:>5} {name:<32} {min(ts):8.3f}  {' '.join(f'{t:.3f}' for t in ts)}")
        seed_best = min(times["seed (radius 16, 32 bins)"])
        print(f"{n:>5} {'ratio exact (Dr.Jit) / seed':<32} {min(times['exact (Dr.Jit)']) / seed_best:8.2f}")
        if "exact (NumPy)" in times:
            print(f"{n:>5} {'ratio exact (NumPy) / seed':<32} {min(times['exact (NumPy)']) / seed_best:8.2f}")
        seed, ex = results["seed (radius 16, 32 bins)"], results["exact (Dr.Jit)"]
        accuracy[n] = (seed, ex)

    for n, (seed, ex) in accuracy.items():
        diff = seed[0].astype(np.float64) - ex[0].astype(np.float64)  # > 0: seed over-reports
        print()
        print(f"accuracy at {n}x{n}, sine of the horizon angle, seed - exact (exact = truth):")
        print(
            f"{'channel':>8} {'azimuth':>8} {'mean|d|':>8} {'max|d|':>8} {'mean d':>8} "
            f"{'under>0.05':>11} {'over>0.05':>10} {'exact mean':>11}"
        )
        for k in range(cv.CHANNEL_COUNT):
            d = diff[..., k]
            print(
                f"{k:>8} {45 * k:>8} {np.abs(d).mean():8.4f} {np.abs(d).max():8.4f} {d.mean():+8.4f} "
                f"{(d < -0.05).mean():11.2%} {(d > 0.05).mean():10.2%} {ex[0][..., k].mean():11.4f}"
            )
        print(
            f"{'all':>8} {'':>8} {np.abs(diff).mean():8.4f} {np.abs(diff).max():8.4f} {diff.mean():+8.4f} "
            f"{(diff < -0.05).mean():11.2%} {(diff > 0.05).mean():10.2%} {ex[0].mean():11.4f}"
        )
        for name, i in (("mean_cos", 1), ("mean_cos2", 2)):
            d = seed[i].astype(np.float64) - ex[i].astype(np.float64)
            print(
                f"ambient {name}: seed (32 bins) - exact (8 directions): mean {d.mean():+.4f}, "
                f"max |d| {np.abs(d).max():.4f}"
            )
    print()
    print(
        f"reproduce: .venv/bin/python benchmarks/bench_horizon_methods.py --sizes {args.sizes} "
        f"--repeat {args.repeat}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
