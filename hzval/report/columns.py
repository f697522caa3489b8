"""The report's vocabulary: columns, technique views, frame panels, labels, colours and line styles.

Each metric's column has its label, format and which way is worse. A frame has image panels and raw files; the
labels are those of parameters, timings and versions; the colours and line styles are those every page and
plot gives the truth and each technique.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, Callable

from hzval.metrics.results import FrameRecord, SweepResult
from hzval.techniques import registry as technique

__all__ = [
    "TRUTH_COLOUR",
    "TECHNIQUE_COLOURS",
    "TECHNIQUE_STYLES",
    "ENGINE_COLOUR",
    "technique_colour",
    "num",
    "fmt_deg",
    "fmt_seconds",
    "fixed",
    "Metric",
    "TECHNIQUE_METRICS",
    "OPTIONAL_METRICS",
    "TRUTH_TIME",
    "TRUTH_METRICS",
    "FACING",
    "FLOOR_METRICS",
    "TechniqueView",
    "technique_views",
    "flatten",
    "lead_metrics",
    "technique_metrics",
    "PANELS",
    "TECHNIQUE_PANELS",
    "RAW_FILES",
    "TECHNIQUE_RAW_FILES",
    "PARAMETER_GROUPS",
    "timing_labels",
    "VERSION_LABELS",
    "value_text",
    "azimuth_text",
    "timing_rows",
]

#: The truth's colour, on the page and in the plots.
TRUTH_COLOUR = "#7fd1ae"
#: The techniques' colours, in the order ``metrics.json`` lists them (the
#: first is the lead technique's, the page's "lead" side beside the truth).
TECHNIQUE_COLOURS = (
    "#b9a3ff",
    "#f2c14e",
    "#6cc3ff",
    "#ff8fa3",
    "#c7e36b",
    "#e39bd3",
    "#7ee0e0",
    "#d8b08c",
    "#8fd694",
    "#ff6b6b",
    "#c0c0c0",
    "#4f9dff",
    "#f59e6b",
    "#a0d8ff",
    "#d4a5ff",
    "#e8e07a",
)
#: Line styles of the techniques in the plots, in the same order.
TECHNIQUE_STYLES = ("-", "--", ":", "-.", (0, (5, 1, 1, 1)))


def num(x) -> float | None:
    """Return a finite float, or ``None`` (missing, null, NaN, not a number)."""
    if isinstance(x, bool) or x is None:
        return None
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def frame_label(frame: dict) -> str:
    """Return a frame's short label, its azimuth (``+15°``).

    In a sweep over several elevations (an ``el`` name) it has its elevation too (``+15° (elevation 30°)``).
    """
    az = fmt_deg(frame.get("azimuth_deg"))
    name = frame.get("name")
    if isinstance(name, str) and name.startswith("el"):
        return f"{az} (elevation {fmt_deg(frame.get('elevation_deg')).lstrip('+')})"
    return az


def fmt_deg(x) -> str:
    """``-60`` -> ``−60°``, ``0`` -> ``0°``, ``7.5`` -> ``+7.5°``."""
    v = num(x)
    if v is None:
        return "—"
    if v == 0:
        return "0°"
    return f"{v:+g}°".replace("-", "\u2212")


def fmt_seconds(x) -> str:
    """Seconds with a unit that suits them: ``850 µs``, ``12.3 ms``, ``1.25 s``."""
    v = num(x)
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


def fixed(digits: int) -> Callable[[Any], str]:
    """Return a formatter of numbers to ``digits`` decimals (a dash for a missing one)."""
    return lambda v: "—" if num(v) is None else f"{num(v):.{digits}f}"


def _percent(v) -> str:
    v = num(v)
    return "—" if v is None else f"{100 * v:.2f} %"


def _psnr(v) -> str:
    v = num(v)
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
#: table's first columns (:func:`lead_metrics`).
TECHNIQUE_METRICS: tuple[Metric, ...] = (
    Metric(
        "visibility_mae",
        "|F−V|",
        "",
        "Visibility: mean |F − V| over pixels, the technique's factor F against "
        "ray-traced visibility V, both in [0, 1]",
        fixed(4),
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
        fixed(4),
        group="image",
        floor="floor_flip_mean",
    ),
    Metric(
        "delta_e2000_mean",
        "ΔE2000",
        "",
        "Mean CIEDE2000 colour difference on display (sRGB) values; about 1 is just noticeable",
        fixed(3),
        group="image",
        floor="floor_delta_e2000_mean",
    ),
    Metric(
        "rmse",
        "RMSE",
        "",
        "Root mean square error on linear values (the largest radiance the declared effects can produce = 1)",
        fixed(4),
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
        fixed(4),
        group="reflection",
    ),
    Metric(
        "perfect_parallax_mae",
        "|F−V| at hit",
        "",
        "At perfect parallax: mean |F − V| with the textures "
        "read at the truth's own hit point of each sample rather than where the camera ray meets the flat "
        "plane; the difference from |F−V| is the parallax error's share",
        fixed(4),
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
        fixed(4),
        group="floor",
        error=False,  # a bound, not a technique's error: never marked "worst"
    ),
    Metric(
        "floor_rmse",
        "floor RMSE",
        "",
        "Perfect-shadows floor: RMSE (linear) of the unshadowed shading times V against the truth",
        fixed(4),
        group="floor",
        error=False,
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


#: The colour of ``hzval score``'s engine, beside the registry's techniques.
ENGINE_COLOUR = "#ff7a45"


def technique_colour(name: str, place: int) -> str:
    """Return a technique's colour, the same on every page and plot whichever technique leads.

    The registry's techniques get theirs by their place in it (:func:`hzval.techniques.registry.names`),
    ``score``'s engine its own, any other by its place in the list shown.

    Parameters
    ----------
    name : str
        The technique's registry name, or ``engine``.
    place : int
        Its index among the techniques shown.

    Returns
    -------
    str
        A CSS hex colour.

    Examples
    --------
    >>> names = __import__("hzval.techniques.registry", fromlist=["names"]).names()
    >>> technique_colour(names[0], 3) == technique_colour(names[0], 0) == TECHNIQUE_COLOURS[0]
    True
    """
    known = technique.names()
    if name in known:
        return TECHNIQUE_COLOURS[known.index(name) % len(TECHNIQUE_COLOURS)]
    if name == "engine":
        return ENGINE_COLOUR
    return TECHNIQUE_COLOURS[place % len(TECHNIQUE_COLOURS)]


def technique_views(metrics: dict) -> list[TechniqueView]:
    """Return the techniques of a sweep's ``metrics`` (``techniques``), in their order; the first leads."""
    result = SweepResult.of(metrics)
    views = []
    frames = result.frames
    for i, (name, t) in enumerate(result.techniques.items()):
        parallax = any("perfect_parallax_mae" in (f.scores(name) or {}) for f in frames)
        views.append(
            TechniqueView(
                str(name),
                str(t.get("label") or name),
                str(t.get("file_stem") or name),
                technique_colour(str(name), i),
                TECHNIQUE_STYLES[i % len(TECHNIQUE_STYLES)],
                parallax,
            )
        )
    return views


