"""Benchmark: the peak memory of building and writing a displaced tile mesh, per triangle.

Builds :func:`hzval.geometry.tile.displaced_mesh` of a built-in material (vertex normals and texture
coordinates, as ``bake --mesh`` and ``export-scene`` build it) in a fresh process per case, writes
it as PLY, and prints the peak's rise over the map's own, in bytes a triangle, beside the count
:func:`hzval.geometry.tile.mesh_size` gave before anything was built (it must be exact) and
:data:`hzval.core.budget.MESH_BYTES_PER_TRIANGLE`, the figure ``check_fits`` charges.

Usage::

    python benchmarks/bench_mesh_memory.py [--material bricks] [--cases 512:0.05:0,512:0.5:0,...]

Each case is ``SIZE:DEPTH:MARGIN`` (``MARGIN`` ``auto``: the wrap margin for 10-degree lights).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile

_CASE = r"""
import json, resource, sys
import hzval
hzval.init()
from hzval import materials
from hzval.core import conventions as cv
from hzval.geometry import tile
material, size, depth, margin, path = sys.argv[1:]
h = materials.generate(material, int(size)).height
margin = None if margin == "auto" else int(margin)
ht = cv.heights_in_texels(h, float(depth))
vertices, triangles = tile.mesh_size(ht, "wrap", None if margin is None else margin)
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
m = tile.displaced_mesh(h, float(depth), "wrap", margin=margin, normals=True)
tile.write_ply(m, path)
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
built = (int(m.vertex_count()), int(m.face_count()))
print(json.dumps({"counted": [vertices, triangles], "built": built, "rise": peak - before}))
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--material", default="bricks")
    ap.add_argument("--cases", default="512:0.05:0,512:0.5:0,512:0.05:200,1024:0.2:0")
    args = ap.parse_args()
    from hzval.core.budget import MESH_BYTES_PER_TRIANGLE

    print(f"charged: {MESH_BYTES_PER_TRIANGLE} bytes a triangle")
    print("size  depth  margin  vertices   triangles  counted=built  rise MiB  bytes/triangle")
    for case in args.cases.split(","):
        size, depth, margin = case.split(":")
        with tempfile.TemporaryDirectory() as tmp:
            out = subprocess.run(
                [sys.executable, "-c", _CASE, args.material, size, depth, margin, f"{tmp}/m.ply"],
                capture_output=True,
                text=True,
                check=True,
            )
        r = json.loads(out.stdout.strip().splitlines()[-1])
        v, t = r["counted"]
        print(
            f"{size:>4}  {depth:>5}  {margin:>6}  {v:>9,}  {t:>10,}  {str(r['counted'] == r['built']):>13}"
            f"  {r['rise'] / 2**20:8.1f}  {r['rise'] / t:14.1f}"
        )


if __name__ == "__main__":
    main()
