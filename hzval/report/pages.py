"""The HTML comparison report of a sweep (docs/ARCHITECTURE.md; issue 5).

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
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Callable
from urllib.parse import quote

from hzval.io import files
from hzval.report import images
from hzval.techniques import registry as technique

__all__ = [
    "TRUTH_COLOUR",
    "TECHNIQUE_COLOURS",
    "TECHNIQUE_STYLES",
    "TEMPLATES",
    "fmt_deg",
    "fmt_seconds",
    "Metric",
    "TECHNIQUE_METRICS",
    "OPTIONAL_METRICS",
    "TRUTH_TIME",
    "TRUTH_METRICS",
    "FACING",
    "FLOOR_METRICS",
    "TechniqueView",
    "technique_views",
    "PANELS",
    "TECHNIQUE_PANELS",
    "RAW_FILES",
    "TECHNIQUE_RAW_FILES",
    "build_context",
    "FLOOR_COLOUR",
    "plot_metrics",
    "plot_timings",
    "SPLIT_COLOURS",
    "SplitView",
    "split_views",
    "plot_split",
    "render_html",
    "write_report",
    "render_suite",
]

#: The truth's colour, on the page and in the plots.
TRUTH_COLOUR = "#7fd1ae"
#: The techniques' colours, in the order ``metrics.json`` lists them (the
#: first is the lead technique's, the page's "lead" side beside the truth).
TECHNIQUE_COLOURS = ("#b9a3ff", "#f2c14e", "#6cc3ff", "#ff8fa3", "#c7e36b")
#: Line styles of the techniques in the plots, in the same order.
TECHNIQUE_STYLES = ("-", "--", ":", "-.", (0, (5, 1, 1, 1)))

#: Plot palette (matches the page's dark neutral theme).
_BG, _PANEL, _TEXT, _MUTED, _GRID, _ACCENT, _WORST = (
    "#1f1f22",
    "#1f1f22",
    "#e4e4e7",
    "#9b9ba3",
    "#34343a",
    "#e8e8ec",
    "#ff6b6b",
)

TEMPLATES = Path(__file__).parent / "templates"


# --------------------------------------------------------------------------
# Formatting
# --------------------------------------------------------------------------


def _num(x) -> float | None:
    """A finite float, or ``None`` (missing, null, NaN, not a number)."""
    if isinstance(x, bool) or x is None:
        return None
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def fmt_deg(x) -> str:
    """``-60`` -> ``−60°``, ``0`` -> ``0°``, ``7.5`` -> ``+7.5°``."""
    v = _num(x)
    if v is None:
        return "—"
    if v == 0:
        return "0°"
    return f"{v:+g}°".replace("-", "\u2212")


def fmt_seconds(x) -> str:
    """Seconds with a unit that suits them: ``850 µs``, ``12.3 ms``, ``1.25 s``."""
    v = _num(x)
    if v is None:
        return "—"
    a = abs(v)
    if a == 0:
        return "0 s"
    if a < 1e-3:
        return f"{v * 1e6:.0f} µs"
    if a < 1:
        return f"{v * 1e3:.3g} ms" if a < 0.1 else f"{v * 1e3:.0f} ms"
    if a < 100:
        return f"{v:.2f} s"
    return f"{v:.0f} s"


def _fixed(digits: int) -> Callable[[Any], str]:
    return lambda v: "—" if _num(v) is None else f"{_num(v):.{digits}f}"


def _percent(v) -> str:
    v = _num(v)
    return "—" if v is None else f"{100 * v:.2f} %"


def _psnr(v) -> str:
    v = _num(v)
    return "∞" if v is None else f"{v:.2f}"


@dataclass(frozen=True)
class Metric:
    """A column of the summary table and a chip of each frame."""

    key: str
    label: str  # short, for the table head and chips
    unit: str  # shown after the label in the table head, or ""
    title: str  # tooltip: what it is and how it was computed
    fmt: Callable[[Any], str]
    worse: str = "max"  # "max": larger is worse; "min": smaller is worse
    null_is: float | None = None  # the value ``null`` stands for (PSNR: +inf), else "not measured"
    bar: bool = True  # draw a data bar (share of the column's largest value)
    group: str = ""  # the table's column group
    floor: str | None = None  # the flattened key of its perfect-shadows floor, shown beside it
    error: bool = True  # an error (marked "worst" where largest); times and the truth's statistics are not


#: A technique's scores (keys of ``frames[i].techniques[name]``); the lead technique's are the summary
#: table's first columns (:func:`_lead_metrics`).
TECHNIQUE_METRICS: tuple[Metric, ...] = (
    Metric(
        "visibility_mae",
        "|F−V|",
        "",
        "Visibility: mean |F − V| over pixels, the technique's factor F against "
        "ray-traced visibility V, both in [0, 1]",
        _fixed(4),
        group="visibility",
    ),
    Metric(
        "leak_fraction",
        "leaks",
        "%",
        "Light leaks: pixels the technique lights (F ≥ 0.5) that the truth "
        "shadows (V < 0.5), as a share of all pixels",
        _percent,
        group="visibility",
    ),
    Metric(
        "false_shadow_fraction",
        "false shadows",
        "%",
        "False shadows: pixels the technique shadows "
        "(F < 0.5) that the truth lights (V ≥ 0.5), as a share of all pixels",
        _percent,
        group="visibility",
    ),
    Metric(
        "flip_mean",
        "FLIP",
        "",
        "Mean FLIP error (NVIDIA, LDR, 67 pixels per degree) on display "
        "values: 0 = identical, 1 = maximally different",
        _fixed(4),
        group="image",
        floor="floor_flip_mean",
    ),
    Metric(
        "delta_e2000_mean",
        "ΔE2000",
        "",
        "Mean CIEDE2000 colour difference on display (sRGB) values; about 1 is just noticeable",
        _fixed(3),
        group="image",
        floor="floor_delta_e2000_mean",
    ),
    Metric(
        "rmse",
        "RMSE",
        "",
        "Root mean square error on linear values (the largest radiance the declared effects can produce = 1)",
        _fixed(4),
        group="image",
        floor="floor_rmse",
    ),
    Metric(
        "psnr_db",
        "PSNR",
        "dB",
        "Peak signal-to-noise ratio on linear values, peak 1; ∞ = identical. Lower is worse",
        _psnr,
        worse="min",
        null_is=math.inf,
        bar=False,
        group="image",
    ),
    Metric(
        "reflection_mae",
        "|o−R|",
        "",
        "Reflection occlusion: mean |o − R| over pixels, the technique's "
        "reflection fade o against the ray-traced unoccluded fraction R of the glossy lobe about the mirror "
        "direction",
        _fixed(4),
        group="reflection",
    ),
    Metric(
        "perfect_parallax_mae",
        "|F−V| at hit",
        "",
        "At perfect parallax: mean |F − V| with the textures "
        "read at the truth's own hit point of each sample rather than where the camera ray meets the flat "
        "plane; the difference from |F−V| is the parallax error's share",
        _fixed(4),
        group="parallax",
    ),
)
#: Shown only where a frame has them: the reflection fade (scenes that declare
#: ``reflection_occlusion``), and the factor at the truth's own hit points (a view other than ``top``).
OPTIONAL_METRICS = ("reflection_mae", "perfect_parallax_mae")

TRUTH_TIME = Metric(
    "truth_s",
    "truth",
    "time",
    "Ground-truth render time of the frame (Mitsuba, kernels synchronised)",
    fmt_seconds,
    group="render time",
    error=False,
)

#: What the truth has to shadow (``frames[i].truth``, flattened to ``truth_<key>``,
#: :mod:`hzval.metrics.facing`).
TRUTH_METRICS: tuple[Metric, ...] = (
    Metric(
        "truth_shadowed_fraction",
        "shadowed",
        "%",
        "The truth's shadowed pixels (V < 0.5), as a share of all pixels",
        _percent,
        group="truth",
        error=False,
    ),
    Metric(
        "truth_attached_fraction",
        "facing away",
        "%",
        "Attached shadows: pixels whose surface faces away "
        "from the light (N·L ≤ 0), black in every image; the visibility columns leave them out",
        _percent,
        group="truth",
        error=False,
    ),
)
#: The visibility metrics the report shows over the pixels that face the light, when a frame has them.
FACING = {
    "visibility_mae": "visibility_mae_facing",
    "leak_fraction": "leak_fraction_facing",
    "false_shadow_fraction": "false_shadow_fraction_facing",
}

#: The perfect-shadows floor (``frames[i]["floor"]``, flattened to ``floor_<key>``): the
#: techniques' unshadowed shading times the truth's visibility, scored against the truth.
FLOOR_METRICS: tuple[Metric, ...] = (
    Metric(
        "floor_flip_mean",
        "floor FLIP",
        "",
        "Perfect-shadows floor: FLIP of the techniques' unshadowed "
        "shading times the truth's own visibility V, against the truth. The part of every technique's FLIP "
        "that is shading and noise, not shadows",
        _fixed(4),
        group="floor",
    ),
    Metric(
        "floor_rmse",
        "floor RMSE",
        "",
        "Perfect-shadows floor: RMSE (linear) of the unshadowed shading times V against the truth",
        _fixed(4),
        group="floor",
    ),
)


@dataclass(frozen=True)
class TechniqueView:
    """A technique as the report shows it (``metrics.json``'s ``techniques``)."""

    name: str
    label: str
    stem: str
    colour: str
    style: object
    parallax: bool = False  # a view measured its factor at the truth's hit points


def technique_views(metrics: dict) -> list[TechniqueView]:
    """The techniques of a sweep's ``metrics`` (``techniques``), in their order; the first leads."""
    info = metrics.get("techniques")
    info = info if isinstance(info, dict) else {}
    views = []
    frames = [f for f in (metrics.get("frames") or []) if isinstance(f, dict)]
    for i, (name, t) in enumerate(info.items()):
        t = t if isinstance(t, dict) else {}
        parallax = any(
            isinstance((f.get("techniques") or {}).get(name), dict)
            and "perfect_parallax_mae" in f["techniques"][name]
            for f in frames
        )
        views.append(
            TechniqueView(
                str(name),
                str(t.get("label") or name),
                str(t.get("file_stem") or name),
                TECHNIQUE_COLOURS[i % len(TECHNIQUE_COLOURS)],
                TECHNIQUE_STYLES[i % len(TECHNIQUE_STYLES)],
                parallax,
            )
        )
    return views


def _flatten(frames: list[dict], views: list[TechniqueView]) -> list[dict]:
    """Frames with every technique's metrics lifted to ``<name>_<key>`` and its seconds to ``<name>_s``."""
    out = []
    for f in frames:
        per = f.get("techniques") if isinstance(f.get("techniques"), dict) else {}
        g = dict(f)
        if isinstance(f.get("floor"), dict):
            g.update({f"floor_{k}": val for k, val in f["floor"].items()})
        if isinstance(f.get("truth"), dict):
            g.update({f"truth_{k}": val for k, val in f["truth"].items()})
        for v in views:
            m = per.get(v.name)
            if isinstance(m, dict):
                g.update({f"{v.name}_{k}": val for k, val in m.items() if k not in ("files", "seconds")})
                # the report's visibility columns: over the pixels that face the light, where measured
                for whole, facing in FACING.items():
                    if facing in m:
                        g[f"{v.name}_{whole}_whole"] = m.get(whole)
                        g[f"{v.name}_{whole}"] = m[facing]
                if "seconds" in m:  # hzval score's engine has no render time: no column
                    g[f"{v.name}_s"] = m["seconds"]
        out.append(g)
    return out


def _lead_metrics(v: TechniqueView, frames: list[dict]) -> tuple["Metric", ...]:
    """The summary table's columns of the lead technique: every score it has in some frame."""
    shown = []
    for m in TECHNIQUE_METRICS:
        key = f"{v.name}_{m.key}"
        if m.key in OPTIONAL_METRICS and not any(_num(f.get(key)) is not None for f in frames):
            continue
        # the headline scores carry the technique's name, as every other technique's columns do
        label = f"{v.name} {m.label}" if m.key in ("visibility_mae", "flip_mean") else m.label
        shown.append(replace(m, key=key, label=label, group=f"{v.name} · {m.group}"))
    return tuple(shown)


def _technique_metrics(v: TechniqueView) -> tuple["Metric", ...]:
    """The summary table's columns of a technique after the lead."""
    return (
        Metric(
            f"{v.name}_visibility_mae",
            f"{v.name} |F−V|",
            "",
            f"{v.label}: mean |F − V| over pixels against the same ray-traced visibility",
            _fixed(4),
            group=v.name,
        ),
        Metric(
            f"{v.name}_flip_mean",
            f"{v.name} FLIP",
            "",
            f"{v.label}: mean FLIP error against the truth (display values)",
            _fixed(4),
            group=v.name,
            floor="floor_flip_mean",
        ),
        *(
            (
                Metric(
                    f"{v.name}_perfect_parallax_mae",
                    f"{v.name} at hit",
                    "",
                    f"{v.label}: mean |F − V| with "
                    "its textures read at the truth's own hit points (perfect parallax)",
                    _fixed(4),
                    group=v.name,
                ),
            )
            if v.parallax
            else ()
        ),
        Metric(
            f"{v.name}_s",
            v.name,
            "time",
            f"{v.label}: frame time, the unshadowed shading it multiplies "
            "included (Dr.Jit, kernels synchronised)",
            fmt_seconds,
            group=v.name,
            error=False,
        ),
    )


#: The images of a frame, in the order of the row, with their captions.
PANELS: tuple[tuple[str, str, str], ...] = (
    ("truth_png", "truth", "ray-traced, Mitsuba"),
    ("lead_png", "", "Dr.Jit"),
    ("plain_png", "normal mapping only", "no shadows"),
    ("flip_png", "FLIP error", ""),
    ("visdiff_png", "visibility difference", "F against V"),
)
#: A technique's images after the lead's (keys of ``frames[i]["techniques"][name]["files"]``).
TECHNIQUE_PANELS: tuple[tuple[str, str, str], ...] = (
    ("png", "", "Dr.Jit"),
    ("flip_png", "FLIP error", ""),
    ("visdiff_png", "visibility difference", "F against V"),
)

#: Raw files of a frame, linked from its card: (group, [(key, label)]).
RAW_FILES: tuple[tuple[str, tuple[tuple[str, str], ...]], ...] = (
    ("EXR", (("truth", "truth"), ("plain", "plain"), ("visibility", "V"), ("truth_variance", "variance"))),
    ("PNG", (("visibility_png", "V"),)),
)

#: A technique's raw files (keys of ``frames[i]["techniques"][name]["files"]``).
TECHNIQUE_RAW_FILES: tuple[tuple[str, str], ...] = (
    ("image", "image"),
    ("factor", "F"),
    ("factor_png", "F png"),
)

_PARAMETER_GROUPS: tuple[tuple[str, tuple[tuple[str, str], ...]], ...] = (
    ("surface", (("depth", "depth"), ("boundary", "boundary"), ("truth_tolerance", "truth tolerance"))),
    (
        "light",
        (
            ("light", "light"),
            ("light_radius_deg", "light radius"),
            ("elevation_deg", "elevation"),
            ("azimuths_deg", "azimuths"),
        ),
    ),
    ("sampling", (("spp", "samples per pixel"), ("supersampling", "pixels per texel"), ("seed", "seed"))),
    (
        "view",
        (
            ("camera", "camera"),
            ("view_elevation_deg", "view elevation"),
            ("view_azimuth_deg", "view azimuth"),
            ("fov_deg", "field of view"),
            ("distance_tiles", "distance (tile widths)"),
            ("plane", "techniques' plane"),
            ("filter", "texture filter"),
            ("mips", "mip-maps"),
            ("max_anisotropy", "max anisotropy"),
            ("parallax", "parallax mapping"),
            ("parallax_steps", "parallax steps"),
        ),
    ),
)

_TIMING_LABELS: tuple[tuple[str, str], ...] = (
    ("bake_s", "bake"),
    ("truth_setup_s", "truth set-up"),
    ("truth_s", "truth renders"),
    ("plain_setup_s", "normal mapping set-up"),
    ("plain_s", "normal mapping renders"),
    ("compare_s", "compare"),
    ("write_s", "write frames"),
    ("report_s", "report"),
)


def _timing_labels(views: list[TechniqueView]) -> tuple[tuple[str, str], ...]:
    """The stages of a sweep's timings: the fixed ones, then each technique's set-up and renders."""
    fixed = _TIMING_LABELS[:5]
    own = tuple(
        pair
        for v in views
        for pair in ((f"{v.stem}_setup_s", f"{v.label} set-up"), (f"{v.stem}_s", f"{v.label} renders"))
    )
    return fixed + own + _TIMING_LABELS[5:]


_VERSION_LABELS: tuple[tuple[str, str], ...] = (
    ("hzval", "hzval"),
    ("mitsuba", "Mitsuba"),
    ("drjit", "Dr.Jit"),
    ("llvm", "LLVM"),
    ("variant", "variant"),
    ("python", "Python"),
    ("machine", "machine"),
)


def _value_text(key: str, value) -> str:
    """A parameter, version or material value as text."""
    if value is None:
        return "—"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if key == "azimuths_deg" and isinstance(value, (list, tuple)):
        return _azimuth_text(value)
    if key in ("elevation_deg", "light_radius_deg"):
        return fmt_deg(value).lstrip("+")
    if isinstance(value, (list, tuple)):
        return ", ".join(str(v) for v in value) or "none"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def _azimuth_text(values) -> str:
    vals = [_num(v) for v in values]
    if not vals or any(v is None for v in vals):
        return ", ".join(str(v) for v in values) or "none"
    n = len(vals)
    listed = ", ".join(fmt_deg(v) for v in vals)
    if n >= 3:
        steps = {round(b - a, 9) for a, b in zip(vals, vals[1:])}
        if len(steps) == 1 and next(iter(steps)) > 0:
            return f"{fmt_deg(vals[0])} … {fmt_deg(vals[-1])}, step {next(iter(steps)):g}° ({n} lights)"
    return f"{listed} ({n} light{'s' if n != 1 else ''})"


# --------------------------------------------------------------------------
# The view model: everything the template shows, formatted
# --------------------------------------------------------------------------


def _src(out: Path, rel) -> dict | None:
    """A file of the report as ``{"src": URL-quoted relative path, "path": as given, "full", "width"}``;
    ``None`` if absent. A large PNG with a preview (:func:`hzval.io.files.preview_of`) is shown by
    its preview: ``src`` is the preview's, ``full`` the file's own URL and ``width`` its width in
    pixels, which the page loads when the reader zooms in (else both ``None``)."""
    if not isinstance(rel, str) or not rel:
        return None
    if not (out / rel).is_file():
        return {"src": None, "path": rel, "full": None, "width": None}
    url = quote(rel.replace("\\", "/"), safe="/")
    preview = files.preview_of(rel)
    if rel.endswith(".png") and (out / preview).is_file():
        from PIL import Image

        with Image.open(out / rel) as img:  # reads the header only
            width = img.size[0]
        return {"src": quote(preview, safe="/"), "path": rel, "full": url, "width": width}
    return {"src": url, "path": rel, "full": None, "width": None}


def _columns(frames: list[dict], metrics: tuple[Metric, ...]) -> list[dict]:
    """Per metric: the values, which frames are worst, the bar scale, and the summary."""
    cols = []
    for m in metrics:
        raw = [f.get(m.key) for f in frames]
        vals = []
        for r in raw:
            v = _num(r)
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
    m: Metric = col["metric"]
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
    if m.floor and _num(frame.get(m.floor)) is not None and v is not None:
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
    """The worst value of each quality metric and the frame it comes from."""
    tiles = []
    for col in cols:
        m: Metric = col["metric"]
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
            else f"at {fmt_deg(frames[i].get('azimuth_deg'))}"
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


def _timings(t: dict, n_frames: int, views: list[TechniqueView]) -> dict:
    rows, known = [], set()
    per_frame = {"truth_s", "plain_s"} | {f"{v.stem}_s" for v in views}
    for key, label in _timing_labels(views):
        known.add(key)
        v = _num(t.get(key))
        if v is None:
            continue
        note = ""
        if key == "bake_s" and t.get("bake_cached"):
            note = "cached"
        elif key in per_frame and n_frames:
            note = f"{fmt_seconds(v / n_frames)} per frame"
        rows.append({"label": label, "seconds": v, "text": fmt_seconds(v), "note": note})
    for key, value in t.items():  # anything else the sweep timed
        if key in known or key in ("total_s", "bake_cached"):
            continue
        v = _num(value)
        if v is not None:
            rows.append(
                {
                    "label": key.removesuffix("_s").replace("_", " "),
                    "seconds": v,
                    "text": fmt_seconds(v),
                    "note": "",
                }
            )
    stages = sum(r["seconds"] for r in rows)
    total = _num(t.get("total_s"))
    for r in rows:
        r["share"] = f"{100 * r['seconds'] / stages:.0f} %" if stages > 0 else ""
    return {
        "rows": rows,
        "total_text": fmt_seconds(total if total is not None else stages),
        "total_is_sum": total is None,
        "stages": stages,
    }


def _effects(parameters: dict, simulated: dict, views: list[TechniqueView]) -> dict:
    """The declared effects, what the truth and each technique simulated, and what each left out."""
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
    for title, keys in _PARAMETER_GROUPS:
        rows = []
        for key, label in keys:
            if key in p:
                seen.add(key)
                value = p[key]
                text = _value_text(key, value)
                if key == "depth" and _num(value) is not None:
                    text = f"{value:g} × image width"
                elif key == "supersampling" and _num(value) is not None:
                    text = (
                        f"{value:g} × {value:g} (a magnification: image scores depend on it)"
                        if value != 1
                        else "1 (one pixel per texel)"
                    )
                rows.append({"label": label, "text": text, "key": key})
        if rows:
            groups.append({"title": title, "rows": rows})
    other = [
        {"label": k, "text": _value_text(k, v), "key": k}
        for k, v in p.items()
        if k not in seen and k != "effects"
    ]
    if other:
        groups.append({"title": "other", "rows": other})
    return groups


def _technique_parameters(metrics: dict, views: list[TechniqueView]) -> list[dict]:
    """Each technique's own settings (``techniques[name].parameters``), for the parameters card."""
    info = metrics.get("techniques") if isinstance(metrics.get("techniques"), dict) else {}
    out = []
    for v in views:
        params = (info.get(v.name) or {}).get("parameters") or {}
        rows = [(k.replace("_", " "), _value_text(k, val)) for k, val in params.items() if k != "simulated"]
        if rows:
            out.append({"label": v.label, "colour": v.colour, "rows": rows})
    return out


def _versions(v: dict) -> list[dict]:
    rows, seen = [], set()
    for key, label in _VERSION_LABELS:
        if key in v:
            seen.add(key)
            rows.append({"label": label, "text": _value_text(key, v[key])})
    rows += [{"label": k, "text": _value_text(k, val)} for k, val in v.items() if k not in seen]
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
    """The images' aspect ratio: the camera's resolution, else the tile's."""
    res = camera.get("resolution")
    if isinstance(res, (list, tuple)) and len(res) == 2 and all(_num(c) for c in res):
        cols, rows = res
    return f"{int(cols)} / {int(rows)}" if _num(cols) and _num(rows) else "1 / 1"


def _view(out: Path, metrics: dict) -> dict | None:
    """The camera and the view's errors (``metrics.json``'s ``camera`` and ``view``), for a view other
    than ``top``; ``None`` for it."""
    cam, view = metrics.get("camera") or {}, metrics.get("view")
    if cam.get("kind", "top") == "top" or not isinstance(view, dict):
        return None

    def spread(d):
        d = d if isinstance(d, dict) else {}
        if _num(d.get("mean")) is None:
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
            f"{100 * view['seen_fraction']:.1f}%" if _num(view.get("seen_fraction")) is not None else "—",
        ),
        ("parallax error (texels)", spread(view.get("parallax_error_texels"))),
        ("pixel footprint (texels)", spread(view.get("footprint_texels"))),
    ]
    if _num(cam.get("fov_deg")) is not None:
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


