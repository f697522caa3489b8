"""``hzval models [HEIGHT] --out DIR``: what curvature costs each technique (docs/models.md).

The flat bake sees a tile; on a sphere of radius ``R`` a horizon at distance ``d`` along the surface
lies ``d^2 / (2R)`` below the tangent plane (convex) or above it (concave). The study sweeps one
material on caps of spheres and bowls whose texture has a fixed world width ``W = 1`` (the caps'
``world_per_uv`` is 1, so ``depth`` and the relief in texels are the same on every cap), and on
the cube (Figure 5.1, its edges and seams):

``cap+R``
    A convex spherical cap of radius ``R`` texture widths (:data:`RADII`), ``2 A`` wide along the
    surface, laid out by geodesic polar coordinates: a grid point ``(x, y)`` at ``r = |(x, y)|``
    goes to ``R (sin(r/R) (x, y)/r, cos(r/R) - 1)``, its UV ``(x, y) + 1/2``: the UVs keep the radial
    distances exactly and the tangential ones to ``sin(r/R)/(r/R)`` (at least 0.90 here).
``bowl+R``
    The same cap mirrored in z with its normals turned inward: concave, signed curvature ``-1/R``.
``flat``
    ``R = infinity``: the same grid, a plane (curvature 0), the reference.
``ring``
    The inside of a torus's ring (:func:`ring_obj`): normal curvature ``-1/2`` along the ring (x,
    concave) and ``+1`` across the tube (y, convex); ``principal_curvatures`` in its row.
``cube``
    The built-in cube: its edges (the frame's normals bend through 90 degrees) and its seams.

Each case is one sweep (:func:`hzval.pipeline.sweep.run`, its report in ``DIR/<case>/``) of every technique
that renders on a model; ``DIR/models.json`` has per case the curvature ``1/R`` (signed, texture
widths^-1) and each technique's mean |F - V|, leaks, false shadows and perfect-parallax floor
(``perfect_parallax_mae``, the technique at the truth's own hits) over the lights; ``DIR/index.html``
plots the error against ``1/R``. The caps are written as OBJ files (z up) in ``DIR/meshes/``.

Each case is then rendered once more for the band (:mod:`hzval.studies.curvature_band`: the pixels whose
base normal sees the light at the scene's elevation, per texel, 16 lights, standard errors), paired
with the flat patch on the same texels: each row's ``band`` (its ``excess``: what curvature alone
costs; the cube's ``seam`` shares, :mod:`hzval.studies.seam_share`) and the study's ``trend`` (whether the
band's |F - V| and its excess rise as the caps' radius shrinks, within noise).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from hzval.core import interrupts
from hzval.io import atomic, documents, staging
from hzval.metrics.results import SweepResult, techniques_of
from hzval.pipeline import sweep
from hzval.report import figures
from hzval.report import pages as report
from hzval.scene import spec as sc
from hzval.studies import bug_signatures, curvature_band, seam_share

__all__ = ["run", "summary_table", "RADII", "BOWLS", "RING", "cap_obj", "ring_obj"]

#: Convex caps' radii and the bowls', in texture widths.
RADII: tuple[float, ...] = (0.5, 1.0, 2.0, 4.0, 8.0)
BOWLS: tuple[float, ...] = (1.0, 2.0)
#: The caps' half width along the surface, texture widths (smaller than the smallest radius).
A = 0.4
#: The torus of the ``ring`` case, texture widths: tube radius ``m`` (convex across the tube,
#: ``+1/m``) and the inner equator's radius about the axis ``rho`` (concave along the ring, ``-1/rho``).
RING: tuple[float, float] = (1.0, 2.0)
#: Grid cells of a cap along each side (its base mesh; the truth refines it to the texel scale).
CELLS = 32


def cap_obj(path: Path, radius: float, sign: int) -> None:
    """Write the cap (``sign`` +1), bowl (-1) or plane (``radius`` inf) of the module docstring as an OBJ.

    It is written at ``path``: positions z up, UVs, normals, counterclockwise seen from the normals' side.
    """
    g = np.linspace(-A, A, CELLS + 1)
    x, y = (a.ravel() for a in np.meshgrid(g, g))
    r = np.hypot(x, y)
    if math.isinf(radius):
        p, n = np.stack([x, y, 0 * x], -1), np.tile([0.0, 0.0, 1.0], (len(x), 1))
    else:
        th = r / radius
        ex, ey = (
            np.divide(x, r, out=np.zeros_like(x), where=r > 0),
            np.divide(y, r, out=np.zeros_like(y), where=r > 0),
        )
        s = np.sin(th)
        p = np.stack([radius * s * ex, radius * s * ey, sign * radius * (np.cos(th) - 1.0)], -1)
        n = np.stack([sign * s * ex, sign * s * ey, np.cos(th)], -1)
    _write_grid_obj(path, p, n, np.stack([x, y], -1) + 0.5)


def cases() -> list[tuple[str, float, str | None]]:
    """``(name, signed curvature 1/R, mesh radius spec)``."""
    out = [(f"cap+{R:g}", 1.0 / R, ("cap", R, 1)) for R in RADII]
    out += [(f"bowl+{R:g}", -1.0 / R, ("cap", R, -1)) for R in BOWLS]
    out += [("ring", None, ("ring", RING, 0))]
    return out + [("flat", 0.0, ("cap", math.inf, 1)), ("cube", None, ("shape", "cube", 0))]


def run(scene, out: str | Path, *, progress: bool = True, command: str = "", force: bool = False) -> dict:
    """Sweep ``scene`` (its material, lights, spp) on every case into ``out``.

    Write ``models.json`` and ``index.html``; return the ``models.json`` content. All or nothing, as a sweep:
    the cases are written into a staging folder inside ``out`` and swapped in whole, so a failure, or a Ctrl-C
    (which stops the run between cases), leaves an earlier report byte for byte and no folder it made.
    """
    out = Path(out)
    with staging.swapped_in(out, force=force) as work:
        with interrupts.cases():
            data = _run(scene, work, progress, command, force)
        data["command"] = staging.portable_command(command)
        documents.write_json(work / "models.json", data)
        _write_page(work, data)
    return data


def case_scene(scene, out: Path, name: str, spec):

    kind, value, sign = spec
    if kind in ("cap", "ring"):
        obj = out / "meshes" / f"{name}.obj"
        cap_obj(obj, value, sign) if kind == "cap" else ring_obj(obj, *value)
        mesh = dataclasses.replace(scene.mesh, shape=str(obj.resolve()), up="z", uv_scale=1.0)
        cam = dataclasses.replace(scene.camera, kind="orthographic", elevation_deg=60.0, azimuth_deg=-90.0)
    else:
        mesh = dataclasses.replace(scene.mesh, shape=value, uv_scale=1.0)
        cam = dataclasses.replace(sc.MODEL_CAMERA, resolution=scene.camera.resolution)
    return dataclasses.replace(scene, mesh=mesh, camera=cam, name=f"{scene.name} {name}").validate()


def _run(scene, out: Path, progress: bool, command: str, force: bool) -> dict:

    rows, bands = [], {}
    todo = cases()
    for i, (name, curvature, spec) in enumerate(todo):
        if progress:
            print(f"hzval models: {i + 1}/{len(todo)}: {name}", flush=True)
        sc = case_scene(scene, out, name, spec)
        result = sweep.run(
            sc,
            out / name,
            options=sweep.Options(),
            progress=False,
            command=f"{command} # case {name}".strip(),
            force=force,
        )
        rows.append(_row(name, curvature, result))
        _ring_row(rows[-1], spec)
        bands[name] = _band_maps(sc, out / name)
    data = {
        "format": "hzval models 1",
        "material": {**result["material"], "name": scene.name},
        "command": command,
        "half_width": A,
        "rows": rows,
    }
    _add_bands(data, bands)
    data["bugs"] = _bug_signatures(scene, out, SweepResult.of(result).names, progress)
    return data


def _bug_signatures(scene, out: Path, techniques, progress: bool) -> dict:
    """Each tangent bug's signature with the lead technique (:mod:`hzval.studies.bug_signatures`)."""
    height = sc.load_material_height(scene.material).height
    return bug_signatures.run(scene, height, list(techniques)[0], out, progress=progress)


