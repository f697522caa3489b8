"""What MikkTSpace frames cost a model sweep: the same sweep with ``--tangents fged2`` and with
``--tangents mikktspace``, run alternately in fresh processes, and the ratio of their median
wall times (issue 40's bound: at most 1.1x).

The model is the built-in mirrored sphere (mirrored UV halves and a seam) written as an OBJ, so
that ``auto`` would pick MikkTSpace for it as for a user's file.

    .venv/bin/python benchmarks/bench_mikktspace.py [--segments 128] [--size 256] [--repeat 3]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def write_obj(path: Path, segments: int) -> int:
    """The mirrored sphere of ``segments`` longitudes as an OBJ; its triangle count."""
    from hzval.geometry import model

    m = model.load("mirrored-sphere", shape_args={"segments": segments, "rings": max(segments // 2, 4)})
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in m.positions.tolist()]
    lines += [f"vt {u!r} {v!r}" for u, v in m.uvs.tolist()]
    lines += [f"vn {x!r} {y!r} {z!r}" for x, y, z in m.normals.tolist()]
    lines += [f"f {a}/{a}/{a} {b}/{b}/{b} {c}/{c}/{c}" for a, b, c in (m.faces + 1).tolist()]
    path.write_text("\n".join(lines) + "\n")
    return len(m.faces)


def sweep_seconds(obj: Path, tangents: str, size: int, out: Path) -> float:
    cmd = [sys.executable, "-m", "hzval", "sweep", "--mesh", str(obj), "--up", "z", "--tangents", tangents]
    cmd += ["--size", str(size), "--resolution", f"{size}x{size}", "--quiet", "--force", "--out", str(out)]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, capture_output=True)
    return time.perf_counter() - t0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--segments", type=int, default=128, help="longitudes of the sphere (default 128)")
    parser.add_argument("--size", type=int, default=256, help="map size and image side (default 256)")
    parser.add_argument("--repeat", type=int, default=3, help="runs of each, alternating (default 3)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        obj = Path(tmp) / "mirrored.obj"
        triangles = write_obj(obj, args.segments)
        times: dict[str, list[float]] = {"fged2": [], "mikktspace": []}
        for _ in range(args.repeat):
            for method in times:
                times[method].append(sweep_seconds(obj, method, args.size, Path(tmp) / method))
    med = {k: statistics.median(v) for k, v in times.items()}
    print(f"mirrored sphere, {triangles} triangles, {args.size} x {args.size}, {args.repeat} runs each")
    for k, v in times.items():
        print(f"  --tangents {k:10s} median {med[k]:.2f} s  ({', '.join(f'{t:.2f}' for t in v)})")
    print(f"mikktspace / fged2: {med['mikktspace'] / med['fged2']:.3f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