def _group_starts(metrics: tuple[Metric, ...]) -> set[str]:
    """Keys of the columns that open a column group (drawn with a rule before them)."""
    return {m.key for i, m in enumerate(metrics) if i == 0 or metrics[i - 1].group != m.group}


def _column_groups(metrics: tuple[Metric, ...]) -> list[dict]:
    groups: list[dict] = []
    for m in metrics:
        if groups and groups[-1]["title"] == m.group:
            groups[-1]["span"] += 1
        else:
            groups.append({"title": m.group, "span": 1})
    return groups


def _shown_metrics(frames: list[dict], views: list[TechniqueView]) -> tuple[Metric, ...]:
    """The summary table's columns: the lead technique's scores, the render times, the floor where
    measured, then a few for each other technique."""
    if not views:
        return (TRUTH_TIME,)
    lead = views[0]
    times = (
        TRUTH_TIME,
        Metric(
            f"{lead.name}_s",
            lead.name,
            "time",
            f"{lead.label}: frame time (Dr.Jit, kernels synchronised)",
            fmt_seconds,
            group="render time",
            error=False,
        ),
    )
    truth = tuple(m for m in TRUTH_METRICS if any(_num(f.get(m.key)) is not None for f in frames))
    shown = _lead_metrics(lead, frames) + truth + times
    if any(_num(f.get("floor_flip_mean")) is not None for f in frames):
        shown += FLOOR_METRICS
    for v in views[1:]:
        shown += _technique_metrics(v)
    # a column no frame has at all (hzval score's engine without F images or times) is left out; one
    # that frames have as null stays, "not measured" (or, for PSNR, infinite)
    return tuple(m for m in shown if any(m.key in f for f in frames))


