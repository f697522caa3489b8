"""What a sweep records besides its images.

That is ``frames.json`` (what an engine needs to render the same frames, :func:`engine_frames`),
``metrics.json``'s view and mesh parameters, and the terminal's table (:func:`summary_table`).
"""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

from hzval.geometry import model
from hzval.io import staging
from hzval.metrics import compare
from hzval.metrics.results import SweepResult
from hzval.report import ranking
from hzval.scene import lookup

__all__ = [
    "frame_folder",
    "frame_name",
    "engine_frames",
    "scene_parameters",
    "view_parameters",
    "mesh_parameters",
    "summary_table",
]


def frame_folder(azimuth_deg: float, elevation_deg: float | None = None) -> str:
    """Return the folder name of a frame: ``az-60``, ``az+0``, ``az+7.5``.

    In a sweep over several elevations the elevation comes first, ``el15_az+0``.

    Examples
    --------
    >>> frame_folder(-60.0), frame_folder(7.5, 15.0)
    ('az-60', 'el15_az+7.5')
    """
    name = f"az{azimuth_deg:+g}"
    return name if elevation_deg is None else f"el{elevation_deg:g}_{name}"


def frame_name(frame: dict) -> str:
    """Return the name of a ``metrics.json`` or ``frames.json`` frame.

    It is the frame's own ``name``, else (a sweep of before the elevation axis) its azimuth's
    :func:`frame_folder`.
    """
    return frame.get("name") or frame_folder(frame["azimuth_deg"])


def engine_frames(
    scene, result: dict, albedo_constant: float | None = None, albedo_files: dict | None = None
) -> dict:
    """``frames.json``: what an engine needs to render the sweep's frames itself, for ``hzval score``.

    Per light: the frame's name (``az+0``: the file ``hzval score`` looks for, ``az+0.exr`` linear
    or ``az+0.png`` sRGB, and ``f_az+0.exr`` its shadow factor F), azimuth and elevation, and ``L``
    in tangent space (toward the light); for all: the camera, the light's kind, irradiance and
    radiance, the albedo, the samples per pixel and the rule that places them, the display exposure
    and what it means for an EXR and a PNG, the image size and the material (:func:`_engine_notes`).
    ``albedo_files``: where an albedo image was written beside it
    (:func:`hzval.pipeline.writing.write_albedo`).
    """
    m = result["material"]
    return {
        "format": "hzval engine frames 2",
        "material": m,
        "image_size": result["camera"]["resolution"],
        "camera": result["camera"],
        "light": {
            "kind": scene.light.kind,
            "radius_deg": scene.light.radius_deg,
            "irradiance": scene.light.irradiance,
            **_light_radiance(scene.light),
        },
        "exposure": result["exposure"]["scale"],
        "effects": list(scene.effects),
        **_engine_notes(scene, albedo_constant, albedo_files),
        "conventions": "tangent space in texels: +x right, +y up the image, +z out of the surface; "
        "azimuth counterclockwise from +x; L points toward the light",
        "frames": [
            {
                "name": frame_name(f),
                "azimuth_deg": f["azimuth_deg"],
                "elevation_deg": f["elevation_deg"],
                "light_direction": [
                    float(c) for c in scene.light.direction(f["azimuth_deg"], f["elevation_deg"])
                ],
            }
            for f in result["frames"]
        ],
    }


def _light_radiance(light) -> dict:
    """Return the light's radiance.

    A ``hard`` light is a direction (a delta: no radiance, only its irradiance ``E`` on a surface facing it);
    a ``soft`` disk of angular radius ``rho`` whose facing surface receives ``E`` has ``L = E / (pi sin^2
    rho)`` (docs/ARCHITECTURE.md, "Shading").
    """
    if light.kind != "soft" or not light.radius_deg:
        return {
            "radiance": None,
            "radiance_note": "a directional light: irradiance E on a surface facing it, "
            "E cos(theta) on one at theta",
        }
    rho = math.radians(light.radius_deg)
    return {
        "radiance": light.irradiance / (math.pi * math.sin(rho) ** 2),
        "radiance_note": "a disk of uniform radiance L = E / (pi sin^2 rho): a surface facing it receives E",
    }


