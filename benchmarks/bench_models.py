"""A sweep on a model, and where its time goes (issue 28, "Performance").

A 512 x 512 material on a 20k-triangle model (a torus with UVs, written as OBJ and read back as a
user's file is), 384 x 384 pixels, 5 lights, every technique that renders on models; the budget is
60 s here. Prints the set-up's stages (bake, the displaced mesh and its camera rays, each
technique's set-up), the frames' (truth, techniques, comparisons, files), the peak memory against the
estimate the sweep checked before allocating, and the displaced mesh's size.

    python benchmarks/bench_models.py [--size 512] [--triangles 20000] [--resolution 384] [--spp 4]
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def write_torus(path: Path, triangles: int) -> int:
    """A torus of about ``triangles`` triangles, as OBJ (z up), with :func:`hzval.geometry.model.torus`'s
    UVs."""
    import trimesh

    from hzval.geometry import model

    sides = max(8, int(round(math.sqrt(triangles / 2 / 2))))
    segments = max(8, int(round(triangles / 2 / sides)))
    t = model.torus(segments=segments, sides=sides)
    mesh = trimesh.Trimesh(
        t.positions,
        t.faces,
        vertex_normals=t.normals,
        process=False,
        visual=trimesh.visual.TextureVisuals(uv=t.uvs),
    )
    mesh.export(path)
    return len(t.faces)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--triangles", type=int, default=20000)
    ap.add_argument("--resolution", type=int, default=384)
    ap.add_argument("--spp", type=int, default=4)
    ap.add_argument("--material", default="bricks")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        n = write_torus(tmp / "torus.obj", args.triangles)
        cmd = [
            sys.executable,
            "-m",
            "hzval",
            "sweep",
            "--material",
            args.material,
            "--size",
            str(args.size),
            "--mesh",
            str(tmp / "torus.obj"),
            "--up",
            "z",
            "--camera",
            "perspective",
            "--view-elevation",
            "35",
            "--resolution",
            f"{args.resolution}x{args.resolution}",
            "--spp",
            str(args.spp),
            "--azimuths",
            "-60:60:30",
            "--out",
            str(tmp / "out"),
            "--quiet",
        ]
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
        wall = time.perf_counter() - t0
        m = json.loads((tmp / "out" / "metrics.json").read_text())
    t = m["timings"]
    print(
        f"{args.material} {args.size}^2 on a {n}-triangle torus (OBJ), {args.resolution}^2 px, {args.spp} "
        "spp, "
        f"{len(m['frames'])} lights, techniques {', '.join(m['techniques'])}"
    )
    print(
        f"  wall {wall:.1f} s (budget 60 s), of which the sweep's own {t.get('total_s', float('nan')):.1f} s"
    )
    for key in sorted(k for k in t if k.endswith("_s")):
        print(f"  {key:24} {t[key]:8.2f} s")
    print(
        f"  displaced mesh {m['mesh']['displaced_triangles']:,} triangles; seen "
        f"{m['mesh']['seen_fraction']:.2f}"
    )
    mem = m.get("memory", {})
    if mem:
        print(
            f"  peak {mem.get('peak_rss_bytes', 0) / 2**30:.2f} GiB, estimated "
            f"{mem.get('estimate_bytes', 0) / 2**30:.2f} GiB"
        )
    for f in m["frames"]:
        print(
            f"  az {f['azimuth_deg']:+5.0f}: truth {f['truth_s']:.2f} s, macro-shadowed "
            f"{f.get('macro_shadowed', 0):.3f}, "
            + ", ".join(
                f"{k} {v['seconds']:.2f} s |F-V| {v['visibility_mae']:.4f}"
                for k, v in f["techniques"].items()
            )
        )


if __name__ == "__main__":
    main()