def flatten(frames: list[dict], views: list[TechniqueView]) -> list[dict]:
    """Frames with every technique's metrics lifted to ``<name>_<key>`` and its seconds to ``<name>_s``."""
    out = []
    for f in frames:
        per = FrameRecord(f).techniques
        g = dict(f)
        if isinstance(f.get("floor"), dict):
            g.update({f"floor_{k}": val for k, val in f["floor"].items()})
        if isinstance(f.get("truth"), dict):
            g.update({f"truth_{k}": val for k, val in f["truth"].items()})
        for v in views:
            m = per.get(v.name)
            if m is not None:
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


def lead_metrics(v: TechniqueView, frames: list[dict]) -> tuple["Metric", ...]:
    """Return the summary table's columns of the lead technique: every score it has in some frame."""
    shown = []
    for m in TECHNIQUE_METRICS:
        key = f"{v.name}_{m.key}"
        if m.key in OPTIONAL_METRICS and not any(num(f.get(key)) is not None for f in frames):
            continue
        # the headline scores carry the technique's name, as every other technique's columns do
        label = f"{v.name} {m.label}" if m.key in ("visibility_mae", "flip_mean") else m.label
        shown.append(replace(m, key=key, label=label, group=f"{v.name} · {m.group}"))
    return tuple(shown)


