"""``hzval views``: the light sweep seen from a set of views, and where each technique breaks.

Each view (:data:`VIEWS`) is swept with each lookup (:data:`LOOKUPS`: plain
bilinear reads, trilinear mip-maps, parallax occlusion mapping, both) into
``DIR/<view>/<lookup>/``, a normal sweep report; ``DIR/views.json`` collects
their sweep means and ``DIR/index.html`` plots each technique's visibility
error against the view's elevation and against the texels a pixel covers,
with and without mips and parallax. The views span the footprints the
issue asks for: ``top`` (one texel a pixel), orthographic at 60, 45, 30 and
15 degrees (1.15 to 3.9 texels along the view), perspective near (about
half a texel) and far (about 4 across, 8 along).

``views.json``::

    {"format": "hzval views 1", "material": {...}, "rows": [
        {"view", "lookup", "camera": {kind, elevation_deg, ...}, "footprint_texels", "parallax_error_texels",
         "seen_fraction", "report", "techniques": {name: {visibility_mae, visibility_mae_facing,
         perfect_parallax_mae, flip_mean}}}]}

Every number is a mean over the sweep's frames (and, within a frame, over the
pixels that see the surface). The tables and plots show :func:`headline`: ``|F - V|`` over the
pixels facing the light, as ``hzval sweep`` does, where a view has them (``top``), else the whole
image's (the other views have no facing mask).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from hzval.core import interrupts
from hzval.core.errors import InputError
from hzval.io import atomic, documents, staging
from hzval.metrics.results import SweepResult, techniques_of
from hzval.pipeline import sweep
from hzval.report import figures
from hzval.report import pages as report
from hzval.scene import camera as hz_camera
from hzval.scene import lookup

__all__ = ["VIEWS", "LOOKUPS", "run", "headline"]

#: The views: name -> camera.
VIEWS: dict[str, hz_camera.Camera] = {
    "top": hz_camera.Camera(),
    "ortho-60": hz_camera.Camera(kind="orthographic", elevation_deg=60),
    "ortho-45": hz_camera.Camera(kind="orthographic", elevation_deg=45),
    "ortho-30": hz_camera.Camera(kind="orthographic", elevation_deg=30),
    "ortho-15": hz_camera.Camera(kind="orthographic", elevation_deg=15),
    "near": hz_camera.Camera(kind="perspective", elevation_deg=35, distance=0.5, fov_deg=40),
    "far": hz_camera.Camera(kind="perspective", elevation_deg=35, distance=6.0, fov_deg=40),
}
#: The lookups each view is swept with: name -> settings.
LOOKUPS: dict[str, lookup.Lookup] = {
    "bilinear": lookup.Lookup(),
    "mips": lookup.Lookup(filter="trilinear"),
    "parallax": lookup.Lookup(parallax="occlusion"),
    "mips+parallax": lookup.Lookup(filter="trilinear", parallax="occlusion"),
}


def run(
    scene,
    out: str | Path,
    *,
    views: list[str] | None = None,
    lookups: list[str] | None = None,
    options=None,
    progress: bool = True,
    command: str = "",
    force: bool = False,
) -> dict:
    """Sweep ``scene`` from every view with every lookup into ``out``.

    Writes ``views.json`` and ``index.html``; returns the ``views.json`` content. The ``top`` view is swept
    with the first lookup only: straight down, a ray meets the plane where it meets the surface, so parallax
    mapping moves nothing, and a pixel covers one texel, where mips read level 0. The run holds ``out``
    (:func:`hzval.io.staging.output_folder`, ``force`` as there) and writes into a staging folder swapped in
    whole: a failure, or a Ctrl-C (which stops the run between sweeps), leaves an earlier report byte for byte
    and no folder it created.
    """
    out = Path(out)
    chosen = _pick(views, VIEWS, "--views")
    kinds = _pick(lookups, LOOKUPS, "--lookups")
    with staging.swapped_in(out, force=force) as work:  # all or nothing, as a sweep
        with interrupts.cases():
            data = _run(scene, work, chosen, kinds, options, progress, command, force)
        data["command"] = staging.portable_command(command)
        documents.write_json(work / "views.json", data)
        _write_page(work, data)
    return data


def _run(scene, out: Path, chosen, kinds, options, progress: bool, command: str, force: bool) -> dict:
    """:func:`run`'s sweeps into ``out`` (the staging folder); the ``views.json`` content."""
    rows = []
    runs = [(v, k) for v in chosen for k in kinds if not (v == "top" and k != kinds[0])]
    for i, (v, k) in enumerate(runs):
        sc_v = dataclasses.replace(
            scene, camera=VIEWS[v], lookup=LOOKUPS[k], name=f"{scene.name} {v} {k}"
        ).validate()
        folder = out / v / k
        if progress:
            print(f"hzval views: {i + 1}/{len(runs)}: {v}, {k}", flush=True)
        result = sweep.run(
            sc_v,
            folder,
            options=options or sweep.Options(),
            progress=False,
            command=f"{command} # view {v}, lookup {k}".strip(),
            force=force,
        )
        rows.append(_row(v, k, result, folder.relative_to(out) / "index.html"))
    material = rows[0]["material"] if rows else {}
    for r in rows:
        r.pop("material")
    data = {
        "format": "hzval views 1",
        "material": material,
        "command": command,
        "rows": rows,
    }
    return data


