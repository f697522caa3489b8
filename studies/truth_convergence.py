"""The truth's tolerance: how mean V and horizon's |F - V| move as the tolerance halves (issue 27).

For every built-in material (256 x 256, its own depth and boundary) and the two photo-like maps of
``studies/orientation_check.py`` (depth 0.05, ``open``), a sweep of five hard lights at 30
degrees (azimuths -60:60:30, 16 spp, the truth and ``horizon``) at each tolerance of
``--tolerances``; it prints, per map and tolerance, the mean V over the frames, horizon's mean
|F - V|, the triangles per cell of the wrap/open mesh, and the change of both from the next larger
tolerance (the default is chosen where halving moves mean V by at most 0.002 and |F - V| by at
most 1% everywhere; docs/truth-surface.md)::

    python studies/truth_convergence.py [--out /tmp/truth-convergence]
                                        [--tolerances 0.08,0.04,0.02,0.01,0.005]
                                           [--materials all] [--size 256]

The sweeps of one map share one bake (the same folder's cache); only the truth changes.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from orientation_check import make_photos  # noqa: E402


def sweep_at(scene, tolerance: float, out: Path) -> dict:
    """Mean V over the frames and horizon's mean |F - V| of one sweep at ``tolerance``."""
    import dataclasses

    from hzval.io import codecs
    from hzval.pipeline import sweep

    scene = dataclasses.replace(
        scene, material=dataclasses.replace(scene.material, truth_tolerance=tolerance)
    )
    m = sweep.run(scene, out, options=sweep.Options(techniques=("horizon",)), progress=False)
    vs, fvs = [], []
    for fr in m["frames"]:
        V = codecs.read_exr(out / fr["files"]["visibility"])
        vs.append(float(np.mean(next(iter(V.values())) if isinstance(V, dict) else V)))
        fvs.append(float(fr["techniques"]["horizon"]["visibility_mae"]))
    return {
        "mean_v": float(np.mean(vs)),
        "horizon_fv": float(np.mean(fvs)),
        "truth_setup_s": m["timings"]["truth_setup_s"],
    }


def triangles_per_cell(height: np.ndarray, scene, tolerance: float) -> float:
    """Triangles per cell of the tile's vertex grid (margin and skirt aside)."""
    from hzval.core import conventions as cv
    from hzval.geometry import tile as mesh

    lv = mesh.cell_levels(cv.heights_in_texels(height, scene.material.depth), tolerance)
    return float(np.mean(np.where(lv == 0, 2.0, 4.0 * lv.astype(np.float64) ** 2)))


def main(argv=None) -> int:
    from hzval import materials
    from hzval.scene import spec as sc

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=Path("/tmp/truth-convergence"))
    p.add_argument("--tolerances", default="0.08,0.04,0.02,0.01,0.005")
    p.add_argument("--materials", default="all", help="comma-separated built-ins and/or files, or all")
    p.add_argument("--size", type=int, default=256)
    p.add_argument("--depth", type=float, default=0.05, help="a file's depth (default 0.05)")
    args = p.parse_args(argv)
    tols = [float(t) for t in args.tolerances.split(",")]
    names = (
        materials.names() + [str(q) for q in make_photos(args.out / "photos")]
        if args.materials == "all"
        else args.materials.split(",")
    )
    rows = []
    print(f"{'map':13} {'tolerance':>9} {'tri/cell':>8} {'mean V':>7} {'dV':>7} {'|F-V|':>7} {'d|F-V|':>7}")
    for name in names:
        builtin = materials.is_builtin(name)
        scene = sc.override(
            sc.Scene(),
            height=name,
            size=args.size if builtin else None,
            depth=None if builtin else args.depth,
            boundary=None if builtin else "open",
            elevation=30.0,
            azimuths="-60:60:30",
            light="hard",
            spp=16,
        )
        height = sc.load_material_height(scene.material).height
        label = Path(name).stem if not builtin else name
        prev = None
        for t in tols:
            r = sweep_at(scene, t, args.out / label)
            r.update(map=label, tolerance=t, tri_per_cell=triangles_per_cell(height, scene, t))
            dv = "" if prev is None else f"{r['mean_v'] - prev['mean_v']:+7.4f}"
            dfv = "" if prev is None else f"{(r['horizon_fv'] / prev['horizon_fv'] - 1) * 100:+6.2f}%"
            print(
                f"{label:13} {t:9.4g} {r['tri_per_cell']:8.2f} {r['mean_v']:7.4f} {dv:>7} "
                f"{r['horizon_fv']:7.4f} {dfv:>7}",
                flush=True,
            )
            rows.append(r)
            prev = r
    (args.out / "convergence.json").write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
