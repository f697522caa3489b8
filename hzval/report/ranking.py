"""Every technique of a sweep ranked, and its error against light elevation beside no shadows at all.

This is the answer to "is X worth shipping instead of Y?".

A sweep's frames are ``(elevation, azimuth)`` pairs (:func:`hzval.pipeline.renders.lights`). Per
technique and elevation, :func:`by_elevation` takes the mean over that elevation's azimuths of the
frame's mean ``|F - V|`` (over the pixels that face the light where measured,
:mod:`hzval.metrics.facing`) and mean FLIP; the frame's ``no_shadows`` record is the same for
``F = 1`` (the unshadowed shading). :func:`ranking` ranks the techniques by ``|F - V|`` over the
whole sweep (FLIP breaks ties) and marks the elevations at which a technique's ``|F - V|`` is
above no shadows': there it does harm. Where a sweep also ran a technique's fit (``NAME-fit``,
``metrics.json``'s ``techniques.FIT.fit_of``), :func:`floors` gives per elevation its shipped score,
its floor (the fitted textures' score), no shadows', and the split of the shipped error into what
the bake loses and what the representation cannot hold; a floor above no shadows means the formula
itself does harm there, whatever the bake. Pure data, no markup: pages and the terminal format it.
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np

from hzval.metrics.results import Scores, SweepResult
from hzval.report import columns

__all__ = [
    "NONE",
    "by_elevation",
    "ranking",
    "worse_than_none",
    "floor_note",
    "visibility_of",
    "fits",
    "floors",
    "formula_harms",
    "pareto",
    "error_per_byte",
]

#: The baseline's name in :func:`by_elevation`: no shadows at all, ``F = 1``.
NONE = "no shadows"
#: How far above no shadows' mean ``|F - V|`` a floor must be for the formula to count as doing harm
#: (:func:`floors`): a thousandth, the terminal's last digit but one, so that a floor of 0.00002 against
#: 0 at a high sun is not called harm.
HARM_MARGIN = 1e-3


def visibility_of(record: dict) -> float | None:
    """Return a frame record's ``|F - V|``, over the pixels facing the light where measured.

    Where the facing pixels were not measured it is over the whole image. The report, the ranking and the
    suite all show this figure.
    """
    return columns.num(record.get("visibility_mae_facing", record.get("visibility_mae")))


def by_elevation(metrics: dict) -> dict[str, list[dict]]:
    """Each technique's (and :data:`NONE`'s) mean scores per light elevation.

    Parameters
    ----------
    metrics : dict
        A sweep's ``metrics.json``.

    Returns
    -------
    dict
        ``{name: [{"elevation_deg", "visibility_mae", "flip_mean", "frames"}, ...]}`` in increasing
        elevation; a mean is ``None`` where no frame of that elevation measured it.
    """
    rows: dict[str, dict[float, dict[str, list]]] = defaultdict(
        lambda: defaultdict(lambda: defaultdict(list))
    )
    for f in SweepResult.of(metrics).frames:
        if columns.num(f.get("elevation_deg")) is None:
            continue
        e = float(f["elevation_deg"])
        records: dict[str, Scores] = dict(f.techniques)
        if f.no_shadows is not None:
            records[NONE] = f.no_shadows
        for name, r in records.items():
            rows[name][e]["visibility_mae"].append(visibility_of(r))
            rows[name][e]["flip_mean"].append(columns.num(r.get("flip_mean")))
    out = {}
    for name, per in rows.items():
        out[name] = [
            {
                "elevation_deg": e,
                "visibility_mae": _mean(v["visibility_mae"]),
                "flip_mean": _mean(v["flip_mean"]),
                "frames": len(v["visibility_mae"]),
            }
            for e, v in sorted(per.items())
        ]
    return out


def _mean(values: list) -> float | None:
    kept = [v for v in values if v is not None]
    return float(np.mean(kept)) if kept else None


def worse_than_none(table: dict[str, list[dict]], name: str) -> list[float]:
    """Return the elevations (degrees) at which ``name``'s mean ``|F - V|`` is above no shadows'.

    Both means are those of :func:`by_elevation`'s ``table``.
    """
    none = {r["elevation_deg"]: r["visibility_mae"] for r in table.get(NONE, [])}
    return [
        r["elevation_deg"]
        for r in table.get(name, [])
        if r["visibility_mae"] is not None
        and none.get(r["elevation_deg"]) is not None
        and r["visibility_mae"] > none[r["elevation_deg"]]
    ]


def fits(metrics: dict) -> dict[str, str]:
    """``{shipped technique: its fit}`` for the fits a sweep ran beside their technique."""
    info = SweepResult.of(metrics).techniques
    return {t.fit_of: name for name, t in info.items() if t.fit_of in info and t.fit_of != name}


def floors(metrics: dict) -> dict[str, list[dict]]:
    """Each fitted technique's floor per light elevation.

    Parameters
    ----------
    metrics : dict
        A sweep's ``metrics.json``.

    Returns
    -------
    dict
        ``{shipped technique: [row, ...]}`` in increasing elevation, a row ``elevation_deg``, ``fit``
        (its fit's name), ``shipped``, ``floor`` and ``none`` (mean ``|F - V|``, :func:`visibility_of`),
        ``bake_loss`` (shipped minus floor: what a better bake could win back), ``representation``
        (the floor: what the formula cannot do even with the best textures) and ``harms`` (the floor
        above no shadows by more than :data:`HARM_MARGIN`: the formula itself does harm there); a value
        is ``None`` where unmeasured. A negative ``bake_loss`` is a fit that does worse than the bake
        at that elevation, having traded it for its training lights.
    """
    table = by_elevation(metrics)
    none = {r["elevation_deg"]: r["visibility_mae"] for r in table.get(NONE, [])}
    out = {}
    for shipped, fit in fits(metrics).items():
        floor = {r["elevation_deg"]: r["visibility_mae"] for r in table.get(fit, [])}
        rows = []
        for r in table.get(shipped, []):
            e, s = r["elevation_deg"], r["visibility_mae"]
            f, n = floor.get(e), none.get(e)
            rows.append(
                {
                    "elevation_deg": e,
                    "fit": fit,
                    "shipped": s,
                    "floor": f,
                    "none": n,
                    "bake_loss": None if s is None or f is None else s - f,
                    "representation": f,
                    "harms": f is not None and n is not None and f > n + HARM_MARGIN,
                }
            )
        out[shipped] = rows
    return out


def formula_harms(metrics: dict) -> dict[str, list[float]]:
    """``{shipped technique: elevations}`` where even its fitted floor is worse than no shadows."""
    out = {n: [r["elevation_deg"] for r in rows if r["harms"]] for n, rows in floors(metrics).items()}
    return {n: at for n, at in out.items() if at}


def ranking(metrics: dict) -> list[dict]:
    """Return the sweep's techniques ranked, best first, with no shadows among them as the baseline.

    Parameters
    ----------
    metrics : dict
        A sweep's ``metrics.json``.

    Returns
    -------
    list of dict
        ``name``, ``label``, ``visibility_mae`` and ``flip_mean`` (means over every frame),
        ``at_hits`` (on a model or a view: ``|F - V|`` read at the truth's own hits, no parallax;
        ``None`` where not measured),
        ``bytes_per_texel`` (its textures as stored, the normal map aside; ``None`` for the baseline),
        ``ms_per_frame`` (its mean render time), ``worse_at`` (:func:`worse_than_none`),
        ``floor`` and ``bake_loss`` (its fit's mean ``|F - V|`` and the shipped minus that, where the
        sweep ran its fit; else ``None``), ``harms_at`` (the elevations where even that floor is worse
        than no shadows) and ``baseline`` (true for :data:`NONE`). Ranked by ``visibility_mae``, then
        ``flip_mean``; unmeasured last.
    """
    table = by_elevation(metrics)
    result = SweepResult.of(metrics)
    info = result.techniques
    fitted, harms = fits(metrics), formula_harms(metrics)
    rows = []
    for name in [*info, NONE]:
        found = [f.no_shadows if name == NONE else f.scores(name) for f in result.frames]
        records = [r for r in found if r is not None]
        if not records:
            continue
        t = info.get(name) or {}
        seconds = _mean([columns.num(r.get("seconds")) for r in records])
        rows.append(
            {
                "name": name,
                "label": NONE if name == NONE else str(t.get("label") or name),
                "visibility_mae": _mean([visibility_of(r) for r in records]),
                "at_hits": _mean([columns.num(r.get("perfect_parallax_mae")) for r in records]),
                "flip_mean": _mean([columns.num(r.get("flip_mean")) for r in records]),
                "bytes_per_texel": None if name == NONE else columns.num(t.get("texture_bytes_per_texel")),
                "ms_per_frame": None if seconds is None else 1000.0 * seconds,
                "worse_at": [] if name == NONE else worse_than_none(table, name),
                "floor": None,
                "bake_loss": None,
                "harms_at": harms.get(name, []),
                "baseline": name == NONE,
            }
        )
    means = {r["name"]: r["visibility_mae"] for r in rows}
    for r in rows:
        floor = means.get(fitted.get(r["name"]))
        if floor is not None and r["visibility_mae"] is not None:
            r["floor"], r["bake_loss"] = floor, r["visibility_mae"] - floor

    def key(r):
        inf = float("inf")
        v, f = r["visibility_mae"], r["flip_mean"]
        return (v is None, inf if v is None else v, inf if f is None else f)

    return sorted(rows, key=key)


def floor_note(metrics: dict) -> str | None:
    """Return one line where the image scores cannot rank the shadows.

    That is where the perfect-shadows floor's mean FLIP (exact shadows on the techniques' shading) is at or
    above a technique's, so that FLIP there measures the shading, not the shadows; ``None`` where every
    technique's FLIP is above the floor's.
    """
    floor = _mean([columns.num((f.floor or {}).get("flip_mean")) for f in SweepResult.of(metrics).frames])
    if floor is None:
        return None
    below = [
        (r["label"], r["flip_mean"])
        for r in ranking(metrics)
        if not r["baseline"] and r["flip_mean"] is not None and r["flip_mean"] <= floor
    ]
    if not below:
        return None
    listed = ", ".join(f"{label} {flip:.4f}" for label, flip in below)
    return (
        f"image scores cannot rank the shadows here: the perfect-shadows floor's FLIP ({floor:.4f}) is at "
        f"or above {listed}; the shading's own difference from the truth's dominates, so the table ranks "
        "by |F - V|"
    )


def pareto(points: list[tuple[float, float]]) -> list[bool]:
    """Which of ``(cost, error)`` points no other point is at least as good as in both and better in one.

    Examples
    --------
    >>> pareto([(0.0, 0.2), (1.0, 0.1), (1.0, 0.15), (4.0, 0.1)])
    [True, True, False, False]
    """
    return [
        not any(q != p and q[0] <= p[0] and q[1] <= p[1] and (q[0] < p[0] or q[1] < p[1]) for q in points)
        for p in points
    ]


def error_per_byte(metrics: dict) -> dict[float, list[dict]]:
    """Each technique's error against the bytes per texel its textures take, per light elevation.

    Parameters
    ----------
    metrics : dict
        A sweep's ``metrics.json``.

    Returns
    -------
    dict
        ``{elevation: [point, ...]}``, a point ``name``, ``label``, ``bytes_per_texel`` (its textures as
        stored, top level, the normal map aside; no shadows 0), ``error`` (mean ``|F - V|`` at that
        elevation, :func:`visibility_of`), ``fitted`` (a ``NAME-fit``), ``fit_of`` (the technique it
        fits, or ``None``) and ``pareto`` (on the front of
        least bytes and least error, :func:`pareto`).
    """
    info = SweepResult.of(metrics).techniques
    out: dict[float, list[dict]] = defaultdict(list)
    for name, rows in by_elevation(metrics).items():
        t = info.get(name) or {}
        b = 0.0 if name == NONE else columns.num(t.get("texture_bytes_per_texel"))
        for r in rows:
            if b is not None and r["visibility_mae"] is not None:
                out[r["elevation_deg"]].append(
                    {
                        "name": name,
                        "label": "no shadows (F = 1)" if name == NONE else str(t.get("label") or name),
                        "bytes_per_texel": float(b),
                        "error": r["visibility_mae"],
                        "fitted": bool(t.get("fit_of")),
                        "fit_of": t.get("fit_of"),
                    }
                )
    for points in out.values():
        for p, front in zip(points, pareto([(p["bytes_per_texel"], p["error"]) for p in points])):
            p["pareto"] = front
    return dict(sorted(out.items()))
