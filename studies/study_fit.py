"""Study: the fitted horizon map on every built-in material (docs/fit.md).

For each material at ``--size`` (default 256; its own depth and boundary), ``hzval fit``'s
:func:`hzval.techniques.fitted.fit.fit` with the default training lights and, as held-out lights, the
default sweep's
(elevation 30, azimuths -60..60 by 15: the same samples and the same metric as the sweep's
``visibility_mae``), for each variant: float (every material) and, for the ``--more`` materials,
``--fit-k``, ``--storage u8`` and ``--storage bc7`` (each stored map against the bake stored alike). Prints
one table row per material and variant and writes the records as JSON.

Usage::

    .venv/bin/python studies/study_fit.py [--size 256] [--materials a,b] [--more bricks,gravel,spikes]
                                          [--out study.json]
"""

from __future__ import annotations

import argparse
import json


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--materials", default=None)
    ap.add_argument("--variants", default="float", help="variants of every material")
    ap.add_argument(
        "--more", default="bricks,gravel,spikes", help="materials also fitted with --more-variants"
    )
    ap.add_argument("--more-variants", default="fit-k,u8,bc7")
    ap.add_argument("--out", default="study_fit.json")
    args = ap.parse_args(argv)

    from hzval import materials
    from hzval.bake import maps as bake
    from hzval.core import backend
    from hzval.scene import spec as sc
    from hzval.techniques.fitted import fit

    backend.variant()
    names = args.materials.split(",") if args.materials else materials.names()
    rows = []
    print(
        "material      variant  k      sweep |F-V| baked  fitted  ratio  | training baked  fitted  | epochs "
        " fit s"
    )
    for name in names:
        scene = sc.override(sc.Scene(), height=name, size=args.size)
        hm = sc.load_material_height(scene.material)
        baked = bake.bake(
            hm.height,
            bake.BakeParams(depth=scene.material.depth, boundary=scene.material.boundary).validate(),
        )
        variants = args.variants.split(",") + (
            args.more_variants.split(",") if name in args.more.split(",") else []
        )
        for v in variants:
            storage = v if v in ("u8", "bc7") else "float"
            r = fit.fit(
                hm.height,
                baked,
                scene,
                held_out="30@-60:60:15",
                storage=storage,
                fit_k=v == "fit-k",
                progress=False,
            )
            m, t = r.mae["held_out"], r.mae["training"]
            rows.append(
                {
                    "material": name,
                    "variant": v,
                    "k": r.k,
                    "sweep": m,
                    "training": t,
                    "epochs": r.epochs,
                    "converged": r.converged,
                    "seconds": r.seconds,
                }
            )
            print(
                f"{name:12s}  {v:7s}  {r.k:5.2f}  {m['baked']:.4f}             {m['fitted']:.4f}  "
                f"{m['fitted'] / m['baked']:.2f}   | {t['baked']:.4f}          {t['fitted']:.4f}  | "
                f"{r.epochs:6d}  {r.seconds['fit']:.0f}",
                flush=True,
            )
            with open(args.out, "w") as fh:
                json.dump({"size": args.size, "rows": rows}, fh, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
