"""The HTML comparison report of a sweep (docs/ARCHITECTURE.md).

:func:`write_report` turns the content of ``metrics.json`` into
``out/index.html`` and ``out/plots/*.png``. The page is self-contained: no
network, no frameworks; its CSS and JavaScript are inline, and its images
are the sweep's PNG previews beside it, referenced by relative, URL-quoted
paths. It opens from disk.

What it shows, top to bottom: the material, every parameter, the versions
and the machine, the timings, which effects each side simulated, and the
command that reproduces the run; the worst value of each metric at a
glance; a table of every frame (worst values highlighted); the metrics
against azimuth and where the time goes (matplotlib, Agg); and per frame
truth | horizon-mapped | plain normal mapping | FLIP | visibility
difference, with a swipe comparison, hover/click flipping between truth
and the lead technique, and pixel zoom.

Every value from ``metrics`` reaches the page through Jinja2 with
autoescaping (attribute values included); data for the script goes
through ``|tojson`` only, and file paths are URL-quoted
(:func:`urllib.parse.quote`) before they are escaped into ``src``/``href``.
"""

from __future__ import annotations

import math
from pathlib import Path
from urllib.parse import quote

import jinja2
from PIL import Image

from hzval.io import atomic, codecs, staging
from hzval.metrics import compare
from hzval.metrics.results import FrameRecord, SweepResult
from hzval.report import columns, images, plots, ranking

__all__ = [
    "TEMPLATES",
    "build_context",
    "environment",
    "render_html",
    "write_report",
    "write_plots",
    "write_page",
]
TEMPLATES = Path(__file__).parent / "templates"


def _src(out: Path, rel) -> dict | None:
    """Return a file of the report as ``{"src", "path", "full", "width"}``; ``None`` if absent.

    ``src`` is the URL-quoted relative path and ``path`` the path as given. A large PNG with a preview
    (:func:`hzval.io.codecs.preview_of`) is shown by its preview: ``src`` is the preview's, ``full`` the
    file's own URL and ``width`` its width in pixels, which the page loads when the reader zooms in (else both
    ``None``).
    """
    if not isinstance(rel, str) or not rel:
        return None
    if not (out / rel).is_file():
        return {"src": None, "path": rel, "full": None, "width": None}
    url = quote(rel.replace("\\", "/"), safe="/")
    preview = codecs.preview_of(rel)
    if rel.endswith(".png") and (out / preview).is_file():
        with Image.open(out / rel) as img:  # reads the header only
            width = img.size[0]
        return {"src": quote(preview, safe="/"), "path": rel, "full": url, "width": width}
    return {"src": url, "path": rel, "full": None, "width": None}


def _columns(frames: list[dict], metrics: tuple[columns.Metric, ...]) -> list[dict]:
    """Per metric: the values, which frames are worst, the bar scale, and the summary."""
    cols = []
    for m in metrics:
        raw = [f.get(m.key) for f in frames]
        vals = []
        for r in raw:
            v = columns.num(r)
            if v is None and r is None and m.null_is is not None:
                v = m.null_is
            vals.append(v)
        measured = [v for v in vals if v is not None]
        worst_idx: set[int] = set()
        worst = best = None
        if measured:
            worst = max(measured) if m.worse == "max" else min(measured)
            best = min(measured) if m.worse == "max" else max(measured)
            # a column with no spread (e.g. no leaks anywhere) has no worst frame to point at
            if len(measured) >= 2 and worst != best and m.error:
                worst_idx = {i for i, v in enumerate(vals) if v == worst}
        top = max((abs(v) for v in measured if math.isfinite(v)), default=0.0)
        finite = [v for v in measured if math.isfinite(v)]
        mean = sum(finite) / len(finite) if finite else None
        mean_title = f"mean over {len(finite)} frame{'s' if len(finite) != 1 else ''}"
        if len(finite) < len(measured):
            mean_title += f" (without the {len(measured) - len(finite)} infinite)"
        if m.key == "psnr_db" and measured:  # decibels do not average: the frames' mean squared error
            mean = compare.pooled_psnr_db([f.get("rmse") for f in frames])
            mean_title = f"PSNR of the mean squared error over {len(measured)} frames"
        cols.append(
            {
                "metric": m,
                "vals": vals,
                "worst_idx": worst_idx,
                "worst": worst,
                "top": top,
                # all infinite (identical images): shown as the null value, "∞"
                "mean_text": m.fmt(mean) if mean is not None else (m.fmt(None) if measured else "—"),
                "mean_title": mean_title if measured else "not measured",
                "measured": bool(measured),
            }
        )
    return cols


