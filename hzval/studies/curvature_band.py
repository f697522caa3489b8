"""Curvature and nothing else: each technique's |F - V| in a band of local light elevations.

It is taken on a fixed window of the texture, per texel, beside the flat patch's on the same texels
(docs/models.md).

Why a band. On a cap of radius ``R`` the base normal turns by ``r / R`` at geodesic distance ``r``
from the centre, so one world light meets the surface at a different local elevation on every pixel:
at ``R = 0.5`` texture widths the 0.8-wide cap spans 46 degrees from centre to rim. A mean of
``|F - V|`` over the whole cap then mixes curvature with the light's elevation (lower light, longer
shadows) and with the share of pixels that face away (``F = V = 0``). Here only the pixels whose base
normal ``n`` sees the light's centre ``L`` at the scene's elevation count:

    | asin(n . L) - elevation | <= BAND_DEG            (degrees, the same band on every R)

What else moves with R, and how it is held fixed:

- *the texture*: the caps' UVs keep one texture per world unit (``world_per_uv = 1``,
  hzval.commands.models), so depth and the relief in texels are the same;
- *the metric*: no map flattens a sphere; the geodesic polar UVs shrink tangential lengths by
  ``sin(r/R) / (r/R)``. Only texels within :data:`WINDOW` texture widths of the centre count: at
  the smallest radius (0.5) they are compressed by 2.2% at most (``1 - sin(0.36)/0.36``);
- *the cap's edges*: the window ends :data:`WINDOW` + the bake's search radius (0.125 texture widths
  at 16 of 128 texels) inside the cap's half width (0.4), so every occluder the bake searches for
  exists on the truth's mesh;
- *the camera's framing and texel density on screen*: pixels are binned by the texel their truth's
  hit reads (its base uv), each texel's pixels averaged, then the texels averaged: a mean over the
  surface, whatever the pixels per texel (:data:`RESOLUTION` gives every texel two or more pixels);
- *the texture's content*: the band is a strip through the centre, across the light, whose texels
  depend on R and the azimuth; each frame's flat-patch texel map, read on the same texels, is the
  reference (``excess``, the curvature's own cost), and :data:`AZIMUTHS` lights average the strips.

Noise: every statistic is a mean over the frames (lights) of a per-frame mean, its standard error the
frames' spread, ``std / sqrt(frames)``; a step between two radii uses the per-frame differences
(the same lights, so what the azimuths share cancels). :func:`trend` turns the rows into a statement.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from hzval.core import backend
from hzval.metrics.results import techniques_of
from hzval.pipeline import sweep
from hzval.studies import seam_share

__all__ = [
    "BAND_DEG",
    "WINDOW",
    "AZIMUTHS",
    "RESOLUTION",
    "band_scene",
    "measure",
    "paired",
    "trend",
    "texel_means",
    "in_band",
]

#: The band's half width, degrees of local light elevation about the scene's.
BAND_DEG = 3.0
#: The window's geodesic radius about the texture's centre, texture widths (module docstring).
WINDOW = 0.18
#: The band's lights: 16 azimuths, 22.5 degrees apart (each light's strip crosses the centre).
AZIMUTHS = tuple(22.5 * i for i in range(16))
#: The band's camera, pixels (two or more a texel at 128^2; a 256^2 map gets about one).
RESOLUTION = (256, 256)
#: A fall between neighbouring radii of fewer standard errors than this is noise (:func:`trend`).
NOISE_Z = 2.0


def band_scene(scene, resolution=RESOLUTION, azimuths=AZIMUTHS):
    """``scene`` (one case's) with the band's camera resolution and lights."""
    cam = dataclasses.replace(scene.camera, resolution=tuple(resolution))
    light = dataclasses.replace(scene.light, azimuths_deg=tuple(float(a) for a in azimuths))
    return dataclasses.replace(scene, camera=cam, light=light).validate()


def in_band(n: np.ndarray, L: np.ndarray, elevation_deg: float, half_deg: float = BAND_DEG) -> np.ndarray:
    """Return whether each base normal ``n`` sees ``L`` within ``half_deg`` of ``elevation_deg``.

    ``n`` is ``(..., 3)``, unit, world, and ``L`` the direction toward the light, unit; the elevation is above
    the normal's tangent plane.
    """
    local = np.degrees(np.arcsin(np.clip(n @ np.asarray(L, np.float64), -1.0, 1.0)))
    return np.abs(local - elevation_deg) <= half_deg


def texel_means(values: np.ndarray, texel: np.ndarray, keep: np.ndarray, size: int) -> np.ndarray:
    """Return per texel the mean of ``values`` over the kept pixels that read it.

    Texels are the flat indices ``texel``, ``0 <= texel < size``; NaN where no pixel does.
    """
    idx, v = texel[keep], np.asarray(values, np.float64)[keep]
    count = np.bincount(idx, minlength=size)
    total = np.bincount(idx, weights=v, minlength=size)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, total / np.maximum(count, 1), np.nan)


def _pixel_geometry(truth, window: float):
    """Return per pixel its texel, its base normal and whether it counts.

    The texel is the one its truth's first sample reads (flat index, row-major from ``y = 0``); the base
    normal is the mean of its samples', unit; a pixel counts when it is seen and in the window.
    """
    s = truth.samples("truth")
    spp, rows, cols = s.spp, s.rows, s.cols
    x, y = s.x[::spp].astype(np.float64), s.y[::spp].astype(np.float64)
    n = s.frames[:, 6:9].astype(np.float64).reshape(-1, spp, 3).mean(axis=1)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    col, row = (
        np.clip(np.floor(x), 0, cols - 1).astype(np.int64),
        np.clip(np.floor(y), 0, rows - 1).astype(np.int64),
    )
    r = np.hypot(x / cols - 0.5, y / rows - 0.5)  # texture widths from the centre (uv)
    keep = truth.seen.ravel() & (r <= window)
    return row * cols + col, n, keep, rows * cols


def measure(scene, case_dir, *, window: float = WINDOW, half_deg: float = BAND_DEG, extra=None) -> dict:
    """Render a case's ``scene`` once more, in memory, from the bake its sweep cached in ``case_dir``.

    ``scene`` is a case's (:func:`band_scene`). The result holds, per technique and frame, the texel maps of
    |F - V| at the camera's hits (``mae``) and at the truth's (``floor``) over the band's pixels, ``(frames,
    texels)`` float64 each, and how many texels each frame's band holds. ``extra(setup)``: more techniques to
    measure beside the sweep's, ``{name: (at the camera's hits, at the truth's)}``
    (studies/curved_horizon.py).
    """
    setup = sweep.set_up(scene, case_dir, sweep.Options())
    try:
        texel, n, keep, size = _pixel_geometry(setup.truth, window)
        near, seen = _near_seams(setup.truth)
        perfect = {t.name: t for t in setup.perfect}
        techs = {t.name: (t, perfect.get(t.name)) for t in setup.techniques}
        techs.update(extra(setup) if extra else {})
        out = {name: {"mae": [], "bias": [], "floor": [], "seam": []} for name in techs}
        texels, lit = [], []
        for az in scene.light.azimuths_deg:
            frame = setup.truth.render(az)
            V = frame.layers["visibility"].ravel()
            band = keep & in_band(n, scene.light.direction(az), scene.light.elevation_deg, half_deg)
            lit.append(texel_means(V, texel, band, size))
            texels.append(int(np.isfinite(lit[-1]).sum()))
            for name, (t, p) in techs.items():
                F = t.render(az).layers["factor"].ravel()
                out[name]["mae"].append(texel_means(np.abs(F - V), texel, band, size))
                out[name]["bias"].append(texel_means(F - V, texel, band, size))
                out[name]["seam"].append(seam_share.shares(np.abs(F - V), near, seen))
                Fp = p.render(az).layers["factor"].ravel() if p is not None else np.full_like(F, np.nan)
                out[name]["floor"].append(texel_means(np.abs(Fp - V), texel, band, size))
    finally:
        backend.hand_back_freed_memory()
    return {
        "techniques": {
            k: {m: (v if m == "seam" else np.stack(v)) for m, v in d.items()} for k, d in out.items()
        },
        "texels": texels,
        "lit": np.stack(lit),
        "seam_edges": int(setup.truth.model.seam_edges),
    }


def _near_seams(truth):
    """Return per pixel whether its first sample's base point is near a seam edge and whether it is seen.

    Near means within :data:`hzval.studies.seam_share.SEAM_TEXELS` of a seam edge.
    """
    m = truth.model
    spp = truth.spp
    d = seam_share.seam_distance_texels(m, truth.base_points()[::spp], m.world_per_uv / truth.cols)
    return np.nan_to_num(d, nan=np.inf) <= seam_share.SEAM_TEXELS, truth.seen.ravel()


def frame_means(maps: np.ndarray, on: np.ndarray) -> np.ndarray:
    """Per frame the mean of ``maps[f]`` over the texels ``on[f]`` (NaN where a frame has none)."""
    out = np.full(maps.shape[0], np.nan)
    for f in range(maps.shape[0]):
        if on[f].any():
            out[f] = float(np.mean(maps[f][on[f]]))
    return out


def summary(per_frame: np.ndarray) -> dict:
    """Return the mean over the frames, its standard error from their spread and the frames counted."""
    v = per_frame[np.isfinite(per_frame)]
    if len(v) == 0:
        return {"mean": None, "se": None, "frames": 0}
    se = float(np.std(v, ddof=1) / math.sqrt(len(v))) if len(v) > 1 else None
    return {"mean": float(np.mean(v)), "se": se, "frames": int(len(v))}


def paired(case: dict, flat: dict | None) -> dict:
    """Return one case's band row from :func:`measure`'s maps.

    It holds, per technique, the band's mean |F - V| (``mae``), its floor, the flat patch's on the same texels
    of each frame (``flat``) and the difference (``excess``), the signed ``F - V`` (``bias``, and the flat
    patch's ``flat_bias``: + where the technique leaks, so that a convex surface, whose truth is more lit,
    lowers its error), each ``{mean, se, frames}``, and ``per_frame`` (the frames' means: :func:`trend`'s
    paired steps); ``texels``: the band's texels, mean per frame.
    """
    scored: dict[str, dict] = {}  # each technique's entry, filled below
    row = {
        "texels": float(np.mean(case["texels"])) if case["texels"] else 0.0,
        "techniques": scored,
        "seam_edges": case.get("seam_edges", 0),
    }
    if "lit" in case:  # the truth's lit share in the band, and what curvature changes of it
        on = np.isfinite(case["lit"]) & (np.isfinite(flat["lit"]) if flat is not None else True)
        row["lit"] = summary(frame_means(case["lit"], on))
        if flat is not None:
            row["lit_excess"] = summary(frame_means(case["lit"], on) - frame_means(flat["lit"], on))
    for name, maps in techniques_of(case).items():
        on = np.isfinite(maps["mae"])
        other = None if flat is None else techniques_of(flat).get(name)
        if other is not None:
            on &= np.isfinite(other["mae"])
        mae = frame_means(maps["mae"], on)
        entry = {
            "mae": summary(mae),
            "floor": summary(frame_means(maps["floor"], on & np.isfinite(maps["floor"]))),
            "bias": summary(frame_means(maps["bias"], on)) if "bias" in maps else None,
            "per_frame": [None if not math.isfinite(v) else float(v) for v in mae],
        }
        if other is not None:
            ref = frame_means(other["mae"], on)
            entry["flat"], entry["excess"] = summary(ref), summary(mae - ref)
            if (
                "bias" in other
            ):  # the flat bake's own F - V on the same texels: leaks (+) or false shadows (-)
                entry["flat_bias"] = summary(frame_means(other["bias"], on))
            entry["per_frame_excess"] = [None if not math.isfinite(v) else float(v) for v in mae - ref]
        if maps.get("seam") and row["seam_edges"]:
            entry["seam"] = _seam_stat(maps["seam"])
        scored[name] = entry
    return row


def _seam_stat(per_frame: list[dict]) -> dict:
    """Return the frames' error share near seams (mean, standard error) and the pixel share there."""
    err = np.array([np.nan if f["error_share"] is None else f["error_share"] for f in per_frame])
    pix = [f["pixel_share"] for f in per_frame if f["pixel_share"] is not None]
    return {
        "within_texels": seam_share.SEAM_TEXELS,
        "error_share": summary(err),
        "pixel_share": float(np.mean(pix)) if pix else None,
    }


