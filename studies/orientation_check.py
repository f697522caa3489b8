"""Is the truth the same whichever way the map is turned? (issue 27, docs/truth-surface.md)

For each photo-like height map (``--photos``, default: the two made by :func:`make_photos`) and
each boundary, three orientations with their light turned to match: as is with the light at
azimuth 20 degrees, mirrored left-right at 160, rotated 90 degrees counterclockwise at 110; depth
0.05, a hard light at 30 degrees. Each is swept (the truth and ``horizon``), and its truth's
visibility is checked against an independent march of the bilinear height field
(``tests/oracles/march_check.py``: its own sample positions, NumPy, no Mitsuba)::

    python studies/orientation_check.py [--out /tmp/orient] [--spp 16] [--march-spp 4]
                                           [--truth-tolerance T] [--photos a.png,b.png]

It prints one line per case: mean V, horizon mean |F - V|, the march's mean V, and per photo and
boundary the spreads the issue's "Done when" bounds (mean V within 0.004, |F - V| within 3%,
each mean V within 0.006 of the march).

The photos: a real photograph is a crop that tiles with nothing and carries grain and 8-bit
steps, so :func:`make_photos` takes 256 x 256 crops of the built-in gravel (generated at 384,
seed 11) and bricks (at 512, seed 5) away from their origin, adds Gaussian grain of 1% of the
range (seed 3) and rounds them to 8 bits.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository: tests.oracles
from tests.oracles import march_check as mc  # noqa: E402

#: (name, azimuth in degrees, the map turned): the issue's three orientations.
ORIENTATIONS = (
    ("as-is", 20.0, lambda h: h),
    ("mirrored", 160.0, lambda h: h[:, ::-1]),
    ("rot90", 110.0, lambda h: np.rot90(h)),
)


def make_photos(out: Path) -> list[Path]:
    """Two photo-like 8-bit height maps, ``gravel.png`` and ``bricks.png`` (module docstring)."""
    from hzval import materials
    from hzval.io import codecs

    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(3)
    paths = []
    for name, size, seed, (r, c) in (("gravel", 384, 11, (61, 97)), ("bricks", 512, 5, (131, 203))):
        h = materials.generate(name, size, seed=seed).height[r : r + 256, c : c + 256].astype(np.float64)
        h = (h - h.min()) / (h.max() - h.min())
        h = np.clip(h + rng.normal(0.0, 0.01, h.shape), 0.0, 1.0)
        path = out / f"{name}.png"
        codecs.write_png(path, np.round(h * 255).astype(np.uint8))
        paths.append(path)
    return paths


def march_mean_v(
    h_texels: np.ndarray, boundary: str, azimuth: float, elevation: float, spp: int, seed: int = 0
) -> float:
    """Mean visibility of the bilinear height field from above, by tests/oracles/march_check.py's own
    march (its own jittered positions, ``spp`` a pixel)."""
    rows, cols = h_texels.shape
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:rows, 0:cols]
    x = (xx.ravel()[:, None] + rng.random((rows * cols, spp))).ravel()
    y = (rows - 1 - yy.ravel()[:, None] + rng.random((rows * cols, spp))).ravel()
    P = np.stack([x, y, np.zeros_like(x)], axis=1)
    return float(np.mean(mc.visible(h_texels, boundary, P, mc.light_direction(azimuth, elevation))))


def run_case(
    height_path: Path, boundary: str, orientation, out: Path, spp: int, tolerance: float | None
) -> dict:
    """One sweep of a turned map: its truth's mean V and horizon's mean |F - V|."""
    from hzval.core import conventions as cv
    from hzval.io import codecs, heightmap
    from hzval.pipeline import sweep
    from hzval.scene import spec as sc

    name, azimuth, turn = orientation
    h = np.ascontiguousarray(turn(heightmap.load_height(height_path).height), np.float32)
    turned = out / f"{height_path.stem}-{name}.npy"
    turned.parent.mkdir(parents=True, exist_ok=True)
    np.save(turned, h)
    scene = sc.override(
        sc.Scene(),
        height=str(turned),
        depth=0.05,
        boundary=boundary,
        elevation=30.0,
        azimuths=str(azimuth),
        light="hard",
        spp=spp,
        truth_tolerance=tolerance,
    )
    folder = out / f"{height_path.stem}-{boundary}-{name}"
    m = sweep.run(scene, folder, options=sweep.Options(techniques=("horizon",)), progress=False)
    fr = m["frames"][0]
    V = codecs.read_exr(folder / fr["files"]["visibility"])
    V = next(iter(V.values())) if isinstance(V, dict) else V
    h_tex = cv.heights_in_texels(h, 0.05).astype(np.float64)
    return {
        "photo": height_path.stem,
        "boundary": boundary,
        "orientation": name,
        "azimuth": azimuth,
        "mean_v": float(np.mean(V)),
        "horizon_fv": float(fr["techniques"]["horizon"]["visibility_mae"]),
        "h_tex": h_tex,
    }


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=Path("/tmp/orientation-check"))
    p.add_argument("--spp", type=int, default=16)
    p.add_argument("--march-spp", type=int, default=4)
    p.add_argument("--truth-tolerance", type=float, default=None)
    p.add_argument("--photos", default=None, help="comma-separated height maps (default: make_photos)")
    p.add_argument("--boundaries", default="open,wrap")
    args = p.parse_args(argv)
    photos = [Path(s) for s in args.photos.split(",")] if args.photos else make_photos(args.out / "photos")
    rows = []
    for photo in photos:
        for boundary in args.boundaries.split(","):
            group = []
            for o in ORIENTATIONS:
                r = run_case(photo, boundary, o, args.out, args.spp, args.truth_tolerance)
                r["march_v"] = march_mean_v(r.pop("h_tex"), boundary, r["azimuth"], 30.0, args.march_spp)
                group.append(r)
                print(
                    f"{photo.stem:8} {boundary:5} {r['orientation']:9} az {r['azimuth']:5.0f}  mean V "
                    f"{r['mean_v']:.4f}  horizon |F-V| {r['horizon_fv']:.4f}  march V {r['march_v']:.4f}",
                    flush=True,
                )
            v, fv = [g["mean_v"] for g in group], [g["horizon_fv"] for g in group]
            gap = max(abs(g["mean_v"] - g["march_v"]) for g in group)
            print(
                f"{'':8} {boundary:5} spread: mean V {max(v) - min(v):.4f} (<= 0.004), |F-V| "
                f"{(max(fv) - min(fv)) / np.mean(fv) * 100:.2f}% (<= 3%), truth - march {gap:.4f} (<= 0.006)"
            )
            rows += group
    (args.out / "orientation.json").write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