def _cell(col: dict, i: int, frame: dict, starts: set[str]) -> dict:
    m: columns.Metric = col["metric"]
    v = col["vals"][i]
    raw = frame.get(m.key)
    if v is None:
        text, title = "—", f"{m.label}: not measured"
    else:
        text = m.fmt(raw)
        title = m.title
    bar = None
    if m.bar and v is not None and col["top"] > 0 and math.isfinite(v):
        bar = round(max(0.0, min(1.0, abs(v) / col["top"])), 4)
    floor = None
    # beside it, its perfect-shadows floor ("FLIP 0.085, of which 0.004 ...");
    # PSNR has none (higher is better)
    if m.floor and columns.num(frame.get(m.floor)) is not None and v is not None:
        floor = m.fmt(frame[m.floor])
        title += f" (perfect-shadows floor: {floor}, the part that is shading and noise)"
    return {
        "key": m.key,
        "label": m.label,
        "text": text,
        "worst": i in col["worst_idx"],
        "bar": bar,
        "gstart": m.key in starts,
        "floor": floor,
        "title": title,
        "unit": m.unit if m.unit not in ("time", "%") else "",
    }


def _glance(cols: list[dict], frames: list[dict]) -> list[dict]:
    """Return the worst value of each quality metric and the frame it comes from."""
    tiles = []
    for col in cols:
        m: columns.Metric = col["metric"]
        if m.unit == "time" or m.key == "rmse" or not m.error:
            continue
        if not col["measured"]:
            tiles.append(
                {
                    "label": m.label,
                    "value": "not measured",
                    "where": "",
                    "href": None,
                    "title": m.title,
                    "dim": True,
                }
            )
            continue
        idx = [i for i, v in enumerate(col["vals"]) if v == col["worst"]]
        i = idx[0]
        value = m.fmt(frames[i].get(m.key))
        if m.unit == "dB" and value != "∞":
            value += " dB"
        where = (
            "every frame"
            if len(idx) == len(frames) and len(frames) > 1
            else f"at {columns.fmt_deg(frames[i].get('azimuth_deg'))}"
        )
        kind = "lowest" if m.worse == "min" else "worst"
        tiles.append(
            {
                "label": f"{kind} {m.label}",
                "value": value,
                "where": where,
                "href": None if len(idx) == len(frames) and len(frames) > 1 else f"#frame-{i}",
                "title": m.title,
                "dim": False,
            }
        )
    return tiles


def _effects(parameters: dict, simulated: dict, views: list[columns.TechniqueView]) -> dict:
    """Return the declared effects, what the truth and each technique simulated, and what each left out."""
    declared = [str(e) for e in (parameters.get("effects") or [])]
    truth = [str(e) for e in (simulated.get("truth") or [])]
    rows, notes = [], []
    for v in views:
        own = [str(e) for e in (simulated.get(v.name) or [])]
        rows.append({"label": v.label, "colour": v.colour, "effects": own})
        notes += [f"{e}: not modelled by {v.label}" for e in declared if e not in own]
    notes += [f"{e}: not simulated by the truth" for e in declared if e not in truth]
    return {"declared": declared, "truth": truth, "techniques": rows, "notes": notes}