def trend(points: list[tuple[float, list]], noise_z: float = NOISE_Z) -> dict:
    """Whether a per-frame statistic rises as the curvature grows.

    ``points``: ``(curvature, per-frame values)``, the same frames (lights) in each, any order
    (sorted here by curvature, ascending: the flat patch, then R = 8 .. 0.5). Each step between
    neighbours is the mean of the per-frame differences with its standard error; ``z`` = change / se.
    ``verdict``: ``"does not rise"`` unless the whole change (first to last) is up by more than
    ``noise_z`` standard errors; then ``"rises monotonically"`` (every step up) or ``"rises within
    noise"`` (every fall smaller than ``noise_z`` standard errors), else ``"does not rise"``;
    ``falls`` lists the steps that go down, with their ``z``.
    """
    pts = sorted(points, key=lambda p: p[0])
    steps = [_step(a, b) for a, b in zip(pts, pts[1:])]
    overall = _step(pts[0], pts[-1]) if len(pts) > 1 else None
    falls = [s for s in steps if s["change"] is not None and s["change"] <= 0]
    if overall is None or any(s["change"] is None for s in steps):
        verdict = "not measured"
    elif (overall["z"] or 0.0) <= noise_z:
        verdict = "does not rise"
    elif not falls:
        verdict = "rises monotonically"
    elif all(s["z"] is not None and s["z"] > -noise_z for s in falls):
        verdict = "rises within noise"
    else:
        verdict = "does not rise"
    return {
        "verdict": verdict,
        "noise_z": noise_z,
        "steps": steps,
        "overall": overall,
        "falls": [{"from": s["from"], "to": s["to"], "z": s["z"]} for s in falls],
    }


def _step(a: tuple[float, list], b: tuple[float, list]) -> dict:
    """From curvature ``a[0]`` to ``b[0]``: the mean per-frame change, its standard error and z."""
    x = np.array([np.nan if v is None else v for v in a[1]], np.float64)
    y = np.array([np.nan if v is None else v for v in b[1]], np.float64)
    d = (y - x)[np.isfinite(y - x)]
    if len(d) == 0:
        return {"from": a[0], "to": b[0], "change": None, "se": None, "z": None}
    se = float(np.std(d, ddof=1) / math.sqrt(len(d))) if len(d) > 1 else None
    change = float(np.mean(d))
    z = change / se if se else (math.copysign(math.inf, change) if change else 0.0)
    return {"from": a[0], "to": b[0], "change": change, "se": se, "z": float(z)}
