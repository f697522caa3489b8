"""The suite's overview: thumbnails, ``suite.json`` and ``index.html`` over every material's row.

The rows are worst first, and the terminal's tables show the same (docs/ARCHITECTURE.md, "suite.json").
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any, Callable

import numpy as np
from PIL import Image

from hzval.core import backend
from hzval.io import atomic, codecs, documents, staging
from hzval.metrics.results import SuiteResult, techniques_of
from hzval.report import columns, ranking
from hzval.report import pages as report
from hzval.techniques import registry as technique

__all__ = ["THUMB_PX", "sort_key", "write_overview", "summary_table", "suite_ranking", "render_suite"]

#: Side of a thumbnail in pixels.
THUMB_PX = 144


def sort_key(row: dict) -> tuple:
    """Worst first: failed materials, then the first technique's mean |F - V|."""
    if row["status"] != "ok":
        return (0, 0.0, row["name"])
    tech = next(iter(techniques_of(row).values()), {})
    v = ranking.visibility_of(tech)
    return (1, -(v if v is not None else -1.0), row["name"])


def write_overview(
    out: Path,
    rows: list[dict],
    *,
    command: str,
    engine: str,
    workers: int | None,
    cluster: str | None,
    seconds: float,
    interrupted: bool = False,
    gates: dict | None = None,
) -> dict:
    """Write thumbnails, ``suite.json`` and ``index.html`` for the rows of every material.

    ``gates``: the record of :func:`gate_failures`, listed first.
    """
    rows = sorted(({**r, "origin": _portable_origin(r.get("origin"), out)} for r in rows), key=sort_key)
    command = staging.portable_command(command)
    for row in rows:
        if row["status"] == "ok":
            row["thumbs"] = _thumbnails(out, row)
    names = []
    for row in rows:
        names += [n for n in techniques_of(row) if n not in names]
    techniques = {
        n: {"label": technique.get(n).label, "summary": technique.get(n).summary}
        for n in names
        if n in technique.REGISTRY
    }
    result = {
        "suite": {
            "command": command,
            "engine": engine,
            "workers": workers,
            "cluster": cluster,
            "seconds": seconds,
            "materials": len(rows),
            "interrupted": interrupted,
            "failed": sum(r["status"] == "failed" for r in rows),
            "not_run": sum(r["status"] == "not run" for r in rows),
            "versions": {
                **backend.versions(),
                "variant": ", ".join(sorted({r["variant"] for r in rows if r.get("variant")})),
            },
        },
        "techniques": techniques,
        "materials": rows,
        **({"gates": gates} if gates else {}),
    }
    documents.write_json(out / "suite.json", result)
    html = render_suite(result)
    with atomic.atomic_path(out / "index.html") as tmp:
        tmp.write_text(html, encoding="utf-8")
    return result


def _portable_origin(origin: str | None, out: Path) -> str | None:
    """Return a row's ``origin`` with its path relative to ``out``.

    The origin is ``built-in``, a scene file or ``map + sidecar``; the path is made relative by
    :func:`hzval.io.staging.report_path`.
    """
    if not origin or origin == "built-in":
        return origin
    path, plus, rest = origin.partition(" + ")
    return staging.report_path(path, out) + (plus + rest if plus else "")


def _thumbnails(out: Path, row: dict) -> dict:
    """Make downsampled copies of the chosen frames under ``out/thumbs/<name>/``.

    The result has the same layout as ``row["files"]``, with paths relative to ``out``.
    """
    thumbs = {}
    for az, images in row["files"].items():
        thumbs[az] = {}
        for kind, rel in images.items():
            if rel is None:
                continue
            src = out / row["name"] / rel
            slug = re.sub(r"[^0-9A-Za-z+.-]+", "_", az).strip("_")
            dst = Path("thumbs") / row["name"] / f"az{slug}_{kind}.png"
            try:
                with Image.open(src) as img:
                    img = img.convert("RGB")
                    img.thumbnail((THUMB_PX, THUMB_PX), Image.Resampling.BOX)
                    pixels = np.asarray(img)
            except OSError:
                continue
            (out / dst).parent.mkdir(parents=True, exist_ok=True)
            codecs.write_png(out / dst, pixels)
            thumbs[az][kind] = dst.as_posix()
    return thumbs


def summary_table(result: dict) -> str:
    """Return the terminal's tables, under 100 columns.

    First the techniques over every material that ran, best first (their means, and on how many materials each
    is worse than no shadows at some light elevation: the overview's first table), then a line per material,
    worst first by the lead technique: its lead |F - V| and FLIP, its best technique and its sweep's time, or
    why it failed.
    """
    ranked = suite_ranking(result)
    width = max([len("technique"), *(len(r["label"]) for r in ranked)])
    lines = [f"{'technique':{width}s}   |F-V|    FLIP  worse than no shadows on"]
    lines += [f"{r['label']:{width}s}  {r['vis']:>6s}  {r['flip']:>6s}  {r['worse']}" for r in ranked]
    suite = SuiteResult.of(result)
    names = suite.names
    lead = names[0] if names else None
    lines += ["", f"{'material':20s}  {'lead':>20s}   |F-V|    FLIP  {'best':>20s}   |F-V|  sweep s"]
    for r in suite.materials:
        if r["status"] != "ok":
            lines.append(f"{r['name'][:20]:20s}  failed: {r['error']}")
            continue
        per = r.techniques
        scores = {n: ranking.visibility_of(per.get(n) or {}) for n in names}
        scored = [(v, n) for n, v in scores.items() if v is not None]
        best_v, best = min(scored) if scored else (None, "-")
        t = per.get(lead) or {}
        lines.append(
            f"{r['name'][:20]:20s}  {(lead or '-')[:20]:>20s}  {_fixed(ranking.visibility_of(t)):>6s}  "
            f"{_fixed(t.get('flip_mean')):>6s}  {best[:20]:>20s}  {_fixed(best_v):>6s}  {r['seconds']:7.1f}"
        )
    return "\n".join(lines)