def _parameters(p: dict) -> list[dict]:
    groups, seen = [], set()
    for title, keys in columns.PARAMETER_GROUPS:
        rows = []
        for key, label in keys:
            if key in p:
                seen.add(key)
                value = p[key]
                text = columns.value_text(key, value)
                if key == "depth" and columns.num(value) is not None:
                    text = f"{value:g} × image width"
                elif key == "supersampling" and columns.num(value) is not None:
                    text = (
                        f"{value:g} × {value:g} (a magnification: image scores depend on it)"
                        if value != 1
                        else "1 (one pixel per texel)"
                    )
                rows.append({"label": label, "text": text, "key": key})
        if rows:
            groups.append({"title": title, "rows": rows})
    other = [
        {"label": k, "text": columns.value_text(k, v), "key": k}
        for k, v in p.items()
        if k not in seen and k != "effects"
    ]
    if other:
        groups.append({"title": "other", "rows": other})
    return groups


def _technique_parameters(metrics: dict, views: list[columns.TechniqueView]) -> list[dict]:
    """Each technique's own settings (``techniques[name].parameters``), for the parameters card."""
    info = SweepResult.of(metrics).techniques
    out = []
    for v in views:
        params = (info.get(v.name) or {}).get("parameters") or {}
        rows = [
            (k.replace("_", " "), columns.value_text(k, val)) for k, val in params.items() if k != "simulated"
        ]
        if rows:
            out.append({"label": v.label, "colour": v.colour, "rows": rows})
    return out


def _versions(v: dict) -> list[dict]:
    rows, seen = [], set()
    for key, label in columns.VERSION_LABELS:
        if key in v:
            seen.add(key)
            rows.append({"label": label, "text": columns.value_text(key, v[key])})
    rows += [{"label": k, "text": columns.value_text(k, val)} for k, val in v.items() if k not in seen]
    return rows


def _material(m: dict, camera: dict | None = None) -> dict:
    digest = str(m.get("digest") or "")
    algo, _, hexpart = digest.partition(":")
    short = f"{algo}:{hexpart[:12]}" if hexpart else digest[:19]
    rows, cols = m.get("rows"), m.get("cols")
    size = f"{cols} × {rows} texels" if rows is not None and cols is not None else "—"
    return {
        "name": str(m.get("name") or "unnamed material"),
        "source": str(m.get("source") or "—"),
        "digest": digest,
        "digest_short": short or "—",
        "size": size,
        "path": None if m.get("path") is None else str(m.get("path")),
        "aspect": _aspect(cols, rows, camera or {}),
    }


def _aspect(cols, rows, camera: dict) -> str:
    """Return the images' aspect ratio: the camera's resolution, else the tile's."""
    res = camera.get("resolution")
    if isinstance(res, (list, tuple)) and len(res) == 2 and all(columns.num(c) for c in res):
        cols, rows = res
    return f"{int(cols)} / {int(rows)}" if columns.num(cols) and columns.num(rows) else "1 / 1"


def _view(out: Path, metrics: dict) -> dict | None:
    """Return the camera and the view's errors for a view other than ``top``; ``None`` for it.

    They are ``metrics.json``'s ``camera`` and ``view``.
    """
    cam, view = metrics.get("camera") or {}, metrics.get("view")
    if cam.get("kind", "top") == "top" or not isinstance(view, dict):
        return None

    def spread(d):
        d = d if isinstance(d, dict) else {}
        if columns.num(d.get("mean")) is None:
            return "—"
        return f"mean {d['mean']:.2f}, median {d['p50']:.2f}, p95 {d['p95']:.2f}, max {d['max']:.2f}"

    def vec(v):
        return "(" + ", ".join(f"{c:.1f}" for c in v) + ")" if isinstance(v, list) else "—"

    rows = [
        ("camera", str(cam.get("kind"))),
        ("eye", vec(cam.get("eye"))),
        ("target", vec(cam.get("target"))),
        ("resolution", " × ".join(str(c) for c in cam.get("resolution") or [])),
        (
            "pixels that see the surface",
            f"{100 * view['seen_fraction']:.1f}%"
            if columns.num(view.get("seen_fraction")) is not None
            else "—",
        ),
        ("parallax error (texels)", spread(view.get("parallax_error_texels"))),
        ("pixel footprint (texels)", spread(view.get("footprint_texels"))),
    ]
    if columns.num(cam.get("fov_deg")) is not None:
        rows.insert(3, ("field of view", f"{cam['fov_deg']:g}°"))
    maps = view.get("files") or {}
    return {
        "rows": [{"label": a, "text": b} for a, b in rows],
        "maps": [
            {"title": t, "file": _src(out, maps.get(k))}
            for k, t in (("parallax_error_png", "parallax error"), ("footprint_png", "pixel footprint"))
            if maps.get(k)
        ],
    }


