"""Benchmark: hzval's horizon bake against the seed loop in C, side by side.

One run, one input, one table. The input is a 16-bit PNG of the built-in
brick wall (:func:`hzval.materials.bricks.bricks`), baked at depth 0.05, radius 16,
32 bins, wrap. Rows of the table:

1. the C peer (``tests/oracles/seed_bake.c``) compiled with
   ``gcc -O3 -march=native -fopenmp`` on two threads, in both variants:
   (1a) ``-DHOISTED_TABLE``, the seed loop with its offset-to-bins table
   computed once (the original design notes: "compute it once") -- the peer that the speed
   target is measured against -- and (1b) the literal seed loop, which
   recomputes ``atan2f``/``atanf``/``sqrtf`` for every texel and neighbour;
   whole-process wall time and the time of the bake loop alone;
2. ``hzval bake INPUT.png --out DIR`` as a subprocess (the console script of
   this Python's environment) with a warm Dr.Jit kernel cache: one run to warm
   it, then the best of ``--repeat``;
3. the same with an empty Dr.Jit kernel cache (``DRJIT_CACHE_DIR`` pointed at
   a new empty folder for every run): what a first run on a machine pays;
4. :func:`hzval.bake.horizon.horizon_map` alone, in this process, kernel warm.

It also checks that the two C variants agree bit for bit and that the peer
and ``hzval bake`` computed the same thing:
the peer's output against ``horizon0.exr``, ``horizon1.exr`` and
``ambient.exr`` (max abs difference). The peer reads the very heights that
hzval decodes from the PNG (written to raw float32), so both see one input.

Usage::

    python benchmarks/bench_bake.py [--size 2048] [--repeat 3]
"""

from __future__ import annotations

import argparse
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SOURCE = HERE.parent / "tests" / "oracles" / "seed_bake.c"
DEPTH, RADIUS, ANGLES, BOUNDARY = 0.05, 16, 32, "wrap"
THREADS = 2
C_FLAGS = ["-O3", "-march=native", "-fopenmp"]
#: The two builds of seed_bake.c; "hoisted" is the peer the target is measured against.
C_VARIANTS = {"hoisted": ["-DHOISTED_TABLE"], "literal": []}
TARGET_RATIO = 0.5


def _run(cmd: list[str], env: dict | None = None) -> tuple[float, subprocess.CompletedProcess]:
    """Wall time of a subprocess and its result; raises with its stderr if it fails."""
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(
            f"bench_bake: {shlex.join(cmd)} failed ({proc.returncode}):\n{proc.stdout}{proc.stderr}"
        )
    return wall, proc


def _hzval_script() -> str:
    """The ``hzval`` console script of the environment that runs this script."""
    script = Path(sys.executable).parent / "hzval"
    if not script.exists():
        raise SystemExit(
            f"bench_bake: no hzval console script next to {sys.executable}; "
            "install hzval into this environment (pip install -e .)"
        )
    return str(script)


def _input_map(size: int) -> tuple[np.ndarray, str]:
    """The benchmark's height map and its description."""
    try:
        from hzval.materials.bricks import bricks

        return bricks(size), f"hzval.materials.bricks.bricks({size})"
    except (ImportError, AttributeError):  # pragma: no cover - material.py not written yet
        from scipy.ndimage import gaussian_filter

        rng = np.random.default_rng(1)
        h = gaussian_filter(rng.random((size, size)), sigma=size / 64, mode="wrap")
        h = (h - h.min()) / (h.max() - h.min())
        return h.astype(np.float32), f"smooth random map {size}x{size} (hzval.materials missing)"


