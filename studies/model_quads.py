"""Three unit quads carrying one surface, and the plane: the mesh path's invariance (issue 28).

One quad's UVs equal its (x, y); one is mirrored in u, with the photo mirrored back; one has its UVs
turned 90 degrees, with the photo turned back. All three are the same displaced surface, so the
truth, and every technique's factor through the quad's own tangent frames (handedness -1 on the
mirrored one, the tangent along world y on the turned one), must agree; and the first must score as
``--mesh plane``, the tile hzval measured before it had meshes. Orthographic view at 60 degrees, two
lights, ``open`` (the quads have no neighbours).

    python studies/model_quads.py [--photo PATH] [--size 256] [--depth 0.05] [--spp 4]

Prints each run's horizon (and pom) mean |F - V| over the seen pixels, the per-pixel mean |F - F1|
between each quad and the first (over the pixels both see), and the plane's scores.
docs/meshes.md quotes its output.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
PHOTO = (
    Path(sys.prefix)
    / "lib"
    / f"python{sys.version_info.major}.{sys.version_info.minor}"
    / "site-packages"
    / "matplotlib"
    / "mpl-data"
    / "sample_data"
    / "grace_hopper.jpg"
)

#: (name, UVs of the corners (0,0), (1,0), (1,1), (0,1), the photo turned to match)
QUADS = (
    ("xy", [(0, 0), (1, 0), (1, 1), (0, 1)], lambda a: a),
    ("mirrored-u", [(1, 0), (0, 0), (0, 1), (1, 1)], lambda a: a[:, ::-1]),
    ("turned-90", [(1, 0), (1, 1), (0, 1), (0, 0)], np.rot90),
)


def write_quad(path: Path, uvs) -> None:
    """A unit quad at z = 0 (z up), counterclockwise seen from +z, as OBJ (``v = 0`` at the bottom)."""
    corners = [(0, 0), (1, 0), (1, 1), (0, 1)]
    lines = [f"v {x} {y} 0" for x, y in corners] + [f"vt {u} {v}" for u, v in uvs]
    lines += ["vn 0 0 1", "f 1/1/1 2/2/1 3/3/1", "f 1/1/1 3/3/1 4/4/1"]
    path.write_text("\n".join(lines) + "\n")


def photo_height(path: Path, size: int) -> np.ndarray:
    from PIL import Image

    im = Image.open(path).convert("L")
    side = min(im.size)
    im = im.crop((0, 0, side, side)).resize((size, size), Image.LANCZOS)
    return np.asarray(im, np.float32) / 255.0


def sweep(height: Path, out: Path, mesh: str | None, args) -> dict:
    cmd = [
        sys.executable,
        "-m",
        "hzval",
        "sweep",
        str(height),
        "--out",
        str(out),
        "--quiet",
        "--depth",
        str(args.depth),
        "--boundary",
        "open",
        "--spp",
        str(args.spp),
        "--azimuths",
        "-45,30",
        "--camera",
        "orthographic",
        "--view-elevation",
        "60",
        "--resolution",
        f"{args.size}x{args.size}",
        "--techniques",
        "horizon,pom",
    ]
    if mesh:
        cmd += ["--mesh", mesh, "--up", "z"]
    subprocess.run(cmd, check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
    return json.loads((out / "metrics.json").read_text())


def factors(out: Path, m: dict, name: str) -> list[np.ndarray]:
    from hzval.io import codecs

    return [codecs.read_exr(out / f["techniques"][name]["files"]["factor"])["Y"] for f in m["frames"]]


def main() -> None:
    from PIL import Image

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--photo", type=Path, default=PHOTO)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--depth", type=float, default=0.05)
    ap.add_argument("--spp", type=int, default=4)
    args = ap.parse_args()
    h = photo_height(args.photo, args.size)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        runs = {}
        for name, uvs, turn in QUADS:
            write_quad(tmp / f"{name}.obj", uvs)
            Image.fromarray((np.ascontiguousarray(turn(h)) * 255).round().astype(np.uint8)).save(
                tmp / f"{name}.png"
            )
            runs[name] = (tmp / name, sweep(tmp / f"{name}.png", tmp / name, str(tmp / f"{name}.obj"), args))
        runs["plane"] = (tmp / "plane", sweep(tmp / "xy.png", tmp / "plane", None, args))
        first_out, first = runs["xy"]
        print(
            f"photo {args.photo.name}, {args.size}^2, depth {args.depth}, open, orthographic 60, lights "
            "-45, 30"
        )
        for tech in ("horizon", "pom"):
            ref = factors(first_out, first, tech)
            for name, (out, m) in runs.items():
                mae = [f["techniques"][tech]["visibility_mae"] for f in m["frames"]]
                perfect = [f["techniques"][tech].get("perfect_parallax_mae") for f in m["frames"]]
                line = (
                    f"{tech:8} {name:11} |F-V| {np.mean(mae):.4f} (perfect parallax {np.mean(perfect):.4f})"
                )
                if name != "plane":
                    dF = np.mean([np.nanmean(np.abs(a - b)) for a, b in zip(factors(out, m, tech), ref)])
                    line += f"  mean |F - F(xy)| {dF:.4f}"
                print(line)


if __name__ == "__main__":
    main()