def _group_starts(metrics: tuple[columns.Metric, ...]) -> set[str]:
    """Keys of the columns that open a column group (drawn with a rule before them)."""
    return {m.key for i, m in enumerate(metrics) if i == 0 or metrics[i - 1].group != m.group}


def _column_groups(metrics: tuple[columns.Metric, ...]) -> list[dict]:
    groups: list[dict] = []
    for m in metrics:
        if groups and groups[-1]["title"] == m.group:
            groups[-1]["span"] += 1
        else:
            groups.append({"title": m.group, "span": 1})
    return groups


def _shown_metrics(frames: list[dict], views: list[columns.TechniqueView]) -> tuple[columns.Metric, ...]:
    """Return the summary table's columns: the lead technique's scores, then the others'.

    They are the lead technique's scores, the render times, the floor where measured, then a few for each
    other technique.
    """
    if not views:
        return (columns.TRUTH_TIME,)
    lead = views[0]
    times = (
        columns.TRUTH_TIME,
        columns.Metric(
            f"{lead.name}_s",
            lead.name,
            "time",
            f"{lead.label}: frame time (Dr.Jit, kernels synchronised)",
            columns.fmt_seconds,
            group="render time",
            error=False,
        ),
    )
    truth = tuple(
        m for m in columns.TRUTH_METRICS if any(columns.num(f.get(m.key)) is not None for f in frames)
    )
    shown = columns.lead_metrics(lead, frames) + truth + times
    if any(columns.num(f.get("floor_flip_mean")) is not None for f in frames):
        shown += columns.FLOOR_METRICS
    for v in views[1:]:
        shown += columns.technique_metrics(v)
    # a column no frame has at all (hzval score's engine without F images or times) is left out; one
    # that frames have as null stays, "not measured" (or, for PSNR, infinite)
    return tuple(m for m in shown if any(m.key in f for f in frames))


def _technique_files(f: dict, v: columns.TechniqueView) -> dict:
    """Return a technique's files in a frame (``frames[i].techniques[name].files``)."""
    own = FrameRecord(f).scores(v.name)
    return own.files if own is not None else {}


def _frame_view(
    out: Path, i: int, f: dict, cols: list[dict], starts: set[str], views: list[columns.TechniqueView]
) -> dict:
    """One frame's card: its chips, the lead technique's panels beside the truth, the others' rows."""
    fl = f.get("files") or {}
    lead_files = _technique_files(f, views[0]) if views else {}
    own = {
        "truth_png": fl.get("truth_png"),
        "plain_png": fl.get("plain_png"),
        "lead_png": lead_files.get("png"),
        "flip_png": lead_files.get("flip_png"),
        "visdiff_png": lead_files.get("visdiff_png"),
    }
    panels = []
    for key, title, subtitle in columns.PANELS:
        if key == "lead_png":
            title = views[0].label if views else "technique"
        panels.append({"key": key, "title": title, "subtitle": subtitle, "file": _src(out, own.get(key))})
    raw = []
    for group, keys in columns.RAW_FILES:
        links = [{"label": label, "file": _src(out, fl.get(key))} for key, label in keys]
        links = [r for r in links if r["file"] and r["file"]["src"]]
        if links:
            raw.append({"group": group, "links": links})
    rows = []
    for v in views:
        tf = _technique_files(f, v)
        links = [
            {"label": label, "file": _src(out, tf.get(key))} for key, label in columns.TECHNIQUE_RAW_FILES
        ]
        links = [r for r in links if r["file"] and r["file"]["src"]]
        if links:
            raw.append({"group": f"{v.name} EXR", "links": links})
        if v is not views[0]:
            rows.append(
                {
                    "name": v.name,
                    "label": v.label,
                    "colour": v.colour,
                    "panels": [
                        {
                            "key": key,
                            "title": f"{v.name} {title}" if title else v.label,
                            "subtitle": subtitle,
                            "file": _src(out, tf.get(key)),
                        }
                        for key, title, subtitle in columns.TECHNIQUE_PANELS
                    ],
                }
            )
    return {
        "index": i,
        "id": f"frame-{i}",
        "technique_rows": rows,
        "azimuth": columns.frame_label(f),
        "elevation": columns.fmt_deg(f.get("elevation_deg")).lstrip("+"),
        "cells": [_cell(c, i, f, starts) for c in cols],
        "panels": {p["key"]: p for p in panels},
        "raw": raw,
    }