def _technique_files(f: dict, v: TechniqueView) -> dict:
    """A technique's files in a frame (``frames[i].techniques[name].files``)."""
    per = f.get("techniques") if isinstance(f.get("techniques"), dict) else {}
    own = (per.get(v.name) or {}).get("files") if isinstance(per.get(v.name), dict) else None
    return own if isinstance(own, dict) else {}


def _frame_view(
    out: Path, i: int, f: dict, cols: list[dict], starts: set[str], views: list[TechniqueView]
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
    for key, title, subtitle in PANELS:
        if key == "lead_png":
            title = views[0].label if views else "technique"
        panels.append({"key": key, "title": title, "subtitle": subtitle, "file": _src(out, own.get(key))})
    raw = []
    for group, keys in RAW_FILES:
        links = [{"label": label, "file": _src(out, fl.get(key))} for key, label in keys]
        links = [r for r in links if r["file"] and r["file"]["src"]]
        if links:
            raw.append({"group": group, "links": links})
    rows = []
    for v in views:
        tf = _technique_files(f, v)
        links = [{"label": label, "file": _src(out, tf.get(key))} for key, label in TECHNIQUE_RAW_FILES]
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
                        for key, title, subtitle in TECHNIQUE_PANELS
                    ],
                }
            )
    return {
        "index": i,
        "id": f"frame-{i}",
        "technique_rows": rows,
        "azimuth": fmt_deg(f.get("azimuth_deg")),
        "elevation": fmt_deg(f.get("elevation_deg")).lstrip("+"),
        "cells": [_cell(c, i, f, starts) for c in cols],
        "panels": {p["key"]: p for p in panels},
        "raw": raw,
    }