def _mean(values) -> float | None:
    vals = [float(x) for x in values if x is not None and math.isfinite(float(x))]
    return float(np.mean(vals)) if vals else None


def _row(name: str, curvature, result: dict) -> dict:
    """One case's means over its lights."""
    techniques = {}
    run = SweepResult.of(result)
    for t in run.techniques:
        per = [f.techniques[t] for f in run.frames]
        techniques[t] = {
            k: _mean([p.get(k) for p in per])
            for k in (
                "visibility_mae",
                "leak_fraction",
                "false_shadow_fraction",
                "perfect_parallax_mae",
                "reflection_mae",
            )
        }
    return {
        "case": name,
        "curvature": curvature,
        "radius": None if not curvature else 1.0 / abs(curvature),
        "mesh": {k: result.get("mesh", {}).get(k) for k in ("source", "world_per_uv", "mirrored_fraction")},
        "report": f"{name}/index.html",
        "techniques": techniques,
    }


def _write_page(out: Path, data: dict) -> None:
    """``out/index.html`` from ``models.html.j2`` (:func:`hzval.report.pages.environment`), and its plots."""
    rows = data["rows"]
    names = list(dict.fromkeys(t for r in rows for t in techniques_of(r)))
    _plot(out / "plots" / "models.png", rows, names)
    keys = ("visibility_mae", "leak_fraction", "false_shadow_fraction", "perfect_parallax_mae")
    context = {
        "material": str(data["material"].get("name", "")),
        "command": data["command"],
        "names": names,
        "rows": [
            {
                "case": r["case"],
                "report": r["report"],
                "curvature": "-" if r["curvature"] is None else f"{r['curvature']:+.3g}",
                "cells": [_f4(techniques_of(r).get(n, {}).get(k)) for n in names for k in keys],
            }
            for r in rows
        ],
        "reflection": _plot_reflection(out / "plots" / "reflection.png", rows, names),
        "band": _band_context(out, data),
        "bugs": bug_signatures.page_context(data["bugs"]) if data.get("bugs") else None,
    }
    page = report.environment().get_template("models.html.j2").render(**context)
    with atomic.atomic_path(out / "index.html") as tmp:
        tmp.write_text(page, encoding="utf-8")