def _worst_frame(
    out: Path, frames: list[dict], frame_views: list[dict], views: list[columns.TechniqueView]
) -> dict | None:
    """Return the report's first screen: the lead technique's worst frame, truth | technique | difference.

    The worst frame is the one where the lead technique's |F - V| (over the pixels that face the light, where
    measured; else its FLIP) is largest.
    """
    if not views or not frames:
        return None
    lead = views[0]
    pairs = ((f"{lead.name}_visibility_mae", "|F−V|"), (f"{lead.name}_flip_mean", "FLIP"))
    for key, label in pairs:  # noqa: B007 (the label of the metric found is read after the loop)
        vals = [columns.num(f.get(key)) for f in frames]
        if any(v is not None for v in vals):
            break
    else:
        return None
    i = max(range(len(frames)), key=lambda k: -math.inf if vals[k] is None else vals[k])
    p = frame_views[i]["panels"]
    diff = (
        p["visdiff_png"]
        if p["visdiff_png"]["file"] and p["visdiff_png"]["file"].get("src")
        else p["flip_png"]
    )
    panels = [
        {"title": "truth", "subtitle": "ray-traced", "file": p["truth_png"]["file"], "visdiff": False},
        {"title": lead.label, "subtitle": "", "file": p["lead_png"]["file"], "visdiff": False},
    ]
    rows = frame_views[i]["technique_rows"]
    if lead.name == "engine" and rows:  # hzval score: the sweep's first technique beside the engine
        panels.append(
            {
                "title": rows[0]["label"],
                "subtitle": "hzval, the same sweep",
                "file": rows[0]["panels"][0]["file"],
                "visdiff": False,
            }
        )
    panels.append(
        {
            "title": f"{lead.label}: {diff['title']}",
            "subtitle": diff["subtitle"],
            "file": diff["file"],
            "visdiff": diff is p["visdiff_png"],
        }
    )
    return {
        "index": i,
        "id": frame_views[i]["id"],
        "azimuth": frame_views[i]["azimuth"],
        "metric": label,
        "value": columns.fixed(4)(vals[i]),
        "lead": lead.label,
        "panels": panels,
    }


def _visibility_scope(metrics: dict) -> str | None:
    """Say what the report's visibility columns are measured over (:data:`columns.FACING`), in words."""
    frames = SweepResult.of(metrics).frames
    facing = any("visibility_mae_facing" in t for f in frames for t in f.techniques.values())
    if not facing:
        return None
    away = [columns.num((f.get("truth") or {}).get("attached_fraction")) for f in frames]
    away = [a for a in away if a is not None]
    share = f" ({100 * (1 - sum(away) / len(away)):.0f}% of them on average)" if away else ""
    return (
        f"|F−V|, leaks and false shadows are over the pixels that face the light{share}: those facing away "
        "(attached shadows) are black in every image whatever F and V. metrics.json has both: "
        "visibility_mae (the whole image) and visibility_mae_facing."
    )


