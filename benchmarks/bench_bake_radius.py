"""Benchmark: what the seed horizon bake's search radius costs in compile and run time.

The seed bake (:func:`hzval.bake.horizon.horizon_map`) is one Dr.Jit kernel. Its
unrolled form has one block of code per neighbour offset (radius 16: 797
offsets; 32: 3,204; 64: 12,848), so its compile time grows faster than the
square of the radius; the looped form (symbolic loops over the offset table,
which the kernel reads as data) has the same code at every radius, bin
count and map size, and compiles in well under a second, but gathers every
neighbour and runs 3-10x slower. This script measures,
for each radius and kernel form, on a ``SIZE x SIZE`` brick map
(:func:`hzval.materials.bricks.bricks`, depth 0.05, 32 bins, wrap):

``cold``
    the first :func:`~hzval.bake.horizon.horizon_map` call of a fresh process with an
    **empty** Dr.Jit kernel cache (``DRJIT_CACHE_DIR`` set to a new empty
    folder): compile + run, what a first bake on a machine pays;
``disk``
    the first call of a second fresh process with that cache, now filled:
    loads the compiled kernel from disk + run (every later ``hzval bake``);
``warm``
    later calls in the same process (kernel in memory): the run alone, best
    of ``--repeat``.

and, from Dr.Jit's kernel history of the cold call, the seconds spent
generating LLVM IR (``codegen``) and compiling it (``backend``). Each
measurement runs in its own subprocess (``--child``), so one radius's
compiled kernels never help another's. It also checks that the forms agree
bit for bit at every radius (``max |loop - unrolled|`` must be 0).

Usage::

    python benchmarks/bench_bake_radius.py [--size 512] [--radii 16,32,64]
        [--kernels unrolled,loop,auto] [--repeat 3]

``--kernels`` takes ``auto`` (what :func:`~hzval.bake.horizon.horizon_map` picks:
:func:`hzval.bake.horizon.choose_kernel`, unrolled up to
:data:`hzval.bake.horizon.UNROLL_MAX_OFFSETS` offsets, above it the form with the
faster first bake by a cost model fitted to this script's figures; the
table shows ``auto=FORM``), ``unrolled`` and ``loop``.

Figures (benchmarks/README.md has the full tables; 2-core AVX2 machine,
512 x 512 bricks, seconds): radius 16: unrolled cold 0.59 / warm 0.040,
loop cold 0.48 / warm 0.43; radius 32: unrolled 4.4 / 0.16, loop 1.6 /
1.4; radius 64: unrolled 104 / 1.9, loop 10.9 / 5.2. At 2048 x 2048,
radius 32: unrolled cold 8.6, loop 40 (warm 29): there the unrolled kernel
wins even with its compile, which is why the choice depends on the size.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

DEPTH, ANGLES, BOUNDARY = 0.05, 32, "wrap"


def _child(size: int, radius: int, kernel: str, repeat: int, save: str | None) -> None:
    """Runs in a fresh process: one cold (or disk-cached) call, then warm calls; prints JSON."""
    import drjit as dr

    from hzval.bake import horizon as bake_horizon
    from hzval.core import backend
    from hzval.core import conventions as cv
    from hzval.materials.bricks import bricks

    backend.variant()
    h = cv.heights_in_texels(bricks(size), DEPTH)
    kw = {} if kernel == "auto" else {"kernel": kernel}
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
        dr.kernel_history()
        t0 = time.perf_counter()
        first = bake_horizon.horizon_map(h, radius, ANGLES, BOUNDARY, **kw)  # returns NumPy: synchronous
        first_s = time.perf_counter() - t0
        hist = [k for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]
    warm = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        bake_horizon.horizon_map(h, radius, ANGLES, BOUNDARY, **kw)
        warm.append(time.perf_counter() - t0)
    if save:
        np.save(save, np.concatenate([first[0], first[1][..., None], first[2][..., None]], axis=-1))
    offsets = sum(len(g.offsets) for g in bake_horizon.horizon_table(radius, ANGLES))
    lanes = size * (size + 2 * (radius - 1))
    print(
        json.dumps(
            {
                "form": bake_horizon.choose_kernel(offsets, lanes) if kernel == "auto" else kernel,
                "first_s": first_s,
                "warm_s": warm,
                "codegen_s": sum(k["codegen_time"] for k in hist) / 1e3,
                "backend_s": sum(k["backend_time"] for k in hist) / 1e3,
                "execution_s": sum(k["execution_time"] for k in hist) / 1e3,
                "compiled": sum(not k["cache_hit"] for k in hist),
                "from_disk": sum(bool(k["cache_disk"]) for k in hist),
                "offsets": offsets,
            }
        )
    )


def _run_child(args, radius: int, kernel: str, cache: Path, save: Path | None) -> dict:
    cmd = [
        sys.executable,
        __file__,
        "--child",
        "--size",
        str(args.size),
        "--radii",
        str(radius),
        "--kernels",
        kernel,
        "--repeat",
        str(args.repeat),
    ] + (["--save", str(save)] if save else [])
    proc = subprocess.run(
        cmd, env=dict(os.environ, DRJIT_CACHE_DIR=str(cache)), capture_output=True, text=True
    )
    if proc.returncode != 0:
        raise SystemExit(f"bench_bake_radius: {shlex.join(cmd)} failed:\n{proc.stdout}{proc.stderr}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", type=int, default=512, help="the map is SIZE x SIZE texels (default 512)")
    parser.add_argument(
        "--radii", default="16,32,64", help="search radii, comma-separated (default 16,32,64)"
    )
    parser.add_argument(
        "--kernels",
        default="unrolled,loop",
        help="kernel forms: auto, unrolled, loop, comma-separated (default unrolled,loop)",
    )
    parser.add_argument("--repeat", type=int, default=3, help="warm calls; the best is shown (default 3)")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--save", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    radii = [int(r) for r in args.radii.split(",")]
    kernels = args.kernels.split(",")
    if args.child:
        _child(args.size, radii[0], kernels[0], args.repeat, args.save)
        return 0

    load = os.getloadavg()[0]
    rows = []
    with tempfile.TemporaryDirectory(prefix="hzval-bench-radius-") as tmp:
        work = Path(tmp)
        for radius in radii:
            outputs = {}
            for kernel in kernels:
                cache = work / f"cache-{radius}-{kernel}"
                cache.mkdir()
                save = work / f"out-{radius}-{kernel}.npy"
                cold = _run_child(args, radius, kernel, cache, save)
                disk = _run_child(args, radius, kernel, cache, None)
                outputs[kernel] = np.load(save)
                rows.append((radius, kernel, cold, disk))
                print(
                    f"  r={radius} {kernel}: cold {cold['first_s']:.2f} s, disk {disk['first_s']:.2f} s, "
                    f"warm {min(cold['warm_s'] + disk['warm_s']):.3f} s",
                    file=sys.stderr,
                    flush=True,
                )
            ref = next(iter(outputs.values()))
            for kernel, out in outputs.items():
                same = out.tobytes() == ref.tobytes()
                rows[-len(kernels) + list(outputs).index(kernel)][2]["identical"] = same

    print(
        f"seed horizon bake: hzval.materials.bricks.bricks({args.size}), depth {DEPTH}, {ANGLES} bins, "
        f"{BOUNDARY}; "
        f"{os.cpu_count()} CPUs, load average {load:.2f} at start"
    )
    print(
        f"{'radius':>6} {'offsets':>7} {'kernel':<15} {'cold s':>8} {'codegen':>8} {'backend':>8} "
        f"{'disk s':>7} {'warm s':>7} {'same':>5}"
    )
    for radius, kernel, cold, disk in rows:
        warm = min(cold["warm_s"] + disk["warm_s"])
        name = kernel if kernel != "auto" else f"auto={cold['form']}"
        print(
            f"{radius:>6} {cold['offsets']:>7} {name:<15} {cold['first_s']:>8.2f} {cold['codegen_s']:>8.2f} "
            f"{cold['backend_s']:>8.2f} {disk['first_s']:>7.2f} {warm:>7.3f} "
            f"{'yes' if cold.get('identical', True) else 'NO':>5}"
        )
    print(
        "cold: first call, empty kernel cache (compile + run); codegen/backend: of it, IR generation and "
        "LLVM compilation; disk: first call of a new process with the cache filled; warm: kernel in memory, "
        f"best of {2 * args.repeat}; same: output bit-identical to the first kernel form's"
    )
    print(
        "reproduce: "
        + shlex.join(
            [sys.executable, str(Path(__file__).resolve())] + (argv if argv is not None else sys.argv[1:])
        )
    )
    return 0 if all(cold.get("identical", True) for _, _, cold, _ in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