def _engine_notes(scene, albedo_constant, albedo_files: dict | None = None) -> dict:
    """Return ``frames.json``'s albedo, samples and exposure.

    These are what a frame scored against the truth must match besides the shadows (a one-sample shader loses
    0.01-0.016 FLIP to aliasing alone; a frame pi times too bright, FLIP 0.68).
    """
    if isinstance(albedo_constant, float):
        albedo = {"kind": "constant", "linear": albedo_constant}
    else:  # an image: written beside frames.json, as linear EXR and as sRGB PNG
        albedo = {"kind": "image", **(albedo_files or {})}
        albedo["from"] = (
            "the material's albedo image"
            if isinstance(scene.material.albedo, str)
            else "the built-in material's own albedo image"
        )
    albedo["brdf"] = "Lambert: radiance = albedo / pi * E * max(N.L, 0) (with diffuse)"
    spp = scene.spp
    n = int(round(math.sqrt(spp)))
    rule = (
        "sample s of pixel p = row * width + col at (u, v) in the pixel, u = (s mod n + U) / n, "
        f"v = (floor(s / n) + V) / n with n = {n} (jittered {n}x{n} strata)"
        if n * n == spp
        else "sample s of pixel p at (u, v) = (U, V) in the pixel (uniform)"
    )
    rule += (
        "; U, V: doubles of numpy's PCG64(SeedSequence([seed, 0x5A3F])), all U of the image in order "
        "p * spp + s, then all V; texel space x = (col + u) / supersampling, y = rows - (row + v) / "
        "supersampling; a pixel is the mean of its samples (hzval.scene.camera.sample_positions)"
    )
    return {
        "albedo": albedo,
        "samples": {
            "spp": spp,
            "seed": scene.seed,
            "supersampling": scene.camera.supersampling,
            "layout": "stratified" if n * n == spp else "uniform",
            "rule": rule,
        },
        "exposure_meaning": {
            "exr": "linear radiance as rendered, before the exposure (hzval score reads it as it is)",
            "png": "display values: srgb_encode(clip(exposure * radiance, 0, 1)), 8 or 16 bits (hzval score "
            "decodes sRGB and divides by the exposure)",
            "f": "f_<name>.exr or .png: the shadow factor F in [0, 1] per pixel (one channel, no sRGB)",
        },
    }


def scene_parameters(scene, out: Path, techniques: list[str]) -> dict:
    """Return ``metrics.json``'s ``parameters`` of a sweep of ``scene`` into ``out`` with ``techniques``.

    ``techniques`` are their names. The parameters are known before the sweep runs, so that a baseline's can
    be compared first.
    """
    return {
        "depth": scene.material.depth,
        "boundary": scene.material.boundary,
        "elevation_deg": scene.light.elevation_deg,
        "elevations_deg": list(scene.light.elevations()),
        "azimuths_deg": list(scene.light.azimuths_deg),
        "light": scene.light.kind,
        "light_radius_deg": scene.light.radius_deg,
        "effects": list(scene.effects),
        "spp": scene.spp,
        "seed": scene.seed,
        "supersampling": scene.camera.supersampling,
        "truth_tolerance": scene.material.truth_tolerance,
        **view_parameters(scene),
        **mesh_parameters(scene, out),
        "techniques": list(techniques),
    }


def view_parameters(scene) -> dict:
    """Return the camera's and the lookup's settings for ``metrics.json``'s parameters.

    There are none for the ``top`` view with the default lookup, whose parameters are as they always were.
    """
    cam, lk = scene.camera, scene.lookup
    if cam.kind == "top" and lk == lookup.Lookup():
        return {}
    out = {"camera": cam.kind}
    if cam.kind != "top":
        out.update(view_elevation_deg=cam.elevation_deg, view_azimuth_deg=cam.azimuth_deg)
    if cam.kind == "perspective":
        out.update(fov_deg=cam.fov_deg, distance_tiles=cam.distance)
    out.update(plane=lk.plane, filter=lk.filter, parallax=lk.parallax)
    if lk.mipmapped:
        out["mips"] = lk.mips
    if lk.filter == "anisotropic":
        out["max_anisotropy"] = lk.max_anisotropy
    if lk.parallax == "occlusion":
        out["parallax_steps"] = lk.parallax_steps
    return out