def build_context(out: Path, metrics: dict, command: str, plot_files: dict[str, str | None]) -> dict:
    """Everything the template needs, formatted; no markup."""
    out = Path(out)
    views = columns.technique_views(metrics)
    frames = columns.flatten([f for f in (metrics.get("frames") or []) if isinstance(f, dict)], views)
    shown = _shown_metrics(frames, views)
    starts = _group_starts(shown)
    parameters = metrics.get("parameters") or {}
    cols = _columns(frames, shown)
    material = _material(metrics.get("material") or {}, metrics.get("camera") or {})
    frame_views = [_frame_view(out, i, f, cols, starts, views) for i, f in enumerate(frames)]

    azimuths = parameters.get("azimuths_deg") or [f.get("azimuth_deg") for f in frames]
    elevation = parameters.get("elevation_deg", frames[0].get("elevation_deg") if frames else None)
    elevations = parameters.get("elevations_deg") or [elevation]
    light = str(parameters.get("light", "—"))
    if light == "soft" and columns.num(parameters.get("light_radius_deg")) is not None:
        light = f"soft, radius {columns.fmt_deg(parameters['light_radius_deg']).lstrip('+')}"
    subtitle = (
        f"{len(frames)} frame{'s' if len(frames) != 1 else ''} · azimuth {columns.azimuth_text(azimuths)} · "
        + (
            f"elevation {columns.fmt_deg(elevation).lstrip('+')}"
            if len(elevations) < 2
            else "elevations " + ", ".join(columns.fmt_deg(e).lstrip("+") for e in elevations)
        )
        + f" · {light} light"
    )

    return {
        "material": material,
        "subtitle": subtitle,
        "command": command or "",
        "parameters": _parameters(parameters),
        "effects": _effects(parameters, metrics.get("simulated") or {}, views),
        "versions": _versions(metrics.get("versions") or {}),
        "timings": columns.timing_rows(metrics.get("timings") or {}, len(frames), views),
        "columns": [
            {
                "label": c["metric"].label,
                "unit": c["metric"].unit,
                "title": c["metric"].title,
                "key": c["metric"].key,
                "mean_text": c["mean_text"],
                "mean_title": c["mean_title"],
                "gstart": c["metric"].key in starts,
            }
            for c in cols
        ],
        "column_groups": _column_groups(shown),
        "glance": _glance(cols, frames),
        "frames": frame_views,
        "first": _worst_frame(out, frames, frame_views, views),
        "visibility_scope": _visibility_scope(metrics),
        "gates": metrics.get("gates") if isinstance(metrics.get("gates"), dict) else None,
        "techniques": [{"name": v.name, "label": v.label, "colour": v.colour} for v in views],
        "warnings": [str(w) for w in (metrics.get("warnings") or [])],
        "technique_parameters": _technique_parameters(metrics, views),
        "ranking": _ranking(metrics, views),
        "view": _view(out, metrics),
        "plots": plot_files,
        "splits": [plots.split_context(frames, sv) for sv in plots.split_views(metrics, views)],
        "leak_hex": images.hex_colour(images.LEAK_RGB),
        "false_shadow_hex": images.hex_colour(images.FALSE_SHADOW_RGB),
        "truth_colour": columns.TRUTH_COLOUR,
        "lead_colour": views[0].colour if views else columns.TECHNIQUE_COLOURS[0],
        # the script's data: labels of the two sides, and the zoom steps
        "js": {
            "labels": {"truth": "truth", "lead": views[0].label if views else "technique"},
            "zooms": [0, 1, 2, 4, 8],
        },
    }


