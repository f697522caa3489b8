"""The figures of the commands past the sweep (matplotlib, Agg, no pyplot state).

They are lines against one axis in a grid of panels (``views``, ``models``), what accuracy costs
(``tradeoff``) and the tangent bugs' signatures (``models``). The sweep report's own are
:mod:`hzval.report.plots`'.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hzval.io import codecs

__all__ = ["Line", "Panel", "plot_panels", "plot_tradeoff", "plot_signed_maps"]

#: The axis label of signed curvature, as the models' panels write it.
CURVATURE = "signed curvature 1/R (texture widths⁻¹; + convex)"


@dataclass
class Line:
    """One line of a panel: its legend's label and its points ``(x, y)``.

    ``dashed`` draws it thin and dashed without markers (a floor); ``errors`` draws each point's ``± error``
    instead.
    """

    label: str
    points: Sequence[tuple[float, float]]
    dashed: bool = False
    errors: Sequence[float] | None = None


@dataclass
class Panel:
    """A panel of lines: its title, axis labels and lines.

    ``footprint`` puts x on a log scale ticked 1, 2, 5 (a footprint spans under a decade); ``zero`` draws the
    line ``y = 0``.
    """

    title: str
    xlabel: str
    ylabel: str
    lines: list[Line] = field(default_factory=list)
    footprint: bool = False
    zero: bool = False


def _draw(ax: Any, panel: Panel) -> None:
    # matplotlib: 0.6 s to import, paid only where a figure is drawn
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    for line in panel.lines:
        x, y = zip(*line.points)
        if line.errors is not None:
            ax.errorbar(x, y, yerr=line.errors, marker="o", capsize=3, label=line.label)
        elif line.dashed:
            ax.plot(x, y, linestyle="--", alpha=0.6, label=line.label)
        else:
            ax.plot(x, y, marker="o", label=line.label)
    if panel.zero:
        ax.axhline(0.0, color="k", lw=0.8)
    ax.set(title=panel.title, xlabel=panel.xlabel, ylabel=panel.ylabel)
    if panel.footprint:
        ax.set(xscale="log")
        # a footprint axis spans under a decade: its minor ticks' labels ran into each other
        ax.xaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        ax.xaxis.set_minor_formatter(NullFormatter())
    ax.grid(alpha=0.3)
    # outside: it never covers a line
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)


def plot_panels(path: Path, grid: Sequence[Sequence[Panel]], size: tuple[float, float]) -> None:
    """Draw ``grid`` (rows of panels) into a PNG at ``path``, ``size`` inches at 110 dpi."""
    # matplotlib: 0.6 s to import, paid only where a figure is drawn
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, dpi=110)
    axes = fig.subplots(max(1, len(grid)), max([1, *(len(row) for row in grid)]), squeeze=False)
    for i, row in enumerate(grid):
        for j, panel in enumerate(row):
            _draw(axes[i][j], panel)
    fig.tight_layout()
    codecs.write_figure(path, fig)


def plot_tradeoff(path: Path, points: Sequence[Any], kinds: Sequence[str]) -> None:
    """Time against visibility error, one panel per kind; marker area ~ storage; Pareto front ringed.

    ``points``: each with ``kind``, ``label``, ``time_s``, ``error``, ``storage_bytes``, ``pareto``
    and ``visibility_mae_facing`` (:class:`hzval.commands.tradeoff.Point`).
    """
    # matplotlib: 0.6 s to import, paid only where a figure is drawn
    from matplotlib.figure import Figure
    from matplotlib.ticker import EngFormatter, LogLocator, MaxNLocator, NullFormatter

    kinds = [k for k in kinds if any(p.kind == k for p in points)]
    fig = Figure(figsize=(4.6 * len(kinds), 4.2))
    axes = fig.subplots(1, len(kinds), squeeze=False)
    labels = {"bake": "bake time (s)", "technique": "frame time (s)", "truth": "truth frame time (s)"}
    smax = max(p.storage_bytes for p in points) or 1
    for ax, kind in zip(axes[0], kinds):
        pts = [p for p in points if p.kind == kind]
        for p in pts:
            area = 30 + 270 * p.storage_bytes / smax
            colour = "#d62728" if p.pareto else "#1f77b4"
            ax.scatter(
                p.time_s, p.error, s=area, alpha=0.75, color=colour, edgecolors="black", linewidths=0.5
            )
            ax.annotate(p.label, (p.time_s, p.error), fontsize=7, xytext=(4, 4), textcoords="offset points")
        front = sorted((p for p in pts if p.pareto), key=lambda p: p.time_s)
        if len(front) > 1:
            ax.plot([p.time_s for p in front], [p.error for p in front], color="#d62728", lw=1)
        times = [p.time_s for p in pts if p.time_s > 0]
        if times and max(times) > 10 * min(times):
            # decades only, in engineering units: finer log ticks crowd the axis
            ax.set_xscale("log")
            ax.xaxis.set_major_locator(LogLocator(numticks=6))
            ax.xaxis.set_minor_formatter(NullFormatter())
        else:
            ax.xaxis.set_major_locator(MaxNLocator(4))
        ax.xaxis.set_major_formatter(EngFormatter(unit="s", places=None, sep=" "))
        ax.set_xlabel(labels[kind])
        facing = all(p.visibility_mae_facing is not None for p in pts)
        ax.set_ylabel("mean |F - V|" + (" (pixels facing the light)" if facing else " (whole image)"))
        ax.set_title(kind)
        ax.grid(True, alpha=0.3)
    fig.suptitle(
        "what accuracy costs: red = Pareto front of its kind; marker area ~ texture memory", fontsize=10
    )
    fig.tight_layout()
    codecs.write_figure(path, fig, dpi=110)


def plot_signed_maps(
    path: Path,
    maps: Sequence[Sequence[Any]],
    rows: Sequence[str],
    columns: Sequence[str],
    *,
    notes,
    label: str,
) -> None:
    """Draw a grid of signed maps in [-1, 1] (blue positive, red negative, NaN grey) with one colour bar.

    Parameters
    ----------
    path : pathlib.Path
        The PNG.
    maps : sequence of sequences of numpy.ndarray
        ``maps[i][j]``: row ``i``'s map in column ``j``.
    rows, columns : sequence of str
        The rows' labels (left) and the columns' titles (top).
    notes : sequence of sequences of str or None
        A note at each map's lower left, or ``None``.
    label : str
        The colour bar's label.
    """
    # matplotlib: 0.6 s to import, paid only where a figure is drawn
    import matplotlib as mpl
    from matplotlib.figure import Figure

    cmap = mpl.colormaps["RdBu"].with_extremes(bad="0.8")
    fig = Figure(figsize=(2.4 * len(columns) + 1.6, 2.2 * len(rows)), dpi=100)
    axes = fig.subplots(len(rows), len(columns), squeeze=False)
    for j, title in enumerate(columns):
        axes[0, j].set_title(title, fontsize=9)
        for i, row in enumerate(rows):
            ax = axes[i, j]
            im = ax.imshow(maps[i][j], cmap=cmap, vmin=-1, vmax=1, interpolation="nearest")
            if notes[i][j] is not None:
                ax.text(0.02, 0.02, notes[i][j], transform=ax.transAxes, fontsize=7)
            ax.set_xticks([]), ax.set_yticks([])
            if j == 0:
                ax.set_ylabel(row, fontsize=9)
    fig.colorbar(im, ax=axes, shrink=0.4, label=label)
    codecs.write_figure(path, fig)
