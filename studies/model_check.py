"""Your model under hzval's truth: does the sweep hold up on it? (issue 28, "a scanned model").

Sweeps a height map on a mesh file in perspective and prints, per frame, the share of lit pixels,
the mean and largest ``|truth - unshadowed|`` where the truth is lit (0 up to the shading's own
rounding when the truth shades as the techniques do: the same normal map carried by the same
tangent frames), the base mesh's macro-shadowed share, and each technique's mean ``|F - V|``.

    python studies/model_check.py MESH HEIGHT [--depth 0.003] [--up y] [--resolution 384]
                                     [--spp 4] [--azimuths -60:60:30] [--out DIR]
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


def main() -> None:
    from hzval.io import codecs

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mesh")
    ap.add_argument("height")
    ap.add_argument("--depth", type=float, default=0.003)
    ap.add_argument("--up", choices=("y", "z"), default="y")
    ap.add_argument("--resolution", type=int, default=384)
    ap.add_argument("--spp", type=int, default=4)
    ap.add_argument("--azimuths", default="-60:60:30")
    ap.add_argument("--out", type=Path, default=None)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = a.out or Path(tmp) / "run"
        subprocess.run(
            [
                sys.executable,
                "-m",
                "hzval",
                "sweep",
                a.height,
                "--mesh",
                a.mesh,
                "--up",
                a.up,
                "--depth",
                str(a.depth),
                "--camera",
                "perspective",
                "--resolution",
                f"{a.resolution}x{a.resolution}",
                "--spp",
                str(a.spp),
                "--azimuths",
                a.azimuths,
                "--all-files",
                "--out",
                str(out),
                "--quiet",
                "--force",
            ],
            check=True,
            cwd=ROOT,
            stdout=subprocess.DEVNULL,
        )
        m = json.loads((out / "metrics.json").read_text())
        print(
            f"{m['mesh']['source']}: {m['mesh']['triangles']} triangles, {m['mesh']['seam_edges']} seam "
            "edges, "
            f"mirrored {m['mesh']['mirrored_fraction']:.2f}, displaced {m['mesh']['displaced_triangles']:,}"
        )
        for f in m["frames"]:

            def rgb(key):
                return np.stack([codecs.read_exr(out / f["files"][key])[c] for c in "RGB"], -1)  # noqa: B023 - called within this iteration

            V = codecs.read_exr(out / f["files"]["visibility"])["Y"]
            lit = np.isfinite(V) & (V == 1.0)
            d = np.abs(rgb("truth") - rgb("plain"))[lit]
            scores = ", ".join(f"{k} |F-V| {v['visibility_mae']:.4f}" for k, v in f["techniques"].items())
            print(
                f"az {f['azimuth_deg']:+5.0f}: lit {lit.mean():.3f}, |truth - unshadowed| where lit: mean "
                f"{d.mean():.5f} max {d.max():.4f}; macro-shadowed {f['macro_shadowed']:.4f}; {scores}"
            )
        for w in m["warnings"]:
            print("warning:", w)


if __name__ == "__main__":
    main()
