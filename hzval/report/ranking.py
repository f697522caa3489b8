"""The answer to "is X worth shipping instead of Y?": every technique of a sweep ranked, and its error
against light elevation beside no shadows at all.

A sweep's frames are ``(elevation, azimuth)`` pairs (:func:`hzval.pipeline.sweep.lights`). Per
technique and elevation, :func:`by_elevation` takes the mean over that elevation's azimuths of the
frame's mean ``|F - V|`` (over the pixels that face the light where measured,
:mod:`hzval.metrics.facing`) and mean FLIP; the frame's ``no_shadows`` record is the same for
``F = 1`` (the unshadowed shading). :func:`ranking` ranks the techniques by ``|F - V|`` over the
whole sweep (FLIP breaks ties) and marks the elevations at which a technique's ``|F - V|`` is
above no shadows': there it does harm. Pure data, no markup: pages and the terminal format it.
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np

from hzval.report import columns

__all__ = ["NONE", "by_elevation", "ranking", "worse_than_none", "floor_note", "visibility_of"]

#: The baseline's name in :func:`by_elevation`: no shadows at all, ``F = 1``.
NONE = "no shadows"


def visibility_of(record: dict) -> float | None:
    """A frame record's ``|F - V|``: over the pixels facing the light where measured (the report's,
    the ranking's and the suite's), else over the whole image."""
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
    for f in metrics.get("frames") or []:
        if not isinstance(f, dict) or columns.num(f.get("elevation_deg")) is None:
            continue
        e = float(f["elevation_deg"])
        records = dict(f.get("techniques") or {})
        if isinstance(f.get("no_shadows"), dict):
            records[NONE] = f["no_shadows"]
        for name, r in records.items():
            if isinstance(r, dict):
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
    """The elevations (degrees) at which ``name``'s mean ``|F - V|`` is above no shadows' (of
    :func:`by_elevation`'s ``table``)."""
    none = {r["elevation_deg"]: r["visibility_mae"] for r in table.get(NONE, [])}
    return [
        r["elevation_deg"]
        for r in table.get(name, [])
        if r["visibility_mae"] is not None
        and none.get(r["elevation_deg"]) is not None
        and r["visibility_mae"] > none[r["elevation_deg"]]
    ]


def ranking(metrics: dict) -> list[dict]:
    """The sweep's techniques ranked, best first, with no shadows among them as the baseline.

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
        ``ms_per_frame`` (its mean render time), ``worse_at`` (:func:`worse_than_none`) and
        ``baseline`` (true for :data:`NONE`). Ranked by ``visibility_mae``, then ``flip_mean``;
        unmeasured last.
    """
    table = by_elevation(metrics)
    info = metrics.get("techniques") if isinstance(metrics.get("techniques"), dict) else {}
    frames = [f for f in metrics.get("frames") or [] if isinstance(f, dict)]
    rows = []
    for name in [*info, NONE]:
        records = [
            (f.get("no_shadows") if name == NONE else (f.get("techniques") or {}).get(name)) for f in frames
        ]
        records = [r for r in records if isinstance(r, dict)]
        if not records:
            continue
        t = info.get(name) if isinstance(info.get(name), dict) else {}
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
                "baseline": name == NONE,
            }
        )

    def key(r):
        inf = float("inf")
        v, f = r["visibility_mae"], r["flip_mean"]
        return (v is None, inf if v is None else v, inf if f is None else f)

    return sorted(rows, key=key)


def floor_note(metrics: dict) -> str | None:
    """One line where the image scores cannot rank the shadows: the perfect-shadows floor's mean FLIP
    (exact shadows on the techniques' shading) at or above a technique's, so that FLIP there measures
    the shading, not the shadows; ``None`` where every technique's FLIP is above the floor's."""
    frames = [f for f in metrics.get("frames") or [] if isinstance(f, dict)]
    floor = _mean([columns.num((f.get("floor") or {}).get("flip_mean")) for f in frames])
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
