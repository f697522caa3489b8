"""The report's plots (matplotlib, Agg, no pyplot state).

They are each technique's metrics and times against the light's azimuth, and the split of a technique's error
into parts (``Technique.split_parts``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hzval.io import codecs
from hzval.metrics.results import FrameRecord, SweepResult
from hzval.report import columns, ranking

__all__ = [
    "FLOOR_COLOUR",
    "plot_metrics",
    "plot_timings",
    "SPLIT_COLOURS",
    "SplitView",
    "split_views",
    "split_context",
    "plot_split",
    "plot_error_per_byte",
]


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


def _figure(width: float, height: float):
    """Return a figure on an Agg canvas.

    Margins are set by hand: constrained layout would double the time a plot takes.
    """
    # matplotlib: 0.6 s to import, paid only where a figure is drawn
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
    codecs.write_figure(path, fig, dpi=150, facecolor=fig.get_facecolor(), pil_kwargs={"compress_level": 3})


#: The perfect-shadows floor's line in the plots.
FLOOR_COLOUR = "#8d8d96"


def _metric_panels(views: list[columns.TechniqueView], floor: bool) -> tuple:
    """Return ``(title, lines, worse, unit)`` per panel of :func:`plot_metrics`.

    A line is ``(key, label, colour, scale, style)`` on the flattened frames (:func:`columns.flatten`). Image
    metrics get the perfect-shadows floor's line where the sweep has it. Leaks are each technique's solid
    line, false shadows its dashed one.
    """

    def one(key, floored=False):
        lines = [(f"{v.name}_{key}", v.label, v.colour, 1.0, v.style) for v in views]
        if floored and floor:
            lines.append((f"floor_{key}", "perfect-shadows floor", FLOOR_COLOUR, 1.0, ":"))
        return lines

    leaks = []
    for v in views:
        leaks += [
            (f"{v.name}_leak_fraction", v.label, v.colour, 100.0, "-"),
            (f"{v.name}_false_shadow_fraction", v.label, v.colour, 100.0, "--"),
        ]
    return (
        ("visibility  mean |F − V|", one("visibility_mae"), "max", ""),
        ("leaks (solid) & false shadows (dashed)  % of pixels", leaks, "max", "%"),
        ("FLIP  mean", one("flip_mean", True), "max", ""),
        ("ΔE2000  mean", one("delta_e2000_mean", True), "max", ""),
        ("PSNR  dB (linear; higher is better)", one("psnr_db", True), "min", ""),
        ("RMSE  (linear)", one("rmse", True), "max", ""),
    )


def _by_azimuth(frames: list[dict]) -> list[dict]:
    """Merge the flattened frames per azimuth, each number the mean over the azimuth's elevations.

    This is for a sweep over several elevations (:func:`plot_elevation` shows the elevations). A key whose
    every value is ``None`` (PSNR of identical images) stays ``None``.
    """
    groups: dict = {}
    for f in frames:
        groups.setdefault(columns.num(f.get("azimuth_deg")), []).append(f)
    out = []
    for az, group in groups.items():
        g = {"azimuth_deg": az}
        for key in {k for f in group for k in f}:
            vals = [columns.num(f.get(key)) for f in group]
            kept = [v for v in vals if v is not None]
            g[key] = float(np.mean(kept)) if kept else (None if any(key in f for f in group) else np.nan)
        out.append(g)
    return out


def plot_metrics(path: Path, frames: list[dict], views: list[columns.TechniqueView]) -> None:
    """Plot every quality metric against azimuth as small multiples, a line per technique.

    Over several elevations a technique's line is its mean over them. The worst frame is ringed; there is one
    legend, outside the panels.
    """
    # matplotlib: 0.6 s to import, paid only where a figure is drawn
    from matplotlib.ticker import FuncFormatter

    several = len({columns.num(f.get("elevation_deg")) for f in frames}) > 1
    frames = columns.flatten(frames, views)
    if several:
        frames = _by_azimuth(frames)
    az = np.array(
        [
            columns.num(f.get("azimuth_deg")) if columns.num(f.get("azimuth_deg")) is not None else np.nan
            for f in frames
        ],
        dtype=float,
    )

    def series(key, scale=1.0):
        return np.array(
            [np.nan if columns.num(f.get(key)) is None else columns.num(f.get(key)) * scale for f in frames]
        )

    floor = any(columns.num(f.get("floor_flip_mean")) is not None for f in frames)
    panels = _metric_panels(views, floor)
    fig = _figure(14.5, 5.4)
    axes = fig.subplots(2, 3, sharex=True)
    fig.subplots_adjust(left=0.04, right=0.85, top=0.94, bottom=0.1, hspace=0.2, wspace=0.16)
    ticks = [a for a in az if np.isfinite(a)]
    legend: dict = {}
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
            (handle,) = ax.plot(
                az[ok][order],
                y[ok][order],
                color=colour,
                linewidth=1.6,
                marker="o",
                markersize=3.5,
                zorder=3,
                linestyle=style,
            )
            if unit != "%":  # the leaks panel's dashes are its own: the legend shows each technique once
                legend.setdefault(label, handle)
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
                (handle,) = ax.plot(
                    az[inf],
                    np.full(inf.sum(), 0.96),
                    linestyle="none",
                    marker="^",
                    color=_MUTED,
                    transform=ax.get_xaxis_transform(),
                    zorder=3,
                )
                legend.setdefault("∞ (identical)", handle)
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
        if unit == "%":
            ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g} %"))
        if any_data:
            ax.margins(x=0.04, y=0.12)
            if worse == "max":
                ax.set_ylim(bottom=0)
    if legend:
        fig.legend(
            list(legend.values()),
            list(legend),
            loc="center right",
            fontsize=8,
            frameon=False,
            labelcolor=_TEXT,
        )
    for ax in axes[-1]:
        label = "light azimuth (degrees)" + ("; each point the mean over the elevations" if several else "")
        ax.set_xlabel(label, color=_MUTED, fontsize=8)
        if 0 < len(ticks) <= 13:
            ax.set_xticks(ticks)
            ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: columns.fmt_deg(v)))
    _save(fig, path)


#: The no-shadows baseline's line in the elevation plot.
NONE_COLOUR = "#f5f5f5"


def plot_elevation(path: Path, table: dict[str, list[dict]], views: list[columns.TechniqueView]) -> None:
    """Plot mean ``|F - V|`` and mean FLIP against the light's elevation, a line per technique.

    One more line is for no shadows at all. The data is :func:`hzval.report.ranking.by_elevation`'s ``table``;
    the legends are outside the axes.
    """
    fig = _figure(13.0, 4.2)
    axes = fig.subplots(1, 2)
    fig.subplots_adjust(left=0.05, right=0.8, top=0.9, bottom=0.14, wspace=0.2)
    lines = [(v.name, v.label, v.colour, v.style) for v in views]
    lines.append((ranking.NONE, "no shadows (F = 1)", NONE_COLOUR, "--"))
    for ax, (key, title) in zip(
        axes, (("visibility_mae", "visibility  mean |F − V|"), ("flip_mean", "FLIP  mean"))
    ):
        _style_axes(ax, title)
        for name, label, colour, style in lines:
            rows = [r for r in table.get(name, []) if r[key] is not None]
            if rows:
                ax.plot(
                    [r["elevation_deg"] for r in rows],
                    [r[key] for r in rows],
                    color=colour,
                    linestyle=style,
                    linewidth=2.2 if name == ranking.NONE else 1.6,
                    marker="o",
                    markersize=3.5,
                    label=label,
                    zorder=4 if name == ranking.NONE else 3,
                )
        ax.set_xlabel("light elevation (degrees)", color=_MUTED, fontsize=8)
        ax.set_ylim(bottom=0)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="center right", fontsize=8, frameon=False, labelcolor=_TEXT)
    _save(fig, path)


def plot_timings(path: Path, timings: dict, frames: list[dict], views: list[columns.TechniqueView]) -> None:
    """Where the time goes: the run's stages, and each frame's truth and technique times."""
    # matplotlib: 0.6 s to import, paid only where a figure is drawn
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    t = columns.timing_rows(timings, len(frames), views)
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
        "truth renders": columns.TRUTH_COLOUR,
        "truth set-up": columns.TRUTH_COLOUR,
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
    flat = columns.flatten(frames, views)
    series = [
        (
            np.array([columns.num(f.get("truth_s")) or np.nan for f in frames], dtype=float),
            columns.TRUTH_COLOUR,
            "truth",
        )
    ]
    series += [
        (
            np.array([columns.num(f.get(f"{v.name}_s")) or np.nan for f in flat], dtype=float),
            v.colour,
            v.label,
        )
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
        ax2.set_yticks(y, [columns.frame_label(f) for f in frames])
        ax2.invert_yaxis()
        positive = np.concatenate([v[v > 0] for v, _, _ in series])
        if positive.size:
            ax2.set_xscale("log")
            ax2.set_xlim(positive.min() / 2, positive.max() * 2)
            # 1-2-5 ticks labelled in seconds; unlabelled minor ticks (their default
            # labels are scientific notation in the axis' default colour)
            ax2.xaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
            ax2.xaxis.set_major_formatter(FuncFormatter(lambda v, _: columns.fmt_seconds(v)))
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


#: The colours of a split's parts, from the bottom up; a negative part is drawn in :data:`_WORST`.
SPLIT_COLOURS = ("#6cc3ff", "#f2c14e", "#c7e36b", "#ff8fa3")


@dataclass(frozen=True)
class SplitView:
    """A technique's ``split`` of each frame as the report shows it.

    It holds ``parts``, ``(key, label)`` from the bottom up (``metrics.json``'s
    ``techniques.NAME.split_parts``), and its plot's path under the sweep.
    """

    view: columns.TechniqueView
    parts: tuple[tuple[str, str], ...]
    plot: str


def _split_of(f: dict, name: str) -> dict | None:
    """``frames[i].techniques.NAME.split``, or ``None``."""
    m = FrameRecord(f).scores(name)
    s = m.get("split") if m is not None else None
    return s if isinstance(s, dict) else None


def split_views(metrics: dict, views: list[columns.TechniqueView]) -> list[SplitView]:
    """Return the techniques that declare ``split_parts`` and split at least one frame, in their order."""
    result = SweepResult.of(metrics)
    info, frames = result.techniques, result.frames
    out = []
    for v in views:
        t = info.get(v.name) or {}
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
    az = np.array(
        [
            columns.num(f.get("azimuth_deg")) if columns.num(f.get("azimuth_deg")) is not None else np.nan
            for f in frames
        ],
        dtype=float,
    )
    vals = np.array(
        [
            [
                np.nan
                if columns.num((_split_of(f, sv.view.name) or {}).get(k)) is None
                else columns.num(_split_of(f, sv.view.name)[k])
                for k, _ in sv.parts
            ]
            for f in frames
        ],
        dtype=float,
    )
    return az, vals.reshape(len(frames), len(sv.parts))


def split_context(frames: list[dict], sv: SplitView) -> dict:
    """Return the split's table: per frame its parts, their sum and each part's share of it.

    A negative part (the fit worse than the bake on that frame) is flagged.
    """
    _, vals = _split_values(frames, sv)
    rows = []
    for f, row in zip(frames, vals):
        total = float(row.sum()) if all(map(math.isfinite, row)) else None
        rows.append(
            {
                "azimuth": columns.fmt_deg(f.get("azimuth_deg")),
                "total": columns.fixed(4)(total) if total is not None else "—",
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
    """Plot a stacked bar per frame against azimuth: the split's parts from the bottom up.

    Their sum is the whole error; a negative part is drawn hatched down from the top of the others, in
    :data:`_WORST`.
    """
    # matplotlib: 0.6 s to import, paid only where a figure is drawn
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
        ax.xaxis.set_major_formatter(FuncFormatter(lambda x, _: columns.fmt_deg(x)))
    ax.set_ylim(bottom=min(0.0, float(np.nanmin(vals)) if np.isfinite(vals).any() else 0.0))
    ax.grid(False, axis="x")
    _save(fig, path)


def plot_error_per_byte(
    path: Path, table: dict[float, list[dict]], views: list[columns.TechniqueView], title: str | None = None
) -> None:
    """Plot error against bytes per texel, one panel per light elevation.

    The data is :func:`hzval.report.ranking.error_per_byte`'s ``table``. A shipped technique is filled, a
    fitted one hollow, no shadows at 0 bytes, and the Pareto front of least bytes and least error is a step
    line.
    """
    colours = {v.name: v.colour for v in views}
    n = max(1, len(table))
    width = 3.4 + 4.0 * n  # the legend's 3 inches beside the panels
    fig = _figure(width, 4.2)
    axes = fig.subplots(1, n, squeeze=False)[0]
    fig.subplots_adjust(left=0.8 / width, right=1 - 3.0 / width, top=0.88, bottom=0.14, wspace=0.25)
    seen = {}
    for ax, (elevation, points) in zip(axes, table.items()):
        _style_axes(ax, title or f"light elevation {elevation:g}°")
        for p in points:
            # a fit in its technique's colour, hollow: the pair reads as one technique's two bakes
            colour = colours.get(p.get("fit_of") or p["name"], colours.get(p["name"], NONE_COLOUR))
            h = ax.scatter(
                [p["bytes_per_texel"]],
                [p["error"]],
                s=46,
                marker="o" if not p["fitted"] else "D",
                facecolors="none" if p["fitted"] else colour,
                edgecolors=colour,
                linewidths=1.6,
                zorder=4,
            )
            seen.setdefault(p["label"], h)
        front = sorted((p["bytes_per_texel"], p["error"]) for p in points if p["pareto"])
        if front:
            ax.step(*zip(*front), where="post", color=_MUTED, linewidth=1.0, linestyle=":", zorder=2)
        ax.set_xlabel("bytes per texel (textures as stored, top level)", color=_MUTED, fontsize=8)
        ax.set_ylim(bottom=0)
        ax.set_xlim(left=-0.3)
    axes[0].set_ylabel("mean |F − V|, pixels facing the light", color=_MUTED, fontsize=8)
    fig.legend(
        list(seen.values()), list(seen), loc="center right", fontsize=8, frameon=False, labelcolor=_TEXT
    )
    _save(fig, path)