def _f4(v) -> str:
    return "-" if v is None else f"{v:.4f}"


def _plot_reflection(path: Path, rows: list[dict], names: list[str]) -> dict | None:
    """Plot each technique's reflection-occlusion error against signed curvature 1/R.

    The error is mean |o - R| (``reflection_mae``: Toolbag's fade with the interpolated vertex normal against
    the traced glossy lobe), plotted where the study declares ``reflection_occlusion``. Return the page's
    figure and table (``None``: no case has it).
    """
    series = {n: s for n in names if (s := _against_curvature(rows, n, "reflection_mae"))}
    if not series:
        return None
    lines = [figures.Line(n, pts) for n, pts in series.items()]
    panel = figures.Panel("reflection occlusion against curvature", figures.CURVATURE, "mean |o − R|", lines)
    figures.plot_panels(path, [[panel]], (7, 4))
    return {
        "plot": f"plots/{path.name}",
        "names": list(series),
        "rows": [
            {
                "case": r["case"],
                "cells": [_f4(techniques_of(r).get(n, {}).get("reflection_mae")) for n in series],
            }
            for r in rows
        ],
    }


def _against_curvature(rows: list[dict], name: str, key: str) -> list[tuple[float, float]]:
    """Technique ``name``'s ``key`` against each case's signed curvature, in increasing curvature."""
    pts = sorted((r for r in rows if r["curvature"] is not None), key=lambda r: r["curvature"])
    return [
        (r["curvature"], techniques_of(r)[name][key])
        for r in pts
        if techniques_of(r).get(name, {}).get(key) is not None
    ]


def _plot(path: Path, rows: list[dict], names: list[str]) -> None:
    """Each technique's mean |F - V| (and its floor, dashed) against signed curvature 1/R."""
    lines = []
    for n in names:
        if err := _against_curvature(rows, n, "visibility_mae"):
            lines.append(figures.Line(n, err))
        if fl := _against_curvature(rows, n, "perfect_parallax_mae"):
            lines.append(figures.Line(f"{n} floor", fl, dashed=True))
    panel = figures.Panel("error against curvature", figures.CURVATURE, "mean |F − V|", lines)
    figures.plot_panels(path, [[panel]], (7, 4))


# -- the band: curvature and nothing else (hzval.studies.curvature_band) --------------------------------