def mesh_parameters(scene, out: Path) -> dict:
    """Return the mesh's settings for ``metrics.json``'s parameters.

    There are none for the plane, as before. A mesh file is relative to ``out``, as the material's path is, so
    that ``score`` finds it from anywhere.
    """
    if scene.mesh.is_plane:
        return {}
    shape = scene.mesh.shape
    return {
        "mesh": shape if shape in model.SHAPES else staging.report_path(shape, out),
        "uv_scale": scene.mesh.uv_scale,
        "up": scene.mesh.up,
        "tangent_bug": scene.mesh.tangent_bug,
    }


#: The terminal table's width at most, in characters (its notes are wrapped to it).
TABLE_WIDTH = 100


def summary_table(result: dict) -> str:
    """Return the sweep's scores for the terminal, under 100 columns.

    It has a row per technique (the means over its frames of its visibility and image scores, and its render
    time per frame), then no shadows at all (``F = 1``) as the baseline, then notes: each technique's worst
    frame, the light elevations at which a technique is worse than no shadows
    (:func:`hzval.report.ranking.worse_than_none`), its split of the error where it has one (``split_parts``),
    and what ``|F-V|`` is measured over. The report and ``metrics.json`` hold every frame.
    """
    run = SweepResult.of(result)
    frames, names = run.frames, run.names
    facing = any("visibility_mae_facing" in t for f in frames for t in f.techniques.values())
    hits = any("perfect_parallax_mae" in t for f in frames for t in f.techniques.values())

    def vis(t: dict, key: str):
        return t.get(f"{key}_facing", t.get(key)) if facing else t.get(key)

    def mean(records, key, pick=None):
        vals = [(pick or (lambda r, k: r.get(k)))(r, key) for r in records]
        vals = [float(v) for v in vals if isinstance(v, (int, float)) and math.isfinite(v)]
        return sum(vals) / len(vals) if vals else None

    def num(v, digits, scale=1.0, suffix=""):
        return "-" if v is None else f"{v * scale:.{digits}f}{suffix}"

    floor = {r["name"]: r["floor"] for r in ranking.ranking(result)} if ranking.fits(result) else None
    head = ("technique", "|F-V|") + (("floor",) if floor else ()) + (("at hits",) if hits else ())
    head += ("leaks", "false sh.", "FLIP", "dE2000")
    head += ("PSNR dB", "ms/frame")
    rows = []
    for n in [*names, ranking.NONE]:
        found = [f.no_shadows if n == ranking.NONE else f.scores(n) for f in frames]
        recs = [r for r in found if r is not None]
        if not recs:
            continue
        psnr = [r.get("psnr_db") for r in recs]
        # on a model the baseline keeps the base mesh's own shadow, which every technique's F holds too
        none = f"{n} (F = 1)" if not result.get("mesh") else f"{n} (F = M)"
        row = (none if n == ranking.NONE else n, num(mean(recs, "visibility_mae", vis), 4))
        row += (num(floor.get(n), 4),) if floor else ()
        row += (num(mean(recs, "perfect_parallax_mae"), 4),) if hits else ()
        row += (
            num(mean(recs, "leak_fraction", vis), 2, 100, "%"),
            num(mean(recs, "false_shadow_fraction", vis), 2, 100, "%"),
            num(mean(recs, "flip_mean"), 4),
            num(mean(recs, "delta_e2000_mean"), 3),
            _psnr_cell(compare.pooled_psnr_db([r.get("rmse") for r in recs]), psnr),
            num(mean(recs, "seconds"), 1, 1000),
        )
        rows.append(row)
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(head)]

    def line(cells):
        return "  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in enumerate(zip(cells, widths)))

    return "\n".join(
        [line(head), line(["-" * w for w in widths]), *map(line, rows), *_table_notes(result, facing, hits)]
    )