def _peer_vs_bake(peer: np.ndarray, out: Path) -> dict[str, float]:
    """Max abs differences between the peer's output and a bake folder's EXRs."""
    from hzval.io import codecs

    h0, h1, amb = (codecs.read_exr(out / name) for name in ("horizon0.exr", "horizon1.exr", "ambient.exr"))
    horizon = np.stack([h0[c] for c in "RGBA"] + [h1[c] for c in "RGBA"], axis=-1)
    return {
        "horizon": float(np.abs(horizon - peer[..., :8]).max()),
        "mean_cos": float(np.abs(amb["mean_cos"] - peer[..., 8]).max()),
        "mean_cos2": float(np.abs(amb["mean_cos2"] - peer[..., 9]).max()),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", type=int, default=2048, help="the map is SIZE x SIZE texels (default 2048)")
    parser.add_argument(
        "--repeat", type=int, default=3, help="timed runs per row; the best is shown (default 3)"
    )
    parser.add_argument(
        "--keep",
        type=Path,
        default=None,
        help="work in this folder and keep it (default: a temporary folder, removed)",
    )
    args = parser.parse_args(argv)
    if args.size < 8 or args.repeat < 1:
        parser.error("--size must be at least 8 and --repeat at least 1")

    load_start = os.getloadavg()  # before this script loads the machine itself
    gcc = shutil.which("gcc")
    if gcc is None:
        raise SystemExit("bench_bake: gcc is not installed; it is needed to build the C peer")
    hzval = _hzval_script()

    from hzval.bake import horizon as bake_horizon
    from hzval.core import backend
    from hzval.core import conventions as cv
    from hzval.io import codecs, heightmap

    work = Path(tempfile.mkdtemp(prefix="hzval-bench-")) if args.keep is None else args.keep
    work.mkdir(parents=True, exist_ok=True)
    try:
        # -- the input: a 16-bit PNG, and the heights hzval decodes from it
        height, what = _input_map(args.size)
        png = work / f"bricks{args.size}.png"
        codecs.write_png(png, np.round(np.clip(height, 0.0, 1.0) * 65535.0).astype(np.uint16))
        decoded = heightmap.load_height(png).height.astype(np.float32)
        rows, cols = decoded.shape
        raw = work / "height.f32"
        decoded.astype("<f4").tofile(raw)

        # -- (1) the C peer, both variants: (1a) offset table hoisted, (1b) literal
        env_c = dict(os.environ, OMP_NUM_THREADS=str(THREADS))
        c_cmd, c_wall, c_loop, c_out = {}, {}, {}, {}
        for name, defines in C_VARIANTS.items():
            exe = work / f"seed_bake_{name}"
            _run([gcc, *C_FLAGS, *defines, "-o", str(exe), str(SOURCE), "-lm"])
            c_out[name] = work / f"peer_{name}.f32"
            c_cmd[name] = [
                str(exe),
                str(raw),
                str(rows),
                str(cols),
                repr(DEPTH),
                str(RADIUS),
                str(ANGLES),
                BOUNDARY,
                str(c_out[name]),
            ]
            c_wall[name], c_loop[name] = [], []
        for _ in range(args.repeat):  # the variants alternate, so that both see the same machine
            for name in C_VARIANTS:
                wall, proc = _run(c_cmd[name], env_c)
                c_wall[name].append(wall)
                c_loop[name].append(float(re.search(r"loop_s ([0-9.]+)", proc.stderr).group(1)))
        peer = np.fromfile(c_out["hoisted"], dtype="<f4").reshape(rows, cols, 10)
        literal = np.fromfile(c_out["literal"], dtype="<f4").reshape(rows, cols, 10)
        c_identical = peer.tobytes() == literal.tobytes()

        # -- (2) hzval bake, warm kernel cache (a private cache, warmed by one run)
        base = [
            hzval,
            "bake",
            str(png),
            "--depth",
            repr(DEPTH),
            "--radius",
            str(RADIUS),
            "--angles",
            str(ANGLES),
            "--boundary",
            BOUNDARY,
        ]
        warm_cache = work / "drjit-cache-warm"
        warm_cache.mkdir()
        env_warm = dict(os.environ, DRJIT_CACHE_DIR=str(warm_cache))
        _run(base + ["--out", str(work / "bake-warmup")], env_warm)
        hz_warm = []
        for k in range(args.repeat):
            wall, _ = _run(base + ["--out", str(work / f"bake-warm{k}")], env_warm)
            hz_warm.append(wall)
        best_warm = int(np.argmin(hz_warm))
        stages = files_json(work / f"bake-warm{best_warm}" / "bake.json")

        # -- (3) hzval bake, cold: an empty kernel cache for every run
        hz_cold = []
        for k in range(args.repeat):
            cold_cache = work / f"drjit-cache-cold{k}"
            cold_cache.mkdir()
            wall, _ = _run(
                base + ["--out", str(work / f"bake-cold{k}")],
                dict(os.environ, DRJIT_CACHE_DIR=str(cold_cache)),
            )
            hz_cold.append(wall)

        # -- (4) hzval.bake.horizon.horizon_map in this process, kernel warm
        variant = backend.variant()
        h = cv.heights_in_texels(decoded, DEPTH)
        bake_horizon.horizon_map(h, RADIUS, ANGLES, BOUNDARY)  # compile (or load) the kernel
        kernel = []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            bake_horizon.horizon_map(h, RADIUS, ANGLES, BOUNDARY)  # returns NumPy arrays: synchronous
            backend.sync()
            kernel.append(time.perf_counter() - t0)

        # -- same input, same output?
        diffs = {name: _peer_vs_bake(peer, work / name) for name in (f"bake-warm{best_warm}", "bake-cold0")}

        # -- the table
        c_w, c_l = min(c_wall["hoisted"]), min(c_loop["hoisted"])
        lit_w, lit_l = min(c_wall["literal"]), min(c_loop["literal"])
        w, c, kern = min(hz_warm), min(hz_cold), min(kernel)
        ratio, ratio_cold, ratio_lit = w / c_w, c / c_w, w / lit_w
        load_end = os.getloadavg()
        nan = float("nan")
        stage_keys = ["load_s", "normal_s", "horizon_s", "write_s"]
        stage_keys += [k for k in stages if k not in stage_keys]
        staged = sum(stages.get(k, 0.0) for k in stage_keys)
        flags = " ".join(C_FLAGS)
        lines = [
            f"hzval horizon bake vs the seed loop in C: {what}, {cols}x{rows}, 16-bit PNG,",
            f"depth {DEPTH}, radius {RADIUS}, {ANGLES} bins, {BOUNDARY}; {os.cpu_count()} CPUs, "
            f"load average {load_start[0]:.2f} at start ({load_end[0]:.2f} at end, with this run's own "
            "load);",
            f"best of {args.repeat}; hzval variant {variant}",
            "",
            f"{'what':<58} {'whole s':>8} {'bake s':>8}",
            f"{'-' * 58} {'-' * 8} {'-' * 8}",
            f"{'(1a) C seed loop, offset table hoisted (-DHOISTED_TABLE)':<58} {c_w:8.3f} {c_l:8.3f}",
            f"{'(1b) C seed loop, literal (atan2f/atanf/sqrtf per texel)':<58} {lit_w:8.3f} {lit_l:8.3f}",
            f"{'(2) hzval bake (process), Dr.Jit kernel cache warm':<58} {w:8.3f} "
            f"{stages.get('horizon_s', float('nan')):8.3f}",
            f"{'(3) hzval bake (process), Dr.Jit kernel cache EMPTY':<58} {c:8.3f} {'':>8}",
            f"{'(4) hzval.bake.horizon.horizon_map in-process, kernel warm':<58} {'':>8} {kern:8.3f}",
            "",
            f"(1a), (1b): gcc {flags}, OMP_NUM_THREADS={THREADS}; outputs bit-identical: "
            f"{'yes' if c_identical else 'NO'}.",
            "whole s: wall time of the whole process (C: reads raw float32, writes raw float32;",
            "         hzval: starts Python, decodes the PNG, bakes normal+horizon+ambient,",
            "         writes 14 files: EXR, PNG, cube map, bake.json).",
            "bake s:  C: its loop alone (1a: with building the table); (2): bake.json horizon_s",
            "         of the best timed run;",
            "         (4): horizon_map alone, best of the runs.",
            "hzval bake stages, s (bake.json, best warm run): "
            + ", ".join(f"{k[:-2] if k.endswith('_s') else k} {stages.get(k, nan):.3f}" for k in stage_keys)
            + f"; sum {staged:.3f};",
            f"         rest of the process (Python start, imports, Dr.Jit set-up) {w - staged:.3f}",
            f"all runs, s: C hoisted whole {fmt(c_wall['hoisted'])}, loop {fmt(c_loop['hoisted'])};",
            f"             C literal whole {fmt(c_wall['literal'])}, loop {fmt(c_loop['literal'])};",
            f"             hzval warm {fmt(hz_warm)}; cold {fmt(hz_cold)}; kernel {fmt(kernel)}",
            "",
            f"HEADLINE ratio hzval/C hoisted, whole process, warm cache (2)/(1a): {ratio:.2f} "
            f"(target <= {TARGET_RATIO}: {'met' if ratio <= TARGET_RATIO else 'NOT met'})",
            f"ratio hzval/C hoisted, whole process, empty cache (3)/(1a): {ratio_cold:.2f}",
            f"ratio hzval/C hoisted, bake alone (4)/(1a loop): {kern / c_l:.2f}",
            f"ratio hzval/C literal, whole process, warm cache (2)/(1b): {ratio_lit:.2f}; "
            f"bake alone (4)/(1b loop): {kern / lit_l:.2f}",
            "",
            "same output: max |peer - hzval bake| "
            + "; ".join(
                f"{name}: " + ", ".join(f"{k} {v:.2g}" for k, v in d.items()) for name, d in diffs.items()
            ),
            "",
            "reproduce: "
            + shlex.join(
                [sys.executable, str(Path(__file__).resolve())] + (argv if argv is not None else sys.argv[1:])
            ),
        ]
        print("\n".join(lines))
        if not c_identical:
            print("bench_bake: the hoisted and literal C variants differ", file=sys.stderr)
            return 1
        worst = max(v for d in diffs.values() for v in d.values())
        if not worst <= 2e-6:
            print(f"bench_bake: hzval's output differs from the peer's by {worst:.3g}", file=sys.stderr)
            return 1
        return 0
    finally:
        if args.keep is None:
            shutil.rmtree(work, ignore_errors=True)


def fmt(values: list[float]) -> str:
    return " ".join(f"{v:.3f}" for v in values)


def files_json(path: Path) -> dict[str, float]:
    """The stage timings that ``hzval bake`` recorded in ``bake.json``."""
    import json

    return json.loads(path.read_text()).get("timings_s", {})


if __name__ == "__main__":
    sys.exit(main())
