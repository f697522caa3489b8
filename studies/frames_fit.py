"""Study: is the fitted horizon map worse than the baked one on any frame? (docs/fit.md)

Fits a height map (a photo: 16-bit grey PNG or any image hzval reads) at ``--depth`` and
``--boundary`` with :func:`hzval.techniques.fitted.fit.fit` (its options as JSON, e.g. ``'{"guard": 0.25}'``,
``'{"constrain": 0}'``, ``'{"train_spp": 4}'``), then renders the baked and the fitted map with the
horizon technique at each held-out light set (default: the issue's, 25 degrees at -52.5..52.5 by
15, and the default sweep's, 30 degrees at -60..60 by 15) against the truth at the scene's samples,
and prints per set the fitted/baked ratio of mean |F - V|, how many frames got worse, the smallest
margin and each frame's pair; with ``--guards`` also the map guarded at each tolerance
(:func:`hzval.techniques.fitted.guard.guard`) from the same fit.

Usage::

    .venv/bin/python studies/frames_fit.py PHOTO.png [--lights SPEC] [--options JSON] [--guards 0.25,1]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time

from hzval.techniques.fitted import training as fitted_training


def _frames(fs, bake, sines, k, held):
    import numpy as np

    from hzval.techniques import horizon

    ap = horizon.Horizon(fs, dataclasses.replace(bake, horizon=sines), None, k=k)
    return {
        spec: [
            float(np.mean(np.abs(ap.render(a, elevation_deg=e).layers["factor"].astype(np.float64) - v)))
            for (e, a), v in zip(ls, V)
        ]
        for spec, (ls, V) in held.items()
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("height")
    ap.add_argument("--depth", type=float, default=0.05)
    ap.add_argument("--boundary", default="wrap")
    ap.add_argument(
        "--lights",
        default=None,
        help="training lights (default hzval.techniques.fitted.training.TRAINING_LIGHTS)",
    )
    ap.add_argument(
        "--held", default="25@-52.5:52.5:15;30@-60:60:15", help="held-out light sets, ';'-separated"
    )
    ap.add_argument(
        "--options", default="{}", help="more keyword arguments of hzval.techniques.fitted.fit.fit, as JSON"
    )
    ap.add_argument("--guards", default="", help="guard tolerances to try on the same fit")
    args = ap.parse_args(argv)

    from hzval.bake import maps as bake
    from hzval.core import backend
    from hzval.io import storage as hz_storage
    from hzval.scene import spec as sc
    from hzval.techniques.fitted import fit

    backend.variant()
    scene = sc.override(sc.Scene(), height=args.height, depth=args.depth, boundary=args.boundary)
    hm = sc.load_material_height(scene.material)
    baked = bake.bake(hm.height, bake.BakeParams(depth=args.depth, boundary=args.boundary).validate())
    t0 = time.perf_counter()
    r = fit.fit(
        hm.height,
        baked,
        scene,
        lights=args.lights or fitted_training.TRAINING_LIGHTS,
        held_out="",
        progress=False,
        **json.loads(args.options),
    )
    print(
        f"{args.height}: fit {time.perf_counter() - t0:.1f} s, {r.epochs} epochs, training "
        f"{r.mae['training']}"
    )
    held = {
        spec: (
            fitted_training.parse_lights(spec),
            fitted_training.visibility(scene, hm.height, fitted_training.parse_lights(spec)),
        )
        for spec in args.held.split(";")
    }
    fs = fitted_training.fit_scene(scene)
    base = _frames(fs, baked, baked.horizon, r.k, held)
    maps = [("fitted", r.horizon, None)]
    if args.guards:
        train = dataclasses.replace(scene, spp=r.settings["train_spp"])
        V = fitted_training.visibility(train, hm.height, r.lights)
        for tol in (float(t) for t in args.guards.split(",")):
            g, rec = fit.guarded(
                train, baked, hz_storage.get(r.storage), V, r.lights, r.horizon, r.k, r.k, tol
            )
            maps.append((f"guard {tol:g}", g, rec))
    for label, sines, rec in maps:
        got = _frames(fs, baked, sines, r.k, held)
        for spec, b in base.items():
            f = got[spec]
            worse = sum(x > y for x, y in zip(f, b))
            print(
                f"  {label} {spec}: fitted/baked {sum(f) / sum(b):.3f}, worse on {worse}/{len(b)}, smallest "
                "margin "
                f"{min(y - x for x, y in zip(f, b)):+.6f}; "
                + " ".join(f"{y:.4f}/{x:.4f}" for x, y in zip(f, b))
            )
        if rec:
            print(f"    guard: {rec}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