def _psnr_cell(pooled: float | None, psnr: list) -> str:
    """Return the terminal's PSNR of a technique over the frames.

    See :func:`hzval.metrics.compare.pooled_psnr_db`.
    """
    if pooled is None:
        return "inf" if psnr and all(p is None for p in psnr) else "-"
    return "inf" if math.isinf(pooled) else f"{pooled:.2f}"


def _floor_notes(result: dict, several: bool) -> list[str]:
    """Return a line per fitted technique, with its shipped |F-V| split per elevation.

    The split is into what the bake loses and its floor (the representation's), beside no shadows; the lines
    also say where even the floor does harm.
    """

    def cell(v):
        return "-" if v is None else f"{v:.4f}"

    notes = []
    for n, rows in ranking.floors(result).items():
        parts = [
            (f"{r['elevation_deg']:g} deg: " if several else "")
            + f"{cell(r['shipped'])} = bake loss {cell(r['bake_loss'])} + floor {cell(r['floor'])} "
            f"(no shadows {cell(r['none'])})"
            for r in rows
        ]
        notes.append(f"{n} against its fit ({rows[0]['fit']}): " + "; ".join(parts))
        if any(r["bake_loss"] is not None and r["bake_loss"] < 0 for r in rows):
            notes.append(
                f"{n}: a negative bake loss is a fit worse than the bake at that elevation (it traded it "
                "for its training lights): there the floor is not reached"
            )
    harm = ranking.formula_harms(result)
    if harm:
        notes.append(
            "the formula itself does harm (even its fitted floor is worse than no shadows): "
            + "; ".join(
                n + (" at " + ", ".join(f"{e:g}" for e in at) + " deg" if several else "")
                for n, at in harm.items()
            )
        )
    return notes


def _table_notes(result: dict, facing: bool, hits: bool) -> list[str]:
    """:func:`summary_table`'s lines under the table."""
    run = SweepResult.of(result)
    frames = run.frames
    notes = []
    if result.get("mesh"):
        notes.append("F = M: no technique's shadows, the base mesh's own shadow M alone (every F holds it)")
    worst = []
    for n in run.techniques:
        scored = [(ranking.visibility_of(t), frame_name(f)) for f in frames if (t := f.scores(n)) is not None]
        scored = [(v, name) for v, name in scored if isinstance(v, (int, float)) and math.isfinite(v)]
        if len(scored) > 1:
            v, name = max(scored)
            worst.append(f"{n} {name} ({v:.4f})")
    if worst:
        notes.append("worst frame by |F-V|: " + ", ".join(worst))
    table = ranking.by_elevation(result)
    several = len(table.get(ranking.NONE, [])) > 1
    harm = [(n, ranking.worse_than_none(table, n)) for n in run.techniques]
    harm = [(n, at) for n, at in harm if at]
    if harm:
        notes.append(
            "worse than no shadows"
            + (" (mean |F-V| at that elevation): " if several else ": ")
            + "; ".join(
                f"{n}" + (" at " + ", ".join(f"{e:g}" for e in at) + " deg" if several else "")
                for n, at in harm
            )
        )
    floor = ranking.floor_note(result)
    if floor:
        notes.append(floor)
    notes += _floor_notes(result, several)
    for n, t in run.techniques.items():
        parts = [p["key"] for p in t.get("split_parts") or []]
        sums = {k: [(f.scores(n) or {}).get("split", {}).get(k) for f in frames] for k in parts}
        sums = {k: [v for v in vs if isinstance(v, (int, float))] for k, vs in sums.items()}
        if parts and any(sums.values()):
            notes.append(
                f"{n} split: " + ", ".join(f"{k} {sum(v) / len(v):.4f}" for k, v in sums.items() if v)
            )
    if facing:
        notes.append(
            "|F-V|, leaks and false shadows: means over the frames, each over the pixels that face the light "
            "(metrics.json: *_facing; visibility_mae for the whole image)"
        )
    if hits:
        notes.append(
            "at hits: |F-V| with the technique read at the truth's own hits (no parallax); the gap to "
            "|F-V| is the flat surface's parallax, not its shadows"
        )
    return [textwrap.fill(n, width=TABLE_WIDTH, subsequent_indent="  ") for n in notes]