def _worst_frame(
    out: Path, frames: list[dict], frame_views: list[dict], views: list[TechniqueView]
) -> dict | None:
    """The report's first screen: the frame where the lead technique's |F - V| (over the pixels that
    face the light, where measured; else its FLIP) is largest, as truth | technique | difference."""
    if not views or not frames:
        return None
    lead = views[0]
    pairs = ((f"{lead.name}_visibility_mae", "|F−V|"), (f"{lead.name}_flip_mean", "FLIP"))
    for key, label in pairs:  # noqa: B007 (the label of the metric found is read after the loop)
        vals = [_num(f.get(key)) for f in frames]
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
        "value": _fixed(4)(vals[i]),
        "lead": lead.label,
        "panels": panels,
    }


def _visibility_scope(metrics: dict) -> str | None:
    """What the report's visibility columns are measured over (:data:`FACING`), in words."""
    frames = [f for f in (metrics.get("frames") or []) if isinstance(f, dict)]
    facing = any(
        isinstance(t, dict) and "visibility_mae_facing" in t
        for f in frames
        for t in (f.get("techniques") or {}).values()
    )
    if not facing:
        return None
    away = [_num((f.get("truth") or {}).get("attached_fraction")) for f in frames]
    away = [a for a in away if a is not None]
    share = f" ({100 * (1 - sum(away) / len(away)):.0f}% of them on average)" if away else ""
    return (
        f"|F−V|, leaks and false shadows are over the pixels that face the light{share}: those facing away "
        "(attached shadows) are black in every image whatever F and V. metrics.json has both: "
        "visibility_mae (the whole image) and visibility_mae_facing."
    )