def _fixed(v) -> str:
    return "-" if v is None else f"{v:.4f}"


def _cell_of(value, fmt: Callable[[Any], str]) -> dict:
    return {"v": "" if value is None else f"{value:.6g}", "text": "—" if value is None else fmt(value)}


def _suite_row(r: dict, names: list[str]) -> dict:
    """Return a material's row and card, formatted."""
    row = {
        "name": r["name"],
        "origin": r.get("origin", ""),
        "status": r["status"],
        "report": r.get("report"),
        "error": r.get("error", ""),
    }
    if r["status"] != "ok":
        return row
    cells = []
    per = techniques_of(r)
    for n in names:
        t = per.get(n) or {}
        cells += [
            _cell_of(ranking.visibility_of(t), columns.fixed(4)),
            _cell_of(t.get("flip_mean"), columns.fixed(4)),
            _cell_of(None if t.get("seconds") is None else 1000 * t["seconds"], columns.fixed(0)),
        ]
    kinds = [{"name": "truth", "label": "truth"}] + [
        {"name": n, "label": technique.get(n).label.split(" (")[0]} for n in names if n in per
    ]
    row.update(
        size=f"{r['cols']} × {r['rows']}",
        texels=r["cols"] * r["rows"],
        depth=f"{r['depth']:g}",
        boundary=r["boundary"],
        cells=cells,
        floor=_cell_of(r["floor"].get("flip_mean"), columns.fixed(4)),
        truth=_cell_of(None if r.get("truth_s") is None else 1000 * r["truth_s"], columns.fixed(0)),
        sweep=_cell_of(r.get("seconds"), columns.fixed(1)),
        peak=_cell_of(r["peak_rss_bytes"] / 2**30, columns.fixed(2)),
        lights=list(r.get("thumbs", {})),
        thumbs=r.get("thumbs", {}),
        kinds=kinds,
    )
    return row


def suite_ranking(result: dict) -> list[dict]:
    """Return the suite's first table: each technique's means over the materials that ran, best first.

    Each row also says on how many of them the technique is worse than no shadows at some light elevation; no
    shadows comes last, the baseline.
    """
    suite = SuiteResult.of(result)
    info = suite.techniques
    ok = [r for r in suite.materials if r.get("status") == "ok"]
    rows = []
    for n in [*info, ranking.NONE]:
        found = [r.no_shadows if n == ranking.NONE else r.techniques.get(n) for r in ok]
        recs = [t for t in found if t is not None]
        if not recs:
            continue
        vis = [ranking.visibility_of(t) for t in recs]
        flip = [columns.num(t.get("flip_mean")) for t in recs]
        vis, flip = [v for v in vis if v is not None], [v for v in flip if v is not None]
        worse = sum(bool(t.get("worse_at")) for t in recs)
        rows.append(
            {
                "label": "no shadows (F = 1)" if n == ranking.NONE else info[n]["label"],
                "vis": sum(vis) / len(vis) if vis else None,
                "flip": sum(flip) / len(flip) if flip else None,
                "worse": "" if n == ranking.NONE else f"{worse} of {len(recs)}",
                "baseline": n == ranking.NONE,
            }
        )
    rows.sort(key=lambda r: (r["baseline"], r["vis"] is None, r["vis"] or 0.0))
    for r in rows:
        r["vis"], r["flip"] = columns.fixed(4)(r["vis"]), columns.fixed(4)(r["flip"])
    return rows


def render_suite(result: dict) -> str:
    """Return the suite's ``index.html`` for :func:`hzval.report.overview.write_overview`'s ``result``."""
    info = SuiteResult.of(result).techniques
    names = list(info)
    s = result["suite"]
    context = {
        "count": s["materials"],
        "failed": s["failed"],
        "not_run": s.get("not_run", 0),
        "interrupted": s.get("interrupted", False),
        "engine": s["engine"],
        "workers": s["workers"],
        "seconds": columns.fmt_seconds(s["seconds"]),
        "versions": s.get("versions") or {},
        "command": s["command"],
        "techniques": [{"name": n, **info[n]} for n in names],
        "rows": [_suite_row(r, names) for r in result["materials"]],
        "ranking": suite_ranking(result),
        "gates": result.get("gates") if isinstance(result.get("gates"), dict) else None,
    }
    return report.environment().get_template("suite.html.j2").render(**context)
