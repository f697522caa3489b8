"""Benchmark: horizon-map shading frames (hzval.techniques.horizon), once compiled.

Bakes ``hzval.materials.bricks.bricks(SIZE)`` at depth 0.05 (radius 16, 32 bins,
wrap) once, then for every effect set, sample count and path builds an
:class:`hzval.techniques.horizon.Horizon` of a ``SIZE x SIZE`` frame, renders one
frame (compiles its kernels, or loads them from Dr.Jit's disk cache), and
times ``--frames`` more at different azimuths (-60..+60 degrees, the sweep of
Lengyel's Figure 5.3, elevation 30). Per row it prints the mean, min and max
wall time of a frame (``Frame.seconds``: kernels synchronised and images read
back into NumPy; mean, median, min, max), the mean time inside Dr.Jit's
kernels per frame (its kernel history),
and the number of kernels compiled after the first frame, which must be 0:
a new light must reuse the kernels (per-frame values enter them opaquely).
The issue's target: a 512 x 512 frame at 1 sample per pixel in under 10 ms.

Usage::

    python benchmarks/bench_horizon.py [--size 512] [--spp 1,16] [--paths exact,gpu]
                                      [--effects
                                      "shadow;shadow,diffuse;shadow,diffuse,specular,ambient,reflection_occlusion"]
                                      [--frames 20]

Exit status 1 if any row compiled a kernel after its first frame.
"""

from __future__ import annotations

import argparse
import gc
import os
import platform
import shlex
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
DEPTH = 0.05
ELEVATION = 30.0
TARGET_MS = 10.0
DEFAULT_EFFECTS = "shadow;shadow,diffuse;shadow,diffuse,specular,ambient,reflection_occlusion"


def _cpu() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--spp", default="1,16", help="comma-separated samples per pixel")
    ap.add_argument("--paths", default="exact,gpu")
    ap.add_argument("--effects", default=DEFAULT_EFFECTS, help="effect sets, ';'-separated")
    ap.add_argument("--frames", type=int, default=20)
    args = ap.parse_args(argv)

    import hzval.bake as B
    from hzval.core import backend
    from hzval.materials.bricks import bricks
    from hzval.scene import spec as sc
    from hzval.techniques.horizon import Horizon

    variant = backend.variant()
    import drjit as dr

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    t0 = time.perf_counter()
    bake = B.bake(bricks(args.size), B.BakeParams(depth=DEPTH))
    bake_s = time.perf_counter() - t0
    azimuths = np.linspace(-60.0, 60.0, args.frames)

    print(
        f"hzval approximation benchmark: {args.size}x{args.size} bricks, depth {DEPTH}, "
        f"elevation {ELEVATION}, {args.frames} frames at azimuths -60..60 after one warm-up frame"
    )
    print(
        f"machine: {_cpu()}, {os.cpu_count()} cores, load average {load:.2f} at start; "
        f"variant {variant}; "
        + ", ".join(f"{k} {v}" for k, v in backend.versions().items() if k != "variant")
    )
    print(f"bake (not timed below): {bake_s:.2f} s")
    header = (
        f"{'effects':<52} {'spp':>3} {'path':<5} {'first ms':>8} {'mean ms':>8} {'median':>7} "
        f"{'min ms':>7} {'max ms':>7} {'kernel ms':>9} {'compiled':>8}"
    )
    print(header)
    print("-" * len(header))
    failed = False
    for effects in [tuple(e.strip() for e in s.split(",") if e.strip()) for s in args.effects.split(";")]:
        for spp in (int(s) for s in args.spp.split(",")):
            for path in args.paths.split(","):
                scene = sc.Scene(
                    material=sc.MaterialSpec(size=args.size, depth=DEPTH),
                    light=sc.Light(elevation_deg=ELEVATION),
                    effects=effects,
                    spp=spp,
                ).validate()
                approx = Horizon(scene, bake, path=path)
                first = approx.render(float(azimuths[0]) - 7.0).seconds
                seconds, kernel_ms, compiled = [], [], 0
                with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
                    dr.kernel_history()
                    for az in azimuths:
                        seconds.append(approx.render(float(az)).seconds)
                        jit = [h for h in dr.kernel_history() if h["type"] == dr.KernelType.JIT]
                        compiled += sum(not h["cache_hit"] for h in jit)
                        kernel_ms.append(sum(h["execution_time"] for h in jit))
                ms = np.array(seconds) * 1e3
                failed |= compiled > 0
                print(
                    f"{','.join(effects):<52} {spp:>3} {path:<5} {first * 1e3:>8.1f} {ms.mean():>8.2f} "
                    f"{np.median(ms):>7.2f} {ms.min():>7.2f} {ms.max():>7.2f} {np.mean(kernel_ms):>9.2f} "
                    f"{compiled:>8}"
                )
                del approx
                gc.collect()
                dr.flush_malloc_cache()  # the next row starts from fresh allocations
    print(
        f"target: a {args.size}x{args.size} frame at 1 spp in under {TARGET_MS:.0f} ms, "
        "0 kernels compiled after the first frame"
    )
    cmd = [
        os.path.relpath(sys.executable, REPO) if sys.executable.startswith(str(REPO)) else sys.executable,
        "benchmarks/bench_horizon.py",
        "--size",
        str(args.size),
        "--spp",
        args.spp,
        "--paths",
        args.paths,
        "--effects",
        args.effects,
        "--frames",
        str(args.frames),
    ]
    print(f"reproduce: cd {shlex.quote(str(REPO))} && {shlex.join(cmd)}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