def _ranking(metrics: dict, views: list[columns.TechniqueView]) -> dict | None:
    """Return the report's first table (:func:`hzval.report.ranking.ranking`), formatted."""
    rows = ranking.ranking(metrics)
    if not rows:
        return None
    colours = {v.name: v.colour for v in views}
    several = len({f.get("elevation_deg") for f in metrics.get("frames") or [] if isinstance(f, dict)}) > 1

    def at(elevations):
        return " at " + ", ".join(f"{e:g}°" for e in elevations) if several else ""

    def worse(r):
        out = "worse than no shadows" + at(r["worse_at"]) if r["worse_at"] else ""
        if r["harms_at"]:
            out += (
                ("; " if out else "")
                + "even its fitted floor"
                + at(r["harms_at"])
                + ": the formula does harm"
            )
        return out

    out = []
    for i, r in enumerate(rows):
        out.append(
            {
                "rank": "" if r["baseline"] else str(1 + sum(not x["baseline"] for x in rows[:i])),
                "label": r["label"],
                "colour": colours.get(r["name"], plots.NONE_COLOUR),
                "vis": columns.fixed(4)(r["visibility_mae"]),
                "floor": columns.fixed(4)(r["floor"]),
                "bake_loss": columns.fixed(4)(r["bake_loss"]),
                "hits": columns.fixed(4)(r["at_hits"]),
                "flip": columns.fixed(4)(r["flip_mean"]),
                "bytes": "—" if r["bytes_per_texel"] is None else f"{r['bytes_per_texel']:g}",
                "ms": "—" if r["ms_per_frame"] is None else f"{r['ms_per_frame']:.1f}",
                "worse": worse(r),
                "baseline": r["baseline"],
            }
        )
    hits = any(r["at_hits"] is not None for r in rows)
    floors = any(r["floor"] is not None for r in rows)
    return {
        "rows": out,
        "several": several,
        "hits": hits,
        "floors": floors,
        "note": ranking.floor_note(metrics),
    }


def environment():
    """Return the Jinja2 environment of the report's templates (autoescaped HTML)."""
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(str(TEMPLATES)),
        autoescape=jinja2.select_autoescape(
            enabled_extensions=("html", "htm", "xml", "j2"), default_for_string=True, default=True
        ),
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=True,
    )
    return env


def render_html(context: dict) -> str:
    """Return the page for a :func:`build_context` result."""
    return environment().get_template("report.html.j2").render(**context)


def write_report(out: str | Path, metrics: dict, *, command: str) -> Path:
    """Write ``out/index.html`` and ``out/plots/*.png`` for a sweep's ``metrics``; return the index path.

    ``metrics`` is the content of ``out/metrics.json`` (docs/ARCHITECTURE.md); its file
    paths are relative to ``out``. ``command`` is the command line that
    reproduces the run. Every file is written atomically. :func:`write_plots`, then
    :func:`write_page`: a caller that times the run stops its clock between the two, so that the
    page shows the run's whole time.
    """
    return write_page(out, metrics, write_plots(out, metrics), command=command)


def write_plots(out: str | Path, metrics: dict) -> dict[str, str | None]:
    """Write the report's plots of a sweep's ``metrics`` into ``out/plots``.

    It returns their paths relative to ``out`` (``None``: a plot the sweep has no data for).
    """
    out = Path(out)
    frames = [f for f in (metrics.get("frames") or []) if isinstance(f, dict)]
    views = columns.technique_views(metrics)
    plots.plot_metrics(out / "plots" / "metrics.png", frames, views)
    plots.plot_timings(out / "plots" / "timings.png", metrics.get("timings") or {}, frames, views)
    plot_files = {"metrics": "plots/metrics.png", "timings": "plots/timings.png", "elevation": None}
    table = ranking.by_elevation(metrics)
    if len(next(iter(table.values()), [])) > 1:  # light elevation is a sweep axis
        plots.plot_elevation(out / "plots" / "elevation.png", table, views)
        plot_files["elevation"] = "plots/elevation.png"
    for sv in plots.split_views(metrics, views):
        plots.plot_split(out / sv.plot, frames, sv)
    per_byte = ranking.error_per_byte(metrics)
    plot_files["error_per_byte"] = None
    if any(p["bytes_per_texel"] > 0 for points in per_byte.values() for p in points):
        plots.plot_error_per_byte(out / "plots" / "error_per_byte.png", per_byte, views)
        plot_files["error_per_byte"] = "plots/error_per_byte.png"
    return plot_files


def write_page(out: str | Path, metrics: dict, plot_files: dict, *, command: str) -> Path:
    """``out/index.html`` of a sweep's ``metrics`` and its :func:`write_plots`; the index path."""
    out = Path(out)
    html = render_html(build_context(out, metrics, staging.portable_command(command), plot_files))
    index = out / "index.html"
    with atomic.atomic_path(index) as tmp:
        tmp.write_text(html, encoding="utf-8")
    return index
