"""Benchmark: the geometry of the truth on a model (hzval.geometry.model, hzval.geometry.displace), no
rendering.

Loads (or builds) a base mesh, estimates its cut along the texel grid (hzval.geometry.cells), cuts it for
a height map (smoothed noise: its twisted cells get rings), displaces it, and prints where the time
and the memory go and whether the result is watertight (every welded edge shared by two
triangles, on a closed mesh). The default model is
a 20,480-triangle torus (160 x 64, UVs wrapping both ways) at a 512 x 512 map: the issue's
"20k-triangle model".

Usage::

    python benchmarks/bench_meshes.py [MESH] [--size 512] [--depth 0.05] [--tolerance 0.04]
                                      [--uv-scale 1] [--up y|z]

MESH: a shape name, a .obj/.ply/.gltf/.glb path, or ``torus20k`` (the default).
"""

from __future__ import annotations

import argparse
import resource
import time

import numpy as np


def _rss_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * resource.getpagesize() / 2**20


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("mesh", nargs="?", default="torus20k")
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--depth", type=float, default=0.05)
    ap.add_argument("--tolerance", type=float, default=0.04, help="the truth's tolerance, texels")
    ap.add_argument("--uv-scale", type=float, default=1.0)
    ap.add_argument("--up", choices=("y", "z"), default=None)
    a = ap.parse_args()

    from hzval.core import budget
    from hzval.geometry import displace as dp
    from hzval.geometry import model

    t0 = time.perf_counter()
    base = (
        model.torus(segments=160, sides=64, uv_scale=a.uv_scale)
        if a.mesh == "torus20k"
        else model.load(a.mesh, uv_scale=a.uv_scale, up=a.up)
    )
    t1 = time.perf_counter()
    rec = base.record()
    print(
        f"base: {rec['source']}, {rec['triangles']} triangles, world_per_uv {rec['world_per_uv']:.4f}, "
        f"tangents {rec['tangents']}, mirrored {rec['mirrored_fraction']:.3f}, seam edges {rec['seam_edges']}"
        f"  [{t1 - t0:.2f} s]"
    )
    texels = (a.size, a.size)
    from scipy.ndimage import gaussian_filter

    h = gaussian_filter(np.random.default_rng(0).random(texels), 2.0, mode="wrap")
    h = ((h - h.min()) / (h.max() - h.min())).astype(np.float32)
    kw = dict(height=h, depth=a.depth, tolerance=a.tolerance)
    tris, size = dp.estimate(base, texels, "wrap", **kw)
    t2 = time.perf_counter()
    print(f"estimate: {tris} triangles, {size / 2**20:.0f} MiB  [{t2 - t1:.3f} s]")
    start_rss, start_peak = _rss_mb(), _peak_mb()
    r = dp.refine(base, texels, "wrap", **kw)
    t3 = time.perf_counter()
    print(
        f"refine: {len(r.faces)} triangles, {len(r.weld)} vertices ({r.weld.max() + 1} welded)  "
        f"[{t3 - t2:.2f} s]"
    )
    p, f = dp.displace(r, h, a.depth, base.world_per_uv, "wrap")
    t4 = time.perf_counter()
    print(f"displace: {len(p)} positions  [{t4 - t3:.2f} s]")
    w = r.weld[f]
    edges = np.sort(np.stack([w, np.roll(w, -1, 1)], -1).reshape(-1, 2), 1)
    counts = np.unique(edges, axis=0, return_counts=True)[1]
    print(f"edges: {dict(zip(*np.unique(counts, return_counts=True)))} (triangles per welded edge: count)")
    peak = _peak_mb() - max(start_rss, start_peak)
    print(
        f"memory: peak {_peak_mb():.0f} MiB, {peak * 2**20 / len(f):.0f} bytes per triangle over the "
        f"start; estimate {budget.REFINE_BYTES_PER_TRIANGLE}"
    )
    print(f"total: {t4 - t0:.2f} s")


if __name__ == "__main__":
    main()
