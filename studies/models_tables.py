"""The band tables of docs/models.md from ``hzval models`` outputs (issue 29).

    python studies/models_tables.py NAME=DIR [NAME=DIR ...]

Per study (``DIR/models.json``): per case the horizon map's band |F - V| (± one standard error over
the lights), the flat patch's on the same texels, the excess, the flat bake's signed F - V there
(+: it leaks), the truth's lit share minus the flat's, and the trend's verdicts; then the cube's
seam shares and the ring's excess by the light's normal curvature.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def pm(s, d=4, signed=False):
    if not s or s.get("mean") is None:
        return "-"
    m = f"{s['mean']:+.{d}f}" if signed else f"{s['mean']:.{d}f}"
    return f"{m} ± {s['se']:.{d}f}" if s.get("se") is not None else m


def study(name: str, d: dict, tech: str = "horizon") -> list[str]:
    out = [
        f"**{name}** (`{d['command']}`)",
        "",
        "| case | 1/R | texels | band \\|F-V\\| | flat, same texels | **excess** | flat's F - V | lit: cap "
        "- flat |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in d["rows"]:
        if "band" not in r or r["case"] == "cube":
            continue
        t = r["band"]["techniques"][tech]
        k = r.get("principal_curvatures")
        k = f"{k['along_ring_x']:+g} x, {k['across_tube_y']:+g} y" if k else f"{r['curvature']:+g}"
        out.append(
            f"| {r['case']} | {k} | {r['band']['texels']:.0f} | {pm(t['mae'])} | {pm(t.get('flat'))} | "
            f"{pm(t.get('excess'), signed=True)} | {pm(t.get('flat_bias'), signed=True)} | "
            f"{pm(r['band'].get('lit_excess'), 3, True)} |"
        )
    tr = d["trend"][tech]
    for key, label in (("mae", "band |F-V|"), ("excess", "excess")):
        o = tr[key]["overall"]
        falls = ", ".join(f"{f['from']:+g}→{f['to']:+g} {f['z']:+.1f} SE" for f in tr[key]["falls"])
        out.append(
            f"\n{label}: **{tr[key]['verdict']}** (flat → 1/R = 2: {o['change']:+.4f}, {o['z']:+.1f} SE"
            + (f"; falls {falls}" if falls else "")
            + ")"
        )
    return out


def seams(named: list[tuple[str, dict]], tech: str = "horizon") -> list[str]:
    out = ["| material | cube: error within 3 texels of a seam | pixels there | ratio |", "|---|---|---|---|"]
    for name, d in named:
        cube = next(r for r in d["rows"] if r["case"] == "cube")
        s = cube["band"]["techniques"][tech]["seam"]
        e, p = s["error_share"], s["pixel_share"]
        out.append(f"| {name} | {pm(e, 3)} | {p:.3f} | {e['mean'] / p:.2f} |")
    return out


def ring(named: list[tuple[str, dict]], tech: str = "horizon") -> list[str]:
    out = [
        "| material | ring excess, all lights | lights along the ring (k_n < 0) | across the tube (k_n > 0) "
        "|",
        "|---|---|---|---|",
    ]
    for name, d in named:
        r = next(r for r in d["rows"] if r["case"] == "ring")
        by = r["band"]["by_azimuth"]
        neg = [a["excess"][tech] for a in by if a["normal_curvature"] < 0 and a["excess"][tech] is not None]
        pos = [a["excess"][tech] for a in by if a["normal_curvature"] > 0 and a["excess"][tech] is not None]

        def mean(v):
            return sum(v) / len(v) if v else float("nan")

        out.append(
            f"| {name} | {pm(r['band']['techniques'][tech].get('excess'), signed=True)} | "
            f"{mean(neg):+.4f} ({len(neg)}) | {mean(pos):+.4f} ({len(pos)}) |"
        )
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "studies", nargs="+", metavar="NAME=DIR", help="a study's name and its `hzval models` folder"
    )
    args = ap.parse_args(argv)
    named = []
    for a in args.studies:
        name, sep, folder = a.partition("=")
        path = Path(folder) / "models.json"
        if not sep or not name:
            print(f"models_tables: {a}: expected NAME=DIR", file=sys.stderr)
            return 2
        if not path.is_file():
            print(
                f"models_tables: {path}: no such file (run `hzval models --out {folder}` first)",
                file=sys.stderr,
            )
            return 2
        named.append((name, json.loads(path.read_text())))
    for name, d in named:
        print("\n".join(study(name, d)), end="\n\n")
    print("\n".join(seams(named)), end="\n\n")
    print("\n".join(ring(named)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
