"""Every technique on a turned map, at the turned samples: is each one invariant by itself? (issue 27)

A map mirrored, rotated by 90 or 180 degrees or transposed, lit from the turned light, is the same
surface turned; a sweep of it samples each pixel at other random points, whose noise hides a small
asymmetry (and fakes one: two seeds of one map move pom's |F - V| by 5% on a 128 x 128 crop). Here
each sample of the turned map is at the turned position of the as-is map's sample, so V and every
default technique's factor must agree pixel by pixel, to rounding::

    python studies/turned_techniques.py [--spp 8] [--sweeps]

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

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository: tests.oracles
from tests.oracles.turned_techniques import AS_IS, TURNS, crop, turned_frames  # noqa: E402


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
                f"{k} {np.abs(got[k] - got['V']).mean():.5f} "
                f"(max pixel diff {np.abs(got[k] - ref[k]).max():.1e})"
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
