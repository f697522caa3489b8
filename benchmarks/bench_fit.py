"""Benchmark: fitting the horizon map to the truth (hzval.techniques.fitted.fit) at 512 x 512, epoch by epoch.

Builds a built-in material (``--material``, default the brick wall) at
``--size`` (default 512), bakes it (seed method, radius 16), renders the
truth's V for the default training lights (elevations 10/20/40/60, azimuths
0..345 by 15: 96 lights) and the held-out ones, and fits. Prints for each
epoch (a pass over every light, ``steps`` Adam steps) its seconds, seconds
per light (one forward and backward pass of the horizon technique's kernel)
and the loss; then the truth's, the fit's and the evaluation's seconds, the
memory estimate (:func:`hzval.techniques.fitted.training.estimate_bytes`) beside the peak RSS, and
|F - V| baked against fitted. Wall time and the process's user + sys CPU time
are both printed: on a machine shared with others, wall time is what the load
allowed, CPU time what the fit cost. The issue's bar: the whole fit of a
512 x 512 material within 120 s here.

Usage::

    .venv/bin/python benchmarks/bench_fit.py [--size 512] [--material bricks] [--storage float] [--fit-k]
        [--spp 16] [--train-spp N] [--lights SPEC]
"""

from __future__ import annotations

import argparse
import resource
import time

from hzval.techniques.fitted import training as fitted_training


def _cpu() -> float:
    """This process's user + sys CPU seconds (its threads included)."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--material", default="bricks")
    ap.add_argument("--storage", default="float")
    ap.add_argument("--fit-k", action="store_true")
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument(
        "--train-spp", type=int, default=None, help="default: hzval.techniques.fitted.training.training_spp"
    )
    ap.add_argument(
        "--lights",
        default=None,
        help="training lights (default: hzval.techniques.fitted.training.TRAINING_LIGHTS)",
    )
    args = ap.parse_args(argv)

    from hzval.bake import maps as bake
    from hzval.core import backend
    from hzval.scene import spec as sc
    from hzval.techniques.fitted import fit

    backend.variant()
    scene = sc.override(sc.Scene(), height=args.material, size=args.size, spp=args.spp)
    hm = sc.load_material_height(scene.material)
    baked = bake.bake(
        hm.height, bake.BakeParams(depth=scene.material.depth, boundary=scene.material.boundary).validate()
    )
    lights = fitted_training.parse_lights(args.lights or fitted_training.TRAINING_LIGHTS)
    t0, c0 = time.perf_counter(), _cpu()
    r = fit.fit(
        hm.height,
        baked,
        scene,
        lights=lights,
        storage=args.storage,
        fit_k=args.fit_k,
        train_spp=args.train_spp,
        progress=False,
    )
    total, cpu = time.perf_counter() - t0, _cpu() - c0
    per_step = max(1, r.steps // max(1, r.epochs))
    print(
        f"{args.material} {args.size}x{args.size}, {args.spp} spp (training {r.settings['train_spp']}), "
        f"{len(lights)} training lights, "
        f"storage {args.storage}, fit_k {args.fit_k}, {per_step} Adam steps an epoch"
    )
    print("epoch  seconds  s/light  loss")
    for i, (s, loss) in enumerate(zip(r.epoch_seconds, r.loss)):
        print(f"{i + 1:5d}  {s:7.2f}  {s / len(lights):7.4f}  {loss:.5f}")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    est = fitted_training.estimate_bytes(args.size, args.size, args.spp, len(lights))
    print(
        f"truth {r.seconds['truth']:.1f} s, fit {r.seconds['fit']:.1f} s ({r.epochs} epochs, "
        f"{'converged' if r.converged else 'not converged'}), evaluate {r.seconds['evaluate']:.1f} s, "
        f"total {total:.1f} s wall, {cpu:.1f} s CPU (user + sys); k {r.k:.3g}"
    )
    c = r.seconds["cpu"]
    print(f"CPU (user + sys): truth {c['truth']:.1f} s, fit {c['fit']:.1f} s, evaluate {c['evaluate']:.1f} s")
    g = r.settings.get("guard")
    if g:
        print(f"guard: {100 * g['kept_fitted']:.1f} % of texels kept fitted, {g['rounds']} rounds")
    print(f"memory: estimate {est / 2**30:.2f} GiB, peak RSS {peak / 2**30:.2f} GiB")
    for w, m in r.mae.items():
        print(
            f"{w}: |F-V| baked {m['baked']:.4f}, fitted {m['fitted']:.4f} ({m['fitted'] / m['baked']:.2f}x)"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