def build_context(out: Path, metrics: dict, command: str, plots: dict[str, str | None]) -> dict:
    """Everything the template needs, formatted; no markup."""
    out = Path(out)
    views = technique_views(metrics)
    frames = _flatten([f for f in (metrics.get("frames") or []) if isinstance(f, dict)], views)
    shown = _shown_metrics(frames, views)
    starts = _group_starts(shown)
    parameters = metrics.get("parameters") or {}
    cols = _columns(frames, shown)
    material = _material(metrics.get("material") or {}, metrics.get("camera") or {})
    frame_views = [_frame_view(out, i, f, cols, starts, views) for i, f in enumerate(frames)]

    azimuths = parameters.get("azimuths_deg") or [f.get("azimuth_deg") for f in frames]
    elevation = parameters.get("elevation_deg", frames[0].get("elevation_deg") if frames else None)
    light = str(parameters.get("light", "—"))
    if light == "soft" and _num(parameters.get("light_radius_deg")) is not None:
        light = f"soft, radius {fmt_deg(parameters['light_radius_deg']).lstrip('+')}"
    subtitle = (
        f"{len(frames)} frame{'s' if len(frames) != 1 else ''} · azimuth {_azimuth_text(azimuths)} · "
        f"elevation {fmt_deg(elevation).lstrip('+')} · {light} light"
    )

    return {
        "material": material,
        "subtitle": subtitle,
        "command": command or "",
        "parameters": _parameters(parameters),
        "effects": _effects(parameters, metrics.get("simulated") or {}, views),
        "versions": _versions(metrics.get("versions") or {}),
        "timings": _timings(metrics.get("timings") or {}, len(frames), views),
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
        "view": _view(out, metrics),
        "plots": plots,
        "splits": [_split_context(frames, sv) for sv in split_views(metrics, views)],
        "leak_hex": images.hex_colour(images.LEAK_RGB),
        "false_shadow_hex": images.hex_colour(images.FALSE_SHADOW_RGB),
        "truth_colour": TRUTH_COLOUR,
        "lead_colour": views[0].colour if views else TECHNIQUE_COLOURS[0],
        # the script's data: labels of the two sides, and the zoom steps
        "js": {
            "labels": {"truth": "truth", "lead": views[0].label if views else "technique"},
            "zooms": [0, 1, 2, 4, 8],
        },
    }


# --------------------------------------------------------------------------
# Plots (matplotlib, Agg, no pyplot state)
# --------------------------------------------------------------------------