def _band_maps(scene, case_dir: Path) -> dict:
    """Return the case's band texel maps.

    They are :func:`hzval.studies.curvature_band.measure`'s, with its own camera and lights.
    """
    return curvature_band.measure(curvature_band.band_scene(scene), case_dir)


def _add_bands(data: dict, bands: dict) -> None:
    """Add each band-measured row's ``band`` and the study's ``trend``.

    The ``band`` is against the flat patch on the same texels. The ``trend`` says, per technique, whether the
    band's |F - V| and its excess over the flat patch rise from the flat patch through the caps as R shrinks
    (:func:`hzval.studies.curvature_band.trend`).
    """
    flat = bands.get("flat")
    for r in data["rows"]:
        if r["case"] in bands:
            patch = r["case"] != "flat" and r["mesh"].get("source", "").endswith(".obj")  # the patch's UVs
            r["band"] = curvature_band.paired(bands[r["case"]], flat if patch else None)
        if "principal_curvatures" in r and "band" in r:
            r["band"]["by_azimuth"] = _by_azimuth(r, curvature_band.AZIMUTHS)
    convex = [
        r for r in data["rows"] if "band" in r and (r["case"].startswith("cap+") or r["case"] == "flat")
    ]
    names = list(dict.fromkeys(t for r in convex for t in techniques_of(r["band"])))
    data["band"] = {
        "half_deg": curvature_band.BAND_DEG,
        "window": curvature_band.WINDOW,
        "azimuths": list(curvature_band.AZIMUTHS),
        "resolution": list(curvature_band.RESOLUTION),
    }
    data["trend"] = {}
    for n in names:
        have = [r for r in convex if n in techniques_of(r["band"])]
        mae = [(r["curvature"], techniques_of(r["band"])[n]["per_frame"]) for r in have]
        exc = [
            (
                r["curvature"],
                techniques_of(r["band"])[n].get("per_frame_excess")
                or [0.0] * len(techniques_of(r["band"])[n]["per_frame"]),
            )
            for r in have
        ]
        data["trend"][n] = {"mae": curvature_band.trend(mae), "excess": curvature_band.trend(exc)}


# -- the inside of a torus's ring -----------------------------------------------------------


def ring_obj(path: Path, tube: float, rho: float) -> None:
    """Write a ``2 A`` square patch of a torus about its inner equator as an OBJ at ``path``.

    The patch is z up, its centre at the origin and its normal +z. The tube radius is ``tube``, and the inner
    equator is a circle of radius ``rho`` about the torus's axis, which runs along y at height ``rho``.

    A grid point ``(x, y)`` goes to ring angle ``phi = x / rho`` and tube angle ``tau = y / tube``
    (from the inner equator): ``p = C + (rho + tube (1 - cos tau)) e(phi) + tube sin tau y``,
    ``e(phi) = (sin phi, 0, -cos phi)``, ``C = (0, 0, rho)``, its normal ``-cos tau e + sin tau y``;
    UV ``(x, y) + 1/2``. Lengths along the tube are the UVs' exactly, along the ring to
    ``1 + tube (1 - cos tau) / rho`` (1.04 at the rim, 1.008 inside the band's window). Along x the
    surface bends toward its normal (concave, normal curvature ``-1/rho``), along y away from it
    (convex, ``+1/tube``): the inside of a torus's ring, with one texture per world unit (the
    built-in torus's UVs are stretched 3:1 there, around the ring against around the tube).
    """
    g = np.linspace(-A, A, CELLS + 1)
    x, y = (a.ravel() for a in np.meshgrid(g, g))
    phi, tau = x / rho, y / tube
    e = np.stack([np.sin(phi), 0 * phi, -np.cos(phi)], -1)
    yy = np.array([0.0, 1.0, 0.0])
    p = (
        np.array([0.0, 0.0, rho])
        + (rho + tube * (1 - np.cos(tau)))[:, None] * e
        + (tube * np.sin(tau))[:, None] * yy
    )
    n = -np.cos(tau)[:, None] * e + np.sin(tau)[:, None] * yy
    _write_grid_obj(path, p, n, np.stack([x, y], -1) + 0.5)