def headline(scores: dict) -> float | None:
    """Return a technique's ``|F - V|`` in a row.

    It is over the pixels facing the light where measured (the top view), else over the whole image.
    """
    facing = scores.get("visibility_mae_facing")
    return scores.get("visibility_mae") if facing is None else facing


def _pick(names, table: dict, flag: str) -> list[str]:
    if names is None:
        return list(table)
    unknown = [n for n in names if n not in table]
    if unknown or not names:
        raise InputError(flag, f"unknown or no names {unknown}; choose from {', '.join(table)}")
    return list(dict.fromkeys(names))


def _row(view: str, kind: str, result: dict, report: Path) -> dict:
    """One sweep's means (module docstring)."""
    run = SweepResult.of(result)
    techniques = {}
    for name in run.techniques:
        per = [f.techniques[name] for f in run.frames]
        techniques[name] = {
            k: _mean([p.get(k) for p in per])
            for k in ("visibility_mae", "visibility_mae_facing", "perfect_parallax_mae", "flip_mean")
        }
    v = result.get("view") or {}
    cam = VIEWS[view]
    shape = result["camera"]["resolution"]
    top_footprint = {"p50": 1.0 / cam.supersampling, "mean": 1.0 / cam.supersampling}
    return {
        "view": view,
        "lookup": kind,
        "material": result["material"],
        "camera": {
            "kind": cam.kind,
            "elevation_deg": 90.0 if cam.kind == "top" else cam.elevation_deg,
            "distance": cam.distance if cam.kind == "perspective" else None,
            "resolution": shape,
        },
        "footprint_texels": v.get("footprint_texels", top_footprint),
        "parallax_error_texels": v.get("parallax_error_texels", {"mean": 0.0}),
        "seen_fraction": v.get("seen_fraction", 1.0),
        "report": str(report),
        "techniques": techniques,
    }


def _mean(values) -> float | None:
    vals = [float(x) for x in values if x is not None and math.isfinite(float(x))]
    return float(np.mean(vals)) if vals else None


# --------------------------------------------------------------------------
# The page
# --------------------------------------------------------------------------


def _write_page(out: Path, data: dict) -> None:

    plots = out / "plots"
    _plot(plots / "views.png", data["rows"])
    page = (
        report.environment()
        .get_template("views.html.j2")
        .render(
            material=data["material"],
            rows=data["rows"],
            command=data["command"],
            techniques=_technique_names(data["rows"]),
            plot="plots/views.png",
        )
    )
    with atomic.atomic_path(out / "index.html") as tmp:
        tmp.write_text(page, encoding="utf-8")


def _technique_names(rows: list[dict]) -> list[str]:
    names: list[str] = []
    for r in rows:
        names += [n for n in techniques_of(r) if n not in names]
    return names


def _plot(path: Path, rows: list[dict]) -> None:
    """Draw two panels per technique row: |F - V| against view elevation and against pixel footprint.

    Elevation covers the top and orthographic views; the footprint is the median pixel footprint, over every
    view. Each panel has one line per lookup.
    """
    names = _technique_names(rows)
    kinds = list(dict.fromkeys(r["lookup"] for r in rows))
    ylabel = "mean |F − V| (top: facing pixels)"
    grid = []
    for name in names:
        scored = [r for r in rows if headline(techniques_of(r).get(name) or {}) is not None]
        elevation = figures.Panel(f"{name}: error against view elevation", "view elevation (degrees)", ylabel)
        footprint = figures.Panel(
            f"{name}: error against pixel footprint", "texels a pixel covers (median)", ylabel, footprint=True
        )
        for k in kinds:
            pts = [r for r in scored if r["lookup"] == k or r["view"] == "top"]
            ortho = sorted(
                (r["camera"]["elevation_deg"], headline(techniques_of(r)[name]))
                for r in pts
                if r["camera"]["kind"] != "perspective"
            )
            if ortho:
                elevation.lines.append(figures.Line(k, ortho))
            foot = sorted(
                (r["footprint_texels"]["p50"], headline(techniques_of(r)[name]))
                for r in pts
                if r["footprint_texels"].get("p50") is not None
            )
            if foot:
                footprint.lines.append(figures.Line(k, foot))
        grid.append([elevation, footprint])
    figures.plot_panels(path, grid, (10, 3.2 * max(1, len(names))))
