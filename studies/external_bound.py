"""Measure the bound of hzval.io.external.DESCRIBES_CORRELATION: |s - exact| and the correlation with the
exact horizons of the best convention, for a horizon map of the right height map and of a different one.

For every pair of built-in materials (A, B) at one size: hzval's seed bake of B (and of A), stored
as 8-bit sines as an engine would, detected against hzval's exact bake of A (hzval.io.external.detect,
every convention tried). The right map (B = A) must correlate above the bound, every wrong one below; the |s
- exact|
column shows why an absolute bound on it cannot tell them apart.
Also a map of A in another convention (+y down) and a map of A with a radius of 4 texels, which are
right maps.

    python studies/external_bound.py [--size 64]
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np

from hzval import materials
from hzval.bake import maps as bake
from hzval.io import external
from hzval.scene import spec as sc


def _height(name: str, size: int) -> tuple[np.ndarray, float, str]:
    m = materials.get(name)
    hm = sc.load_material_height(sc.MaterialSpec(height=name, size=size))
    return hm.height, m.depth, m.boundary


def _u8(sines: np.ndarray) -> np.ndarray:
    """8-bit storage of sines in [0, 1] (as a PNG holds them), read back in [0, 1]."""
    return np.round(np.clip(sines, 0, 1) * 255) / 255


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=64)
    args = ap.parse_args(argv)
    names = materials.names()
    maps = {n: _height(n, args.size) for n in names}
    exact = {
        n: bake.bake(h, bake.BakeParams(depth=d, boundary=b, method="exact").validate()).horizon
        for n, (h, d, b) in maps.items()
    }
    seed = {
        n: bake.bake(h, bake.BakeParams(depth=d, boundary=b).validate()).horizon
        for n, (h, d, b) in maps.items()
    }
    right, wrong = [], []
    print(f"{'height map':13s} {'horizon map of':15s} best |s - exact|  correlation")
    for a in names:
        for b in names:
            raw = _u8(seed[b])
            found = external.detect(raw, exact[a], external.Encoding())
            best = min(r["mae"] for r in found["scores"])
            rel = found["correlation"]
            (right if a == b else wrong).append(rel)
            print(f"{a:13s} {b:15s} {best:.4f}  {rel:.3f}{'  (right)' if a == b else ''}")
        h, d, bnd = maps[a]
        near = bake.bake(h, bake.BakeParams(depth=d, boundary=bnd, radius=4, angles=32).validate()).horizon
        flipped = external.to_hzval(_u8(seed[a]), dataclasses.replace(external.Encoding(), y="down"))
        for label, raw in (("radius 4", _u8(near)), ("+y down", _u8(flipped))):
            found = external.detect(raw, exact[a], external.Encoding())
            best = min(r["mae"] for r in found["scores"])
            rel = found["correlation"]
            right.append(rel)
            print(f"{a:13s} {a + ', ' + label:15s} {best:.4f}  {rel:.3f}  (right)")
    print(
        f"\ncorrelation: right maps at least {min(right):.3f}; wrong maps at most {max(wrong):.3f} "
        f"(median {np.median(wrong):.3f}); bound {external.DESCRIBES_CORRELATION}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