def _write_grid_obj(path: Path, p: np.ndarray, n: np.ndarray, uv: np.ndarray) -> None:
    """Write a ``CELLS x CELLS`` grid's positions, normals and UVs (x fastest) as an OBJ.

    The winding is counterclockwise seen from the normals' side.
    """
    k = CELLS + 1
    i, j = np.meshgrid(np.arange(CELLS), np.arange(CELLS))
    a = (j * k + i).ravel()
    faces = np.concatenate([np.stack([a, a + 1, a + k + 1], -1), np.stack([a, a + k + 1, a + k], -1)])
    lines = [f"v {q[0]:.9g} {q[1]:.9g} {q[2]:.9g}" for q in p] + [f"vt {q[0]:.9g} {q[1]:.9g}" for q in uv]
    lines += [f"vn {q[0]:.9g} {q[1]:.9g} {q[2]:.9g}" for q in n]
    lines += ["f " + " ".join(f"{v + 1}/{v + 1}/{v + 1}" for v in f) for f in faces]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n")


def _ring_row(row: dict, spec) -> None:
    """Add the ring case's principal curvatures (texture widths^-1, + convex) and their directions."""
    if spec[0] == "ring":
        tube, rho = spec[1]
        row["principal_curvatures"] = {"along_ring_x": -1.0 / rho, "across_tube_y": 1.0 / tube}


def _by_azimuth(row: dict, azimuths) -> list[dict]:
    """Return, per light of the band, its azimuth, normal curvature and each technique's excess.

    The normal curvature is along the light's direction (Euler: ``k_x cos^2 phi + k_y sin^2 phi``); the excess
    is over the flat patch.
    """
    kx, ky = row["principal_curvatures"]["along_ring_x"], row["principal_curvatures"]["across_tube_y"]
    out = []
    for i, az in enumerate(azimuths):
        c, s = math.cos(math.radians(az)), math.sin(math.radians(az))
        out.append(
            {
                "azimuth_deg": float(az),
                "normal_curvature": kx * c * c + ky * s * s,
                "excess": {
                    n: (t.get("per_frame_excess") or [None] * (i + 1))[i]
                    for n, t in techniques_of(row["band"]).items()
                },
            }
        )
    return out


# -- the band's table, trend and plot on the page ------------------------------------------------


def _pm(stat: dict | None, digits: int = 4, signed: bool = False) -> str:
    """``mean ± se`` of a ``{mean, se}`` statistic, or ``-``."""
    if not stat or stat.get("mean") is None:
        return "-"
    m, se = f"{stat['mean']:{'+' if signed else ''}.{digits}f}", stat.get("se")
    return f"{m} ± {se:.{digits}f}" if se is not None else m


def _band_context(out: Path, data: dict) -> dict | None:
    """Return the band's section of the page and its excess plot.

    Per case and technique the section has |F - V|, the flat patch's on the same texels, the excess, the floor
    and the seams' share, and it has the trend's verdicts; ``None`` where no case has a band.
    """
    rows = [r for r in data["rows"] if "band" in r]
    if not rows:
        return None
    b = data["band"]
    names = list(dict.fromkeys(t for r in rows for t in techniques_of(r["band"])))
    _band_plot(out / "plots" / "band.png", rows, names)
    return {
        "half_deg": f"{b['half_deg']:g}",
        "window": f"{b['window']:g}",
        "lights": len(b["azimuths"]),
        "resolution": f"{b['resolution'][0]}×{b['resolution'][1]}",
        "seam_texels": _seam_texels(),
        "names": names,
        "verdicts": [
            {"name": n, "mae": _says(t["mae"]), "excess": _says(t["excess"])}
            for n, t in data.get("trend", {}).items()
        ],
        "rows": [_band_row(r, names) for r in rows],
    }


def _band_row(r: dict, names: list[str]) -> dict:
    cells = []
    for n in names:
        t = techniques_of(r["band"]).get(n, {})
        seam = t.get("seam")
        cells += [_pm(t.get(k), signed=k == "excess") for k in ("mae", "flat", "excess", "floor")]
        cells.append(
            "-"
            if not seam or seam["error_share"]["mean"] is None
            else f"{seam['error_share']['mean']:.3f} / {seam['pixel_share']:.3f}"
        )
    k = r.get("principal_curvatures")
    if k:
        curvature = f"{k['along_ring_x']:+g} (x), {k['across_tube_y']:+g} (y)"
    else:
        curvature = "-" if r["curvature"] is None else f"{r['curvature']:+.3g}"
    return {
        "case": r["case"],
        "curvature": curvature,
        "texels": f"{r['band']['texels']:.0f}",
        "lit": _pm(r["band"].get("lit_excess"), 3, True),
        "cells": cells,
    }


