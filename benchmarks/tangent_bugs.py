"""Each tangent bug's horizon |F - V| on the cube, on its mirrored (-x, w = -1) and unmirrored faces.

    PYTHONPATH=. python benchmarks/tangent_bugs.py [--height bricks] [--size 48] [--spp 2]

The cube in perspective from azimuth 150 (it shows the mirrored -x face), six lights at 30 degrees;
the truth is the same for every bug (hzval.tangent_bugs), only the techniques' frames change.
"""

import argparse

import numpy as np

from hzval import model, scene as S, tangent_bugs, technique
from hzval.bake import BakeParams, bake
from hzval.model_truth import ModelTruth


def errors(height: str, bug: str, n: int, spp: int, res: int):
    """``(|F - V| per pixel, mean over the lights; w per sample; seen)`` for one bug."""
    sc = S.override(S.Scene(), height=height, size=n, depth=0.08, spp=spp, azimuths="0,60,120,180,240,300",
                    boundary="wrap", mesh="cube", camera="perspective", view_elevation=35, view_azimuth=150,
                    resolution=(res, res), tangent_bug=bug)
    h = S.load_material_height(sc.material).height
    mt = ModelTruth(sc, h, model.load("cube"))
    pts = mt.samples()
    f = pts.frames
    w = np.sign(np.sum(np.cross(f[:, 6:9], f[:, 0:3]) * f[:, 3:6], axis=1))
    b = bake(h, BakeParams(depth=sc.material.depth, boundary=sc.material.boundary))
    tech = technique.get("horizon").build(technique.Context(sc, h, b, S.load_albedo(sc.material, *h.shape),
                                                            points=pts))
    e = [np.abs(tech.render(az).layers["factor"] - mt.render(az).layers["visibility"])
         for az in sc.light.azimuths_deg]
    return np.mean(e, axis=0), w.reshape(-1, spp), mt.seen


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--height", default="bricks")
    ap.add_argument("--size", type=int, default=48)
    ap.add_argument("--spp", type=int, default=2)
    ap.add_argument("--resolution", type=int, default=64)
    a = ap.parse_args()
    _, w, seen = errors(a.height, "none", a.size, a.spp, a.resolution)
    mirrored = (w < 0).all(axis=1).reshape(seen.shape) & seen
    plain = (w > 0).all(axis=1).reshape(seen.shape) & seen
    print(f"{a.height} {a.size}^2, {mirrored.sum()} mirrored and {plain.sum()} unmirrored pixels")
    print(f"{'bug':18s} {'mirrored':>9s} {'unmirrored':>11s}")
    for bug in tangent_bugs.NAMES:
        e, _, _ = errors(a.height, bug, a.size, a.spp, a.resolution)
        print(f"{bug:18s} {e[mirrored].mean():9.4f} {e[plain].mean():11.4f}")


if __name__ == "__main__":
    main()
