"""Benchmark: Raudins' terrain shadows (hzval.techniques.terrain) against horizon-map shading, per frame.

Builds the built-in brick wall (``hzval.materials.bricks.bricks(SIZE)``, depth 0.05,
wrap, the default sweep's scene: shadow + diffuse, 16 samples per pixel,
elevation 30), bakes it once, renders one warm-up frame per technique
(compiles the kernels or loads them from Dr.Jit's cache), then times
``--frames`` frames at azimuths -60..+60 degrees:

* terrain, Dr.Jit: the factor alone (sweep + texel + sample kernels), and the
  whole frame (factor + the unshadowed normal-mapped render it multiplies);
* terrain, NumPy: the factor alone (the reference implementation);
* horizon map (``hzval.techniques.horizon``, exact path): the whole shaded frame.

Times are wall times with kernels synchronised and images read back into
NumPy (mean and min over the frames, ms). Kernels compiled after the warm-up
must be 0 (per-frame values are opaque); the script exits 1 otherwise.

Usage::

    .venv/bin/python benchmarks/bench_terrain.py [--size 512] [--frames 9] [--spp 16]
"""

from __future__ import annotations

import argparse
import shlex
import sys
import time

import numpy as np


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--frames", type=int, default=9)
    ap.add_argument("--spp", type=int, default=16)
    args = ap.parse_args(argv)

    from hzval.bake import maps as bake
    from hzval.core import backend
    from hzval.scene import spec as sc
    from hzval.techniques import horizon, surface, terrain

    variant = backend.variant()
    import drjit as dr

    scene = sc.Scene(material=sc.MaterialSpec(size=args.size), spp=args.spp).validate()
    height = sc.load_material_height(scene.material).height
    baked = bake.bake(height, bake.BakeParams(depth=scene.material.depth, boundary=scene.material.boundary))
    ap_ = horizon.Horizon(scene, baked)
    plain = surface.Unshadowed(scene, baked)
    ts = terrain.TerrainShadow(scene, height, bake=baked, unshadowed=plain)
    ref = terrain.TerrainShadow(scene, height, bake=baked, unshadowed=plain, impl="numpy")
    azimuths = np.linspace(-60, 60, args.frames)

    def timed(fn):
        fn(-60.0)  # warm-up: compile or load from the kernel cache
        dr.sync_thread()
        before = len(dr.kernel_history()) if hasattr(dr, "kernel_history") else None
        dr.set_flag(dr.JitFlag.KernelHistory, True)
        dr.kernel_history()  # clear
        out = []
        for az in azimuths:
            dr.sync_thread()
            t0 = time.perf_counter()
            fn(float(az))
            dr.sync_thread()
            out.append(time.perf_counter() - t0)
        hist = dr.kernel_history()
        compiled = sum(1 for k in hist if k.get("type") == dr.KernelType.JIT and not k.get("cache_hit", True))
        dr.set_flag(dr.JitFlag.KernelHistory, False)
        del before
        return np.array(out) * 1e3, compiled

    rows = [
        ("terrain factor, Dr.Jit", lambda az: ts.factor(az)),
        ("terrain factor, NumPy", lambda az: ref.factor(az)),
        ("terrain frame, Dr.Jit (factor + unshadowed render)", lambda az: ts.render(az)),
        ("horizon-map frame (hzval.techniques.horizon, exact)", lambda az: ap_.render(az)),
        ("unshadowed normal-mapped frame", lambda az: ap_.render(az, shadows=False)),
    ]
    cmd = ".venv/bin/python benchmarks/bench_terrain.py " + " ".join(
        shlex.quote(a) for a in (argv or sys.argv[1:])
    )
    print(f"# {cmd.strip()}")
    print(
        f"# {args.size}x{args.size} bricks, wrap, elevation 30, {args.spp} spp, {args.frames} frames, "
        f"variant {variant}"
    )
    print(f"{'what':<52} {'mean ms':>9} {'min ms':>9} {'compiled':>9}")
    bad = False
    for name, fn in rows:
        ms, compiled = timed(fn)
        bad |= compiled > 0 and "NumPy" not in name
        print(f"{name:<52} {ms.mean():9.2f} {ms.min():9.2f} {compiled:9d}")
    a, b = ts.factor(15.0), ref.factor(15.0)
    print(
        f"Dr.Jit vs NumPy factor at +15: max |diff| {np.abs(a - b).max():.2e}, "
        f"mean {np.abs(a - b).mean():.2e}"
    )
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