def technique_metrics(v: TechniqueView) -> tuple["Metric", ...]:
    """Return the summary table's columns of a technique after the lead."""
    return (
        Metric(
            f"{v.name}_visibility_mae",
            f"{v.name} |F−V|",
            "",
            f"{v.label}: mean |F − V| over pixels against the same ray-traced visibility",
            fixed(4),
            group=v.name,
        ),
        Metric(
            f"{v.name}_flip_mean",
            f"{v.name} FLIP",
            "",
            f"{v.label}: mean FLIP error against the truth (display values)",
            fixed(4),
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
                    fixed(4),
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
#: A technique's images after the lead's (keys of ``frames[i].techniques.NAME.files``).
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
#: A technique's raw files (keys of ``frames[i].techniques.NAME.files``).
TECHNIQUE_RAW_FILES: tuple[tuple[str, str], ...] = (
    ("image", "image"),
    ("factor", "F"),
    ("factor_png", "F png"),
)
PARAMETER_GROUPS: tuple[tuple[str, tuple[tuple[str, str], ...]], ...] = (
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


def timing_labels(views: list[TechniqueView]) -> tuple[tuple[str, str], ...]:
    """Return the stages of a sweep's timings: the fixed ones, then each technique's set-up and renders."""
    fixed = _TIMING_LABELS[:5]
    own = tuple(
        pair
        for v in views
        for pair in ((f"{v.stem}_setup_s", f"{v.label} set-up"), (f"{v.stem}_s", f"{v.label} renders"))
    )
    return fixed + own + _TIMING_LABELS[5:]


VERSION_LABELS: tuple[tuple[str, str], ...] = (
    ("hzval", "hzval"),
    ("mitsuba", "Mitsuba"),
    ("drjit", "Dr.Jit"),
    ("llvm", "LLVM"),
    ("variant", "variant"),
    ("python", "Python"),
    ("machine", "machine"),
)


def value_text(key: str, value) -> str:
    """Return a parameter, version or material value as text."""
    if value is None:
        return "—"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if key == "azimuths_deg" and isinstance(value, (list, tuple)):
        return azimuth_text(value)
    if key in ("elevation_deg", "light_radius_deg"):
        return fmt_deg(value).lstrip("+")
    if key == "elevations_deg" and isinstance(value, (list, tuple)):
        return ", ".join(fmt_deg(v).lstrip("+") for v in value) or "none"
    if isinstance(value, dict):  # a setting per texture: "ao u8, bent-normal float"
        return ", ".join(f"{k} {value_text(k, v)}" for k, v in value.items()) or "none"
    if isinstance(value, (list, tuple)):
        return ", ".join(str(v) for v in value) or "none"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def azimuth_text(values) -> str:
    """Return the azimuths in words: first, last and step where evenly spaced (3 or more), else a list."""
    vals = [num(v) for v in values]
    if not vals or any(v is None for v in vals):
        return ", ".join(str(v) for v in values) or "none"
    n = len(vals)
    listed = ", ".join(fmt_deg(v) for v in vals)
    if n >= 3:
        steps = {round(b - a, 9) for a, b in zip(vals, vals[1:])}
        if len(steps) == 1 and next(iter(steps)) > 0:
            return f"{fmt_deg(vals[0])} … {fmt_deg(vals[-1])}, step {next(iter(steps)):g}° ({n} lights)"
    return f"{listed} ({n} light{'s' if n != 1 else ''})"


#: A technique's set-up shorter than this (seconds) gets no row of the report's timings: the techniques
#: that share another's textures and kernel set up in microseconds, and eight such rows said nothing.
SETUP_SHOWN_FROM = 1e-3


def timing_rows(t: dict, n_frames: int, views: list[TechniqueView]) -> dict:
    """Return the report's timing rows of a sweep's ``timings`` (``metrics.json``).

    Each row has its share of their sum. ``left_out``: the labels of the set-ups under
    :data:`SETUP_SHOWN_FROM` (``left_out_below``: that bound as the page writes it).
    """
    rows, known, left_out = [], set(), []
    per_frame = {"truth_s", "plain_s"} | {f"{v.stem}_s" for v in views}
    setups = {f"{v.stem}_setup_s" for v in views}
    for key, label in timing_labels(views):
        known.add(key)
        v = num(t.get(key))
        if v is None:
            continue
        if key in setups and v < SETUP_SHOWN_FROM:
            left_out.append(label)
            continue
        note = ""
        if key == "bake_s" and t.get("bake_cached"):
            note = "cached"
        elif key in per_frame and n_frames:
            note = f"{fmt_seconds(v / n_frames)} per frame"
        rows.append({"label": label, "seconds": v, "text": fmt_seconds(v), "note": note})
    for key, value in t.items():  # anything else the sweep timed
        # technique_frames_s: the renders' wall time, which the rows of plain_s and <stem>_s hold
        if key in known or key in ("total_s", "bake_cached", "technique_frames_s"):
            continue
        v = num(value)
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
    total = num(t.get("total_s"))
    for r in rows:
        r["share"] = f"{100 * r['seconds'] / stages:.0f} %" if stages > 0 else ""
    return {
        "rows": rows,
        "total_text": fmt_seconds(total if total is not None else stages),
        "total_is_sum": total is None,
        "stages": stages,
        "left_out": left_out,
        "left_out_below": fmt_seconds(SETUP_SHOWN_FROM),
    }
