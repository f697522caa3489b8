"""Every technique on a turned map, at the turned samples: is each one invariant by itself? (issue 27)

A map mirrored, rotated by 90 or 180 degrees or transposed, lit from the turned light, is the same
surface turned; a sweep of it samples each pixel at other random points, whose noise hides a small
asymmetry (and fakes one: two seeds of one map move pom's |F - V| by 5% on a 128 x 128 crop). Here
each sample of the turned map is at the turned position of the as-is map's sample, so V and every
default technique's factor must agree pixel by pixel, to rounding::

    python tests/oracles/turned_techniques.py [--spp 8] [--sweeps]

``--sweeps`` adds whole sweeps (32 spp, the sweep's own samples) of the as-is map at seeds 1-4 and of
each turn at seed 1: the noise between seeds beside the spread between turns.
Map: the 128 x 128 crop ``[10:138, 20:148]`` of ``materials.generate("bricks", 192, seed=6)``, depth
0.05, hard light at 30 degrees from azimuth 20 (turned with the map).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

#: (name, the map turned, the light's azimuth turned, where a tangent-space point (x, y) of a rows x
#: cols tile goes): x runs along the columns and y up the rows, so np.rot90 turns counterclockwise.
TURNS = (
    ("mirror", lambda h: h[:, ::-1], lambda a: 180.0 - a, lambda x, y, r, c: (c - x, y)),
    ("rot90", lambda h: np.rot90(h), lambda a: a + 90.0, lambda x, y, r, c: (r - y, x)),
    ("rot180", lambda h: np.rot90(h, 2), lambda a: a + 180.0, lambda x, y, r, c: (c - x, r - y)),
    ("transpose", lambda h: h.T, lambda a: -90.0 - a, lambda x, y, r, c: (r - y, c - x)),
)
AS_IS = ("as-is", lambda h: h, lambda a: a, lambda x, y, r, c: (x, y))


def crop():
    from hzval import materials

    return np.ascontiguousarray(materials.generate("bricks", 192, seed=6).height[10:138, 20:148])


def turned_frames(h, boundary: str, azimuth: float, spp: int, turn=AS_IS, depth: float = 0.05) -> dict:
    """``{"V": truth's visibility, technique: factor}`` of ``h`` turned by ``turn`` (a :data:`TURNS`
    entry), lit from the turned light, each sample at the turned position of the as-is map's sample
    (:func:`hzval.scene.camera.sample_positions`, seed 1); each image in the as-is map's pixel order."""
    from hzval.bake import maps as bake
    from hzval.scene import lookup
    from hzval.scene import spec as sc
    from hzval.scene.camera import sample_positions
    from hzval.techniques import registry as technique
    from hzval.truth.plane import Truth

    _, f, az, point = turn
    rows, cols = h.shape
    ht = np.ascontiguousarray(f(h))
    perm = f(np.arange(rows * cols).reshape(rows, cols)).ravel()  # turned pixel -> as-is pixel
    light = az(azimuth) % 360.0
    scene = sc.override(
        sc.Scene(),
        depth=depth,
        boundary=boundary,
        elevation=30.0,
        spp=spp,
        effects="shadow",
        azimuths=str(light),
    ).validate()
    x, y = (
        np.asarray(a, np.float64).reshape(rows * cols, spp)[perm]
        for a in sample_positions(rows, cols, scene.camera, spp, 1)
    )
    x, y = point(x, y, rows, cols)
    x, y = x.astype(np.float32).ravel(), y.astype(np.float32).ravel()
    out = {"V": Truth(scene, ht, positions=(x, y)).render(light).layers["visibility"]}
    baked = bake.bake(ht, bake.BakeParams(depth=depth, boundary=boundary).validate())
    like = lookup.Samples(np.zeros(1, np.float32), np.zeros(1, np.float32), *ht.shape, spp)
    ctx = technique.Context(scene, ht, baked, None, points=lookup.from_points(x, y, like))
    for t in technique.select(None, scene):
        out[t.name] = t.build(ctx).render(light).layers["factor"]
    inverse = np.empty_like(perm)
    inverse[perm] = np.arange(perm.size)
    return {k: v.ravel()[inverse] for k, v in out.items()}


def sweep_scores(h, boundary: str, turn, seed: int, out: Path) -> dict:
    """Every technique's |F - V| from a whole sweep (32 spp) of ``h`` turned by ``turn``."""
    from hzval.pipeline import sweep
    from hzval.scene import spec as sc

    name, f, az, _ = turn
    path = out / f"{boundary}-{name}.npy"
    np.save(path, np.ascontiguousarray(f(h)))
    scene = sc.override(
        sc.Scene(),
        height=str(path),
        depth=0.05,
        boundary=boundary,
        elevation=30.0,
        azimuths=str(az(20.0) % 360.0),
        spp=32,
        seed=seed,
    )
    m = sweep.run(scene, out / f"{boundary}-{name}-{seed}", progress=False)
    return {k: v["visibility_mae"] for k, v in m["frames"][0]["techniques"].items()}


def main(argv=None) -> int:
    import hzval

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--spp", type=int, default=8)
    p.add_argument("--sweeps", action="store_true")
    args = p.parse_args(argv)
    hzval.init()
    h = crop()
    for boundary in ("open", "wrap"):
        ref = turned_frames(h, boundary, 20.0, args.spp)
        for turn in (AS_IS,) + TURNS:
            got = ref if turn is AS_IS else turned_frames(h, boundary, 20.0, args.spp, turn)
            cells = [f"V {got['V'].mean():.5f}"] + [
                f"{k} {np.abs(got[k] - got['V']).mean():.5f} (max pixel diff "
                f"{np.abs(got[k] - ref[k]).max():.1e})"
                for k in got
                if k != "V"
            ]
            print(f"{boundary} {turn[0]:9}", "  ".join(cells), flush=True)
    if args.sweeps:
        with tempfile.TemporaryDirectory() as tmp:
            for boundary in ("open", "wrap"):
                runs = [(AS_IS, s) for s in (1, 2, 3, 4)] + [(t, 1) for t in TURNS]
                for turn, seed in runs:
                    scores = sweep_scores(h, boundary, turn, seed, Path(tmp))
                    print(
                        f"sweep {boundary} {turn[0]:9} seed {seed}",
                        "  ".join(f"{k} {v:.5f}" for k, v in scores.items()),
                        flush=True,
                    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
