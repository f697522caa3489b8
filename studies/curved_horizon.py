"""Does a curvature correction of the horizon map help? (issue 29, item 2; docs/models.md).

On the study's caps and bowls the curvature is one number, ``1/R`` (+ convex), along every
direction: the ``horizon-curved`` technique (:mod:`hzval.techniques.horizon_curved`: the stored sines plus
their change on a surface of that normal curvature, searched again over the bake's radius) is given
each case's ``1/R``. Each case is measured in the band of local light
elevations (:mod:`hzval.studies.curvature_band`: 16 lights, per texel, one standard error from the lights'
spread), the corrected map beside the baked one on the same pixels and lights, at the camera's hits
(|F - V|) and at the truth's (the floor); ``gain`` = baked - corrected, paired per light.

    python studies/curved_horizon.py [HEIGHT.png] [--material bricks] [--size 128] [--depth 0.1]
                                        [--cases cap+0.5,cap+1,cap+2,bowl+1,bowl+2,flat] [--control 2,-1]
                                        [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def corrected(setup, curvature: float) -> dict:
    """``{"horizon-curved": (camera, truth)}``: the ``horizon-curved`` technique (the registry's) for
    the case's ``curvature`` (texture widths^-1) on the sweep's bake, at the camera's hits and at
    the truth's."""
    from hzval.scene import spec as sc
    from hzval.techniques import registry as technique

    base = next(t for t in setup.techniques if t.name == "horizon")
    scn = base.scene
    height = sc.load_material_height(scn.material).height
    albedo = sc.load_albedo(scn.material, *height.shape)

    def make(at):
        context = technique.Context(scn, height, base.bake, albedo, points=setup.truth.samples(at))
        return technique.get("horizon-curved").build(context, curvature=curvature)

    return {"horizon-curved": (make("camera"), make("truth"))}


def gain(case: dict) -> dict:
    """Baked minus corrected band |F - V| and floor, per light, as ``{mean, se}``."""
    from hzval.studies import curvature_band

    t = case["techniques"]
    out = {}
    for key in ("mae", "floor"):
        on = np.isfinite(t["horizon"][key]) & np.isfinite(t["horizon-curved"][key])
        a, b = (curvature_band.frame_means(t[n][key], on) for n in ("horizon", "horizon-curved"))
        out[key] = {
            "horizon": curvature_band.summary(a),
            "horizon-curved": curvature_band.summary(b),
            "gain": curvature_band.summary(a - b),
        }
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("height", nargs="?", default=None)
    ap.add_argument("--material", default="bricks")
    ap.add_argument("--size", type=int, default=None)
    ap.add_argument("--depth", type=float, default=None)
    ap.add_argument("--cases", default="cap+0.5,cap+1,cap+2,bowl+1,bowl+2,flat")
    ap.add_argument(
        "--control", default="2,-1", help="1/R values whose correction is also tried on the flat patch"
    )
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    from hzval.commands import models as models_command
    from hzval.scene import spec as sc
    from hzval.studies import curvature_band

    size = args.size if args.size is not None else (None if args.height else 128)
    scene = sc.override(
        sc.Scene(),
        height=args.height or args.material,
        size=size,
        depth=args.depth,
        camera="orthographic",
        resolution=(128, 128),
        spp=2,
    )  # hzval models' defaults
    wanted = args.cases.split(",")
    cases = {name: (curvature, spec) for name, curvature, spec in models_command.cases()}
    runs = [(n, cases[n][0], cases[n][1], cases[n][0]) for n in wanted if n in cases]
    for c in args.control.split(",") if args.control else []:
        # the control: the correction of 1/R = c on the flat patch, where it is wrong
        runs.append((f"flat@{float(c):+g}", 0.0, cases["flat"][1], float(c)))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, curvature, spec, corrected_for in runs:
            scn = curvature_band.band_scene(
                models_command.case_scene(scene, Path(tmp), name.split("@")[0], spec)
            )
            case = curvature_band.measure(
                scn,
                Path(tmp) / name.split("@")[0],
                extra=lambda setup: corrected(setup, corrected_for),  # noqa: B023 - called within this iteration
            )
            g = gain(case)
            rows.append({"case": name, "curvature": curvature, "corrected_for": corrected_for, **g})
            m, f = g["mae"], g["floor"]
            print(
                f"{name:8} 1/R {curvature:+.3f}  |F-V| {m['horizon']['mean']:.4f} -> "
                f"{m['horizon-curved']['mean']:.4f} "
                f"gain {m['gain']['mean']:+.4f} ± {m['gain']['se']:.4f}   floor {f['horizon']['mean']:.4f} "
                "-> "
                f"{f['horizon-curved']['mean']:.4f} gain {f['gain']['mean']:+.4f} ± {f['gain']['se']:.4f}",
                flush=True,
            )
    if args.json:
        args.json.write_text(
            json.dumps({"height": args.height or args.material, "depth": args.depth, "rows": rows}, indent=1)
        )


if __name__ == "__main__":
    main()