def _seam_texels() -> str:

    return f"{seam_share.SEAM_TEXELS:g}"


def _says(t: dict) -> str:
    """Return a trend as one phrase: its verdict, the whole change with its z, and any falls' z."""
    o = t.get("overall") or {}
    if o.get("change") is None:
        return t["verdict"]
    falls = ", ".join(_fall(f) for f in t["falls"])
    return (
        f"{t['verdict']} (flat to 1/R = {o['to']:+g}: {o['change']:+.4f}, {o['z']:+.1f} SE"
        + (f"; falls {falls}" if falls else "")
        + ")"
    )


def _fall(f: dict) -> str:
    """Return one step that does not rise, as text.

    For example ``+0.25->+0.5 by 1.3 SE``, or ``no change`` where it is flat to a tenth of a standard error
    (never ``by -0.0 SE``).
    """
    step = f"{f['from']:+g}->{f['to']:+g}"
    z = f.get("z")
    if z is None:
        return step
    if round(-z, 1) == 0:
        return f"{step} no change"
    return f"{step} by {-z:.1f} SE"


def _band_plot(path: Path, rows: list[dict], names: list[str]) -> None:
    """Each technique's band excess over the flat patch, with one standard error, against 1/R."""
    pts = sorted((r for r in rows if r["curvature"] is not None), key=lambda r: r["curvature"])
    lines = []
    for n in names:
        have = [
            (r["curvature"], techniques_of(r["band"])[n].get("excess"))
            for r in pts
            if n in techniques_of(r["band"])
        ]
        have = [(k, e["mean"], e["se"] or 0.0) for k, e in have if e and e["mean"] is not None]
        if have:
            lines.append(figures.Line(n, [(k, m) for k, m, _ in have], errors=[se for *_, se in have]))
    ylabel = "band |F − V| − flat's, same texels"
    panel = figures.Panel("what curvature alone costs (± 1 SE)", figures.CURVATURE, ylabel, lines, zero=True)
    figures.plot_panels(path, [[panel]], (7, 4))


def summary_table(data: dict) -> str:
    """Return ``models.json``'s content as the terminal's table.

    Per case it shows each technique's mean |F - V| and floor (and its reflection error where measured), the
    trends' verdicts and each tangent bug's mirrored |F - V| against the correct frames'.
    """

    def num(v, w=7):
        return f"{v:{w}.4f}" if v is not None else f"{'-':>{w}}"

    rows = data["rows"]
    names = list(dict.fromkeys(t for r in rows for t in techniques_of(r)))
    refl = [
        n for n in names if any(techniques_of(r).get(n, {}).get("reflection_mae") is not None for r in rows)
    ]
    lines = [
        f"{'case':10} {'1/R':>7}  "
        + "  ".join(f"{n:>9} {'floor':>7}" for n in names)
        + "".join(f"  {n + ' |o-R|':>14}" for n in refl)
    ]
    for r in rows:
        k = f"{'-':>7}" if r["curvature"] is None else f"{r['curvature']:+7.3f}"  # the ring, the cube
        t = techniques_of(r)
        vals = "  ".join(
            f"{num(t[n]['visibility_mae'], 9)} {num(t[n]['perfect_parallax_mae'])}" for n in names if n in t
        )
        lines.append(
            f"{r['case']:10} {k}  {vals}"
            + "".join(f"  {num(t.get(n, {}).get('reflection_mae'), 14)}" for n in refl)
        )
    for n, t in data.get("trend", {}).items():
        lines.append(f"{n}: band |F-V| {_says(t['mae'])}; excess over flat {_says(t['excess'])}")
    bugs = data.get("bugs")
    if bugs:
        for case, rec in bugs["cases"].items():
            ratios = ", ".join(
                f"{b} {r['mirrored_ratio']:.2f}x"
                for b, r in rec["bugs"].items()
                if b != "none" and r.get("mirrored_ratio") is not None
            )
            lines.append(f"tangent bugs on {case} ({bugs['technique']} mirrored |F-V| / correct): {ratios}")
    return "\n".join(lines)