def _figure(width: float, height: float):
    """A figure on an Agg canvas. Margins are set by hand: constrained layout
    would double the time a plot takes."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), facecolor=_BG)
    FigureCanvasAgg(fig)
    return fig


def _style_axes(ax, title: str) -> None:
    ax.set_facecolor(_PANEL)
    ax.set_title(title, color=_TEXT, fontsize=10, loc="left", pad=6)
    ax.tick_params(colors=_MUTED, labelsize=8, length=3)
    for side, spine in ax.spines.items():
        spine.set_visible(side in ("left", "bottom"))
        spine.set_color(_GRID)
    ax.grid(True, color=_GRID, linewidth=0.6, alpha=0.8)
    ax.set_axisbelow(True)


def _save(fig, path: Path) -> None:
    files.write_figure(path, fig, dpi=150, facecolor=fig.get_facecolor(), pil_kwargs={"compress_level": 3})


#: The perfect-shadows floor's line in the plots.
FLOOR_COLOUR = "#8d8d96"


def _metric_panels(views: list[TechniqueView], leak_hex: str, false_shadow_hex: str, floor: bool) -> tuple:
    """``(title, lines, worse, unit)`` per panel of :func:`plot_metrics`; a line is
    ``(key, label, colour, scale, style)`` on the flattened frames (:func:`_flatten`).
    Image metrics get the perfect-shadows floor's line where the sweep has it."""
    many = len(views) > 1

    def one(key, floored=False):
        lines = [(f"{v.name}_{key}", v.label if many or floor else "", v.colour, 1.0, v.style) for v in views]
        if floored and floor:
            lines.append((f"floor_{key}", "perfect-shadows floor", FLOOR_COLOUR, 1.0, ":"))
        return lines

    leaks = []
    for v in views:
        prefix = f"{v.name} " if many else ""
        leaks += [
            (f"{v.name}_leak_fraction", f"{prefix}leak (F lit, V shadowed)", leak_hex, 100.0, v.style),
            (f"{v.name}_false_shadow_fraction", f"{prefix}false shadow", false_shadow_hex, 100.0, v.style),
        ]
    return (
        ("visibility  mean |F − V|", one("visibility_mae"), "max", ""),
        ("leaks & false shadows  (% of pixels)", leaks, "max", "%"),
        ("FLIP  mean", one("flip_mean", True), "max", ""),
        ("ΔE2000  mean", one("delta_e2000_mean", True), "max", ""),
        ("PSNR  dB (linear; higher is better)", one("psnr_db", True), "min", ""),
        ("RMSE  (linear)", one("rmse", True), "max", ""),
    )


def plot_metrics(path: Path, frames: list[dict], views: list[TechniqueView]) -> None:
    """Small multiples: every quality metric against azimuth, a line per technique; the worst frame ringed."""
    import numpy as np
    from matplotlib.ticker import FuncFormatter

    az = np.array(
        [_num(f.get("azimuth_deg")) if _num(f.get("azimuth_deg")) is not None else np.nan for f in frames],
        dtype=float,
    )
    frames = _flatten(frames, views)

    def series(key, scale=1.0):
        return np.array([np.nan if _num(f.get(key)) is None else _num(f.get(key)) * scale for f in frames])

    floor = any(_num(f.get("floor_flip_mean")) is not None for f in frames)
    panels = _metric_panels(
        views, images.hex_colour(images.LEAK_RGB), images.hex_colour(images.FALSE_SHADOW_RGB), floor
    )
    fig = _figure(13.0, 5.4)
    axes = fig.subplots(2, 3, sharex=True)
    fig.subplots_adjust(left=0.045, right=0.99, top=0.94, bottom=0.1, hspace=0.2, wspace=0.16)
    ticks = [a for a in az if np.isfinite(a)]
    for ax, (title, lines, worse, unit) in zip(axes.flat, panels):
        _style_axes(ax, title)
        keys = [line[0] for line in lines]
        any_data = False
        for key, label, colour, scale, style in lines:
            y = series(key, scale)
            ok = np.isfinite(y) & np.isfinite(az)
            if not ok.any():
                continue
            any_data = True
            order = np.argsort(az[ok])
            ax.plot(
                az[ok][order],
                y[ok][order],
                color=colour,
                linewidth=1.6,
                marker="o",
                markersize=3.5,
                label=label or None,
                zorder=3,
                linestyle=style,
            )
            w = int(
                np.nanargmax(np.where(ok, y, -np.inf))
                if worse == "max"
                else np.nanargmin(np.where(ok, y, np.inf))
            )
            if np.nanmax(y[ok]) != np.nanmin(y[ok]):
                ax.plot(
                    [az[w]],
                    [y[w]],
                    marker="o",
                    markersize=10,
                    markerfacecolor="none",
                    markeredgecolor=_WORST,
                    markeredgewidth=1.4,
                    zorder=4,
                    clip_on=False,
                )
        psnr = [k for k in keys if k.endswith("_psnr_db")]
        if psnr:
            inf = np.array([f.get(psnr[0]) is None and psnr[0] in f for f in frames]) & np.isfinite(az)
            if inf.any():
                any_data = True
                ax.plot(
                    az[inf],
                    np.full(inf.sum(), 0.96),
                    linestyle="none",
                    marker="^",
                    color=_MUTED,
                    transform=ax.get_xaxis_transform(),
                    label="∞ (identical)",
                    zorder=3,
                )
        if not any_data:
            ax.text(
                0.5,
                0.5,
                "not measured",
                transform=ax.transAxes,
                ha="center",
                va="center",
                color=_MUTED,
                fontsize=9,
            )
            ax.set_yticks([])
        if len(lines) > 1 or psnr:
            handles, _ = ax.get_legend_handles_labels()
            if handles:
                leg = ax.legend(fontsize=8, frameon=False, loc="best", labelcolor=_TEXT)
                leg.set_zorder(5)
        if unit == "%":
            ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g} %"))
        if any_data:
            ax.margins(x=0.04, y=0.12)
            if worse == "max":
                ax.set_ylim(bottom=0)
    for ax in axes[-1]:
        ax.set_xlabel("light azimuth (degrees)", color=_MUTED, fontsize=8)
        if 0 < len(ticks) <= 13:
            ax.set_xticks(ticks)
            ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: fmt_deg(v)))
    _save(fig, path)


