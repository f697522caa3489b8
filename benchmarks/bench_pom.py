"""Benchmark: ray-marched height-field shadows (hzval.techniques.pom) against the steps, beside horizon
mapping.

Builds the built-in brick wall (``hzval.materials.bricks.bricks(SIZE)``, depth 0.05,
wrap, shadow + diffuse, elevation 30, ``--spp`` samples per pixel) and its
converged truth (``--truth-spp`` shadow rays), then for each step count and
both variants renders the sweep's azimuths -60..+60 (one warm-up frame
first) and prints, side by side in one run: the factor's time per frame
(kernels synchronised, mean over the frames), the whole frame's (factor and
the shared unshadowed shading), the horizon map's frame time and their
ratio, and the mean |F - V| against the truth. Kernels compiled after each
variant's first warm-up must be 0: the step count and every per-frame value are
opaque (the script exits 1 otherwise). Then the march's skip table at each reach
(``--reaches``) against none, side by side: its factor time and whether every F
is bit for bit the full march's (exit 1 otherwise).

Usage::

    .venv/bin/python benchmarks/bench_pom.py [--size 512] [--frames 9] [--spp 16] [--truth-spp 64]
                                             [--steps 4,8,16,32,64] [--reaches 1,2,3,4,8]
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
    ap.add_argument("--truth-spp", type=int, default=64)
    ap.add_argument("--steps", default="4,8,16,32,64")
    ap.add_argument("--reaches", default="1,2,3,4,8", help="skip-table reaches (texels) to time")
    args = ap.parse_args(argv)

    import dataclasses

    from hzval.bake import maps as bake
    from hzval.core import backend
    from hzval.scene import spec as sc
    from hzval.techniques import horizon, pom, surface
    from hzval.truth import plane as truth

    variant = backend.variant()
    import drjit as dr

    scene = sc.Scene(material=sc.MaterialSpec(size=args.size), spp=args.spp).validate()
    height = sc.load_material_height(scene.material).height
    baked = bake.bake(height, bake.BakeParams(depth=scene.material.depth, boundary=scene.material.boundary))
    azimuths = [float(a) for a in np.linspace(-60, 60, args.frames)]
    tr = truth.Truth(dataclasses.replace(scene, spp=args.truth_spp, seed=1), height)
    V = {az: tr.render(az).layers["visibility"] for az in azimuths}
    plain = surface.Unshadowed(scene, baked)
    horizon = horizon.Horizon(scene, baked)
    dr.set_flag(dr.JitFlag.KernelHistory, True)

    def timed(fn):
        dr.kernel_history()  # clear
        out, maes = [], []
        for az in azimuths:
            dr.sync_thread()
            t0 = time.perf_counter()
            F = fn(az)
            dr.sync_thread()
            out.append(time.perf_counter() - t0)
            maes.append(float(np.abs(F - V[az]).mean()))
        hist = dr.kernel_history()
        compiled = sum(1 for k in hist if k.get("type") == dr.KernelType.JIT and not k.get("cache_hit", True))
        return 1e3 * float(np.mean(out)), float(np.mean(maes)), compiled

    horizon.render(-60.0)
    h_ms, h_mae, _ = timed(lambda az: horizon.render(az).layers["factor"])
    cmd = ".venv/bin/python benchmarks/bench_pom.py " + " ".join(
        shlex.quote(a) for a in (argv or sys.argv[1:])
    )
    print(f"# {cmd.strip()}")
    print(
        f"# {args.size}x{args.size} bricks, wrap, elevation 30, {args.spp} spp, {args.frames} frames, "
        f"truth {args.truth_spp} spp, variant {variant}"
    )
    print(
        f"{'technique':<28} {'factor ms':>10} {'frame ms':>10} {'x horizon':>10} {'|F-V|':>8} {'compiled':>9}"
    )
    print(f"{'horizon map (exact)':<28} {'':>10} {h_ms:10.2f} {1.0:10.2f} {h_mae:8.4f} {'':>9}")
    bad = False
    for v in pom.VARIANTS:
        first = True  # each variant is a kernel of its own
        for steps in (int(s) for s in args.steps.split(",")):
            m = pom.RayMarchShadow(scene, height, steps=steps, variant=v, unshadowed=plain)
            if first:
                m.render(-60.0)  # compile (or load) the kernels once: later step counts reuse them
            f_ms, mae, compiled = timed(lambda az: m.factor(az, scene.light.elevation_deg))  # noqa: B023 - called within this iteration
            r_ms, _, compiled2 = timed(lambda az: m.render(az).layers["factor"])  # noqa: B023 - called within this iteration
            bad |= (compiled + compiled2 > 0) and not first
            first = False
            print(
                f"{f'pom {v}, {steps} steps':<28} {f_ms:10.2f} {r_ms:10.2f} {r_ms / h_ms:10.2f} {mae:8.4f} "
                f"{compiled + compiled2:9d}"
            )
    bad |= _skip_table_table(args, scene, height, plain, azimuths, timed)
    return 1 if bad else 0


def _skip_table_table(args, scene, height, plain, azimuths, timed) -> bool:
    """The march's skip table (``pom.SKIP_RADIUS``) at each reach against none, side by side at the
    default steps: factor ms, the ratio, and whether every F is bit for bit the full march's."""
    from hzval.techniques import pom

    default = pom.SKIP_RADIUS
    print(f"\n# skip table (pom.SKIP_RADIUS, default {default:g}) at {pom.DEFAULT_STEPS} steps")
    print(f"{'variant':<8} {'reach':>8} {'factor ms':>10} {'x none':>8} {'F as none':>10}")
    bad = False
    try:
        for v in pom.VARIANTS:
            reference = None
            for reach in (None, *(float(r) for r in args.reaches.split(","))):
                pom.SKIP_RADIUS = reach
                m = pom.RayMarchShadow(scene, height, variant=v, unshadowed=plain)
                m.factor(-60.0, scene.light.elevation_deg)  # compile or load
                f_ms, _, _ = timed(lambda az: m.factor(az, scene.light.elevation_deg))  # noqa: B023
                F = [m.factor(az, scene.light.elevation_deg).tobytes() for az in azimuths]
                if reference is None:
                    reference, none_ms = F, f_ms
                same = F == reference
                bad |= not same
                label = "none" if reach is None else f"{reach:g}"
                verdict = "same" if same else "DIFFERS"
                print(f"{v:<8} {label:>8} {f_ms:10.2f} {f_ms / none_ms:8.2f} {verdict:>10}")
    finally:
        pom.SKIP_RADIUS = default
    return bad


if __name__ == "__main__":
    sys.exit(main())
