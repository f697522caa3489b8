"""Benchmark: fitting each per-pixel technique's textures (hzval.techniques.fitted.textures) against
fitting the horizon map (hzval.techniques.fitted.fit), side by side on one material.

Bakes a built-in material (``--material``, default the brick wall) at ``--size`` (default 512),
renders nothing twice: each fit renders its own truth, as ``hzval fit`` does. Prints per fit its
wall and CPU seconds (truth, fit, evaluation), |F - V| baked and fitted on the training and
held-out lights, and the ratio of each technique's whole fit to the horizon fit's, measured in the
same run. The issue's bar: a technique's fit at 512 x 512 takes at most as long as the horizon's.

Usage::

    .venv/bin/python benchmarks/bench_fit_textures.py [--size 512] [--material bricks] [--spp 16]
        [--techniques microshadow-filament,microshadow-hdrp,bent-cone,ssbump]
"""

from __future__ import annotations

import argparse
import resource
import time


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--material", default="bricks")
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--techniques", default="microshadow-filament,microshadow-hdrp,bent-cone,ssbump")
    args = ap.parse_args(argv)

    from hzval.bake import maps as bake
    from hzval.core import backend
    from hzval.scene import spec as sc
    from hzval.techniques.fitted import fit, textures

    backend.variant()
    scene = sc.override(sc.Scene(), height=args.material, size=args.size, spp=args.spp)
    hm = sc.load_material_height(scene.material)
    baked = bake.bake(
        hm.height, bake.BakeParams(depth=scene.material.depth, boundary=scene.material.boundary).validate()
    )
    rows = []
    t0, c0 = time.perf_counter(), _cpu()
    r = fit.fit(hm.height, baked, scene, progress=False)
    rows.append(("horizon", time.perf_counter() - t0, _cpu() - c0, r.seconds, r.mae, f"{r.epochs} epochs"))
    for name in args.techniques.split(","):
        t0, c0 = time.perf_counter(), _cpu()
        r = textures.fit_textures(hm.height, baked, scene, name, progress=False)
        how = " then ".join(r.options["steps"]) + (f" ({r.epochs} epochs)" if r.epochs else "")
        rows.append((name, time.perf_counter() - t0, _cpu() - c0, r.seconds, r.mae, how))
    base_wall, base_cpu = rows[0][1], rows[0][2]
    print(f"{args.material} {args.size}x{args.size}, {args.spp} spp; each fit renders its own truth")
    print(
        f"{'fit':22s} {'wall s':>7s} {'x horizon':>9s} {'CPU s':>7s} {'x horizon':>9s}  truth / fit / eval s"
    )
    for name, wall, cpu, s, _, _ in rows:
        print(
            f"{name:22s} {wall:7.1f} {wall / base_wall:9.2f} {cpu:7.1f} {cpu / base_cpu:9.2f}  "
            f"{s['truth']:.1f} / {s['fit']:.1f} / {s['evaluate']:.1f}"
        )
    for name, _, _, _, mae, how in rows:
        figures = "; ".join(f"{w} {m['baked']:.4f} -> {m['fitted']:.4f}" for w, m in mae.items())
        print(f"{name}: |F-V| {figures} ({how})")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    print(f"peak RSS {peak / 2**30:.2f} GiB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