def plot_timings(path: Path, timings: dict, frames: list[dict], views: list[TechniqueView]) -> None:
    """Where the time goes: the run's stages, and each frame's truth and technique times."""
    import numpy as np
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    t = _timings(timings, len(frames), views)
    # the per-frame legend sits above its bars in rows of two, the title above the legend (four
    # labels in one row ran into the title); the left margin fits the longest stage label
    legend_cols = min(1 + len(views), 2)
    legend_rows = -(-(1 + len(views)) // legend_cols)
    longest = max((len(r["label"]) + 9 for r in t["rows"]), default=10)
    top_in, left_in = 0.36 + 0.2 * legend_rows, max(1.55, 0.075 * longest)
    height = max(2.8, 0.9 + 0.2 * legend_rows + 0.3 * max(len(t["rows"]), len(frames)))
    fig = _figure(13.0, height)
    ax1, ax2 = fig.subplots(1, 2, width_ratios=(1.25, 1))
    fig.subplots_adjust(
        left=left_in / 13.0, right=0.99, top=1 - top_in / height, bottom=0.42 / height, wspace=0.1
    )

    _style_axes(ax1, "where the time goes  (seconds)")
    labels = [r["label"] + (f" ({r['note']})" if r["note"] == "cached" else "") for r in t["rows"]]
    secs = np.array([r["seconds"] for r in t["rows"]], dtype=float)
    palette = {
        "truth renders": TRUTH_COLOUR,
        "truth set-up": TRUTH_COLOUR,
        **{f"{v.label} {what}": v.colour for v in views for what in ("renders", "set-up")},
    }
    colours = [palette.get(r["label"], "#8d8d96") for r in t["rows"]]
    y = np.arange(len(secs))
    if len(secs):
        ax1.barh(y, secs, color=colours, height=0.62, zorder=3)
        ax1.set_yticks(y, labels)
        ax1.invert_yaxis()
        top = secs.max() if secs.max() > 0 else 1.0
        for yi, r in zip(y, t["rows"]):
            ax1.text(
                r["seconds"] + top * 0.01,
                yi,
                f"{r['text']}  {r['share']}",
                va="center",
                color=_TEXT,
                fontsize=8,
            )
        ax1.set_xlim(0, top * 1.22)
        ax1.grid(False, axis="y")
    else:
        ax1.text(0.5, 0.5, "no timings", transform=ax1.transAxes, ha="center", color=_MUTED)
    ax1.tick_params(axis="y", colors=_TEXT)

    _style_axes(ax2, "")
    flat = _flatten(frames, views)
    series = [
        (np.array([_num(f.get("truth_s")) or np.nan for f in frames], dtype=float), TRUTH_COLOUR, "truth")
    ]
    series += [
        (np.array([_num(f.get(f"{v.name}_s")) or np.nan for f in flat], dtype=float), v.colour, v.label)
        for v in views
    ]
    ax2.set_title("per frame  (log scale)", color=_TEXT, fontsize=10, loc="right", pad=6 + 13 * legend_rows)
    y = np.arange(len(frames))
    if len(frames) and any(np.isfinite(v).any() for v, _, _ in series):
        h = 0.8 / len(series)
        for i, (v, colour, label) in enumerate(series):
            ax2.barh(
                y + (i - (len(series) - 1) / 2) * h,
                np.nan_to_num(v),
                height=h,
                color=colour,
                label=label,
                zorder=3,
            )
        ax2.set_yticks(y, [fmt_deg(f.get("azimuth_deg")) for f in frames])
        ax2.invert_yaxis()
        positive = np.concatenate([v[v > 0] for v, _, _ in series])
        if positive.size:
            ax2.set_xscale("log")
            ax2.set_xlim(positive.min() / 2, positive.max() * 2)
            # 1-2-5 ticks labelled in seconds; unlabelled minor ticks (their default
            # labels are scientific notation in the axis' default colour)
            ax2.xaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
            ax2.xaxis.set_major_formatter(FuncFormatter(lambda v, _: fmt_seconds(v)))
            ax2.xaxis.set_minor_formatter(NullFormatter())
        ax2.legend(
            fontsize=8,
            frameon=False,
            labelcolor=_TEXT,
            loc="lower left",
            bbox_to_anchor=(0.0, 1.0),
            ncol=legend_cols,
            borderaxespad=0.2,
            handlelength=1.2,
        )
        ax2.grid(False, axis="y")
    else:
        ax2.text(0.5, 0.5, "no frames", transform=ax2.transAxes, ha="center", color=_MUTED)
    ax2.tick_params(axis="y", colors=_TEXT)
    _save(fig, path)


# --------------------------------------------------------------------------
# Splits: a technique whose frames divide an error into parts (Technique.split_parts)
# --------------------------------------------------------------------------

#: The colours of a split's parts, from the bottom up; a negative part is drawn in :data:`_WORST`.
SPLIT_COLOURS = ("#6cc3ff", "#f2c14e", "#c7e36b", "#ff8fa3")


@dataclass(frozen=True)
class SplitView:
    """A technique's ``split`` of each frame as the report shows it: ``parts`` ``(key, label)`` from the
    bottom up (``metrics.json``'s ``techniques.NAME.split_parts``), its plot's path under the sweep."""

    view: TechniqueView
    parts: tuple[tuple[str, str], ...]
    plot: str


def _split_of(f: dict, name: str) -> dict | None:
    """``frames[i].techniques[name].split``, or ``None``."""
    per = f.get("techniques")
    m = per.get(name) if isinstance(per, dict) else None
    s = m.get("split") if isinstance(m, dict) else None
    return s if isinstance(s, dict) else None


def split_views(metrics: dict, views: list[TechniqueView]) -> list[SplitView]:
    """The techniques that declare ``split_parts`` and split at least one frame, in their order."""
    info = metrics.get("techniques") if isinstance(metrics.get("techniques"), dict) else {}
    frames = [f for f in (metrics.get("frames") or []) if isinstance(f, dict)]
    out = []
    for v in views:
        t = info.get(v.name) if isinstance(info.get(v.name), dict) else {}
        parts = tuple(
            (str(p["key"]), str(p.get("label") or p["key"]))
            for p in (t.get("split_parts") or [])
            if isinstance(p, dict) and p.get("key")
        )
        if parts and any(_split_of(f, v.name) is not None for f in frames):
            out.append(SplitView(v, parts, f"plots/{v.stem}_split.png"))
    return out


def _split_values(frames: list[dict], sv: SplitView):
    """``(azimuths, values)``: the frames' azimuths and each part's value per frame (NaN: missing)."""
    import numpy as np

    az = np.array(
        [_num(f.get("azimuth_deg")) if _num(f.get("azimuth_deg")) is not None else np.nan for f in frames],
        dtype=float,
    )
    vals = np.array(
        [
            [
                np.nan
                if _num((_split_of(f, sv.view.name) or {}).get(k)) is None
                else _num(_split_of(f, sv.view.name)[k])
                for k, _ in sv.parts
            ]
            for f in frames
        ],
        dtype=float,
    )
    return az, vals.reshape(len(frames), len(sv.parts))


def _split_context(frames: list[dict], sv: SplitView) -> dict:
    """The split's table: per frame its parts, their sum and each part's share of it; a negative part
    (the fit worse than the bake on that frame) flagged."""
    _, vals = _split_values(frames, sv)
    rows = []
    for f, row in zip(frames, vals):
        total = float(row.sum()) if all(map(math.isfinite, row)) else None
        rows.append(
            {
                "azimuth": fmt_deg(f.get("azimuth_deg")),
                "total": _fixed(4)(total) if total is not None else "—",
                "cells": [
                    {
                        "text": "—" if not math.isfinite(x) else f"{x:.4f}",
                        "share": f"{100 * x / total:.0f} %" if total and math.isfinite(x) else "",
                        "negative": bool(math.isfinite(x) and x < 0),
                    }
                    for x in row
                ],
            }
        )
    return {
        "name": sv.view.name,
        "label": sv.view.label,
        "plot": sv.plot,
        "parts": [lb for _, lb in sv.parts],
        "rows": rows,
        "negative": sum(any(c["negative"] for c in r["cells"]) for r in rows),
    }


def plot_split(path: Path, frames: list[dict], sv: SplitView) -> None:
    """A stacked bar per frame against azimuth: the split's parts from the bottom up, their sum the whole
    error; a negative part is drawn hatched down from the top of the others, in :data:`_WORST`."""
    import numpy as np
    from matplotlib.ticker import FuncFormatter

    az, vals = _split_values(frames, sv)
    fig = _figure(13.0, 3.4)
    ax = fig.subplots()
    fig.subplots_adjust(left=0.06, right=0.99, top=0.8, bottom=0.15)
    _style_axes(ax, f"{sv.view.label}: the split of the error per frame  (mean |F − V|)")
    ax.set_title(ax.get_title(loc="left"), color=_TEXT, fontsize=10, loc="left", pad=22)  # above the legend
    ok = np.isfinite(az)
    steps = np.diff(np.unique(az[ok]))
    width = 0.7 * (steps.min() if steps.size else 10.0)
    base = np.zeros(len(frames))
    for j, (_, label) in enumerate(sv.parts):
        v = np.nan_to_num(vals[:, j])
        pos = np.where(v > 0, v, 0.0)
        ax.bar(
            az[ok],
            pos[ok],
            width,
            bottom=base[ok],
            color=SPLIT_COLOURS[j % len(SPLIT_COLOURS)],
            label=label,
            zorder=3,
        )
        down = ok & (v < 0)
        if down.any():
            ax.bar(
                az[down],
                -v[down],
                width,
                bottom=(base + v)[down],
                color="none",
                edgecolor=_WORST,
                hatch="///",
                linewidth=1.0,
                label=f"{label} < 0",
                zorder=4,
            )
        base = base + pos
    if not ok.any():
        ax.text(0.5, 0.5, "no frames", transform=ax.transAxes, ha="center", color=_MUTED)
    ax.legend(
        fontsize=8,
        frameon=False,
        labelcolor=_TEXT,
        loc="lower left",
        bbox_to_anchor=(0.0, 1.01),
        ncol=len(sv.parts) + 1,
        borderaxespad=0.0,
    )
    ax.set_xlabel("light azimuth (degrees)", color=_MUTED, fontsize=8)
    if 0 < ok.sum() <= 25:
        ax.set_xticks(az[ok])
        ax.xaxis.set_major_formatter(FuncFormatter(lambda x, _: fmt_deg(x)))
    ax.set_ylim(bottom=min(0.0, float(np.nanmin(vals)) if np.isfinite(vals).any() else 0.0))
    ax.grid(False, axis="x")
    _save(fig, path)


# --------------------------------------------------------------------------
# The page
# --------------------------------------------------------------------------


def environment():
    import jinja2

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
    """The page for a :func:`build_context` result."""
    return environment().get_template("report.html.j2").render(**context)


def write_report(out: str | Path, metrics: dict, *, command: str) -> Path:
    """Write ``out/index.html`` and ``out/plots/*.png`` for a sweep's ``metrics``; return the index path.

    ``metrics`` is the content of ``out/metrics.json`` (docs/ARCHITECTURE.md); its file
    paths are relative to ``out``. ``command`` is the command line that
    reproduces the run. Every file is written atomically.
    """
    out = Path(out)
    frames = [f for f in (metrics.get("frames") or []) if isinstance(f, dict)]
    views = technique_views(metrics)
    plot_metrics(out / "plots" / "metrics.png", frames, views)
    plot_timings(out / "plots" / "timings.png", metrics.get("timings") or {}, frames, views)
    plots = {"metrics": "plots/metrics.png", "timings": "plots/timings.png"}
    for sv in split_views(metrics, views):
        plot_split(out / sv.plot, frames, sv)
    html = render_html(build_context(out, metrics, files.portable_command(command, out), plots))
    index = out / "index.html"
    with files.atomic_path(index) as tmp:
        tmp.write_text(html, encoding="utf-8")
    return index


# --------------------------------------------------------------------------
# The suite's overview (hzval.commands.suite)
# --------------------------------------------------------------------------


def _cell_of(value, fmt: Callable[[Any], str]) -> dict:
    return {"v": "" if value is None else f"{value:.6g}", "text": "—" if value is None else fmt(value)}


def _suite_row(r: dict, names: list[str]) -> dict:
    """A material's row and card, formatted."""
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
    for n in names:
        t = r["techniques"].get(n, {})
        cells += [
            _cell_of(t.get("visibility_mae"), _fixed(4)),
            _cell_of(t.get("flip_mean"), _fixed(4)),
            _cell_of(None if t.get("seconds") is None else 1000 * t["seconds"], _fixed(0)),
        ]
    kinds = [{"name": "truth", "label": "truth"}] + [
        {"name": n, "label": technique.get(n).label.split(" (")[0]} for n in names if n in r["techniques"]
    ]
    row.update(
        size=f"{r['cols']} × {r['rows']}",
        texels=r["cols"] * r["rows"],
        depth=f"{r['depth']:g}",
        boundary=r["boundary"],
        cells=cells,
        floor=_cell_of(r["floor"].get("flip_mean"), _fixed(4)),
        truth=_cell_of(None if r.get("truth_s") is None else 1000 * r["truth_s"], _fixed(0)),
        sweep=_cell_of(r.get("seconds"), _fixed(1)),
        peak=_cell_of(r["peak_rss_bytes"] / 2**30, _fixed(2)),
        lights=list(r.get("thumbs", {})),
        thumbs=r.get("thumbs", {}),
        kinds=kinds,
    )
    return row


def render_suite(result: dict) -> str:
    """The suite's ``index.html`` for :func:`hzval.commands.suite.write_overview`'s ``result``."""
    names = list(result["techniques"])
    s = result["suite"]
    context = {
        "count": s["materials"],
        "failed": s["failed"],
        "not_run": s.get("not_run", 0),
        "interrupted": s.get("interrupted", False),
        "engine": s["engine"],
        "workers": s["workers"],
        "seconds": fmt_seconds(s["seconds"]),
        "versions": s.get("versions") or {},
        "command": s["command"],
        "techniques": [{"name": n, **result["techniques"][n]} for n in names],
        "rows": [_suite_row(r, names) for r in result["materials"]],
        "gates": result.get("gates") if isinstance(result.get("gates"), dict) else None,
    }
    return environment().get_template("suite.html.j2").render(**context)
