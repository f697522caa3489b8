"""What a sweep records besides its images: ``frames.json`` (what an engine needs to render the same
frames, :func:`engine_frames`), ``metrics.json``'s view and mesh parameters, and the terminal's
table (:func:`summary_table`)."""

from __future__ import annotations

import math
from pathlib import Path

from hzval.io import files
from hzval.scene import lookup

__all__ = [
    "frame_folder",
    "engine_frames",
    "view_parameters",
    "mesh_parameters",
    "summary_table",
]


def frame_folder(azimuth_deg: float) -> str:
    """Folder name of a frame: ``az-60``, ``az+0``, ``az+7.5``."""
    return f"az{azimuth_deg:+g}"


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
    (:func:`hzval.pipeline.writing.write_albedo`)."""
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
                "name": frame_folder(f["azimuth_deg"]),
                "azimuth_deg": f["azimuth_deg"],
                "elevation_deg": f["elevation_deg"],
                "light_direction": [float(c) for c in scene.light.direction(f["azimuth_deg"])],
            }
            for f in result["frames"]
        ],
    }


def _light_radiance(light) -> dict:
    """The light's radiance: a ``hard`` light is a direction (a delta: no radiance, only its
    irradiance ``E`` on a surface facing it); a ``soft`` disk of angular radius ``rho`` whose
    facing surface receives ``E`` has ``L = E / (pi sin^2 rho)`` (docs/ARCHITECTURE.md, "Shading")."""
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
    """``frames.json``'s albedo, samples and exposure: what a frame scored against the truth must match
    besides the shadows (a one-sample shader loses 0.01-0.016 FLIP to aliasing alone; a frame pi times
    too bright, FLIP 0.68)."""
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


def view_parameters(scene) -> dict:
    """The camera's and the lookup's settings for ``metrics.json``'s parameters (none for the ``top``
    view with the default lookup, whose parameters are as they always were)."""
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
    """The mesh's settings for ``metrics.json``'s parameters (none for the plane, as before); a mesh
    file relative to ``out``, as the material's path is, so that ``score`` finds it from anywhere."""
    from hzval.geometry import model

    if scene.mesh.is_plane:
        return {}
    shape = scene.mesh.shape
    return {
        "mesh": shape if shape in model.SHAPES else files.report_path(shape, out),
        "uv_scale": scene.mesh.uv_scale,
        "up": scene.mesh.up,
        "tangent_bug": scene.mesh.tangent_bug,
    }


def summary_table(result: dict) -> str:
    """The sweep's metrics as a plain-text table for the terminal: the lead (first) technique's
    scores and time, then each other technique's |F-V|, FLIP and frame time, then the parts of each
    technique's split of the error (``split_parts``, e.g. horizon-fit's bake_loss and representation).
    The visibility columns are over the pixels that face the light where measured
    (:mod:`hzval.metrics.facing`), as the report's, and a last line says so."""
    names = list(result.get("techniques", {}))
    facing = any(
        "visibility_mae_facing" in t for f in result["frames"] for t in f.get("techniques", {}).values()
    )

    def vis(t: dict, key: str):
        return t.get(f"{key}_facing", t.get(key)) if facing else t.get(key)

    lead, others = (names[0], names[1:]) if names else (None, [])
    # on a model: |F - V| at the truth's own hits beside the camera's, so parallax is told apart
    hits = lead is not None and any(
        f.get("techniques", {}).get(lead, {}).get("perfect_parallax_mae") is not None
        for f in result["frames"]
    )
    head = ("azimuth",)
    if lead:
        head += (f"{lead} |F-V|",) + (("at hits",) if hits else ())
        head += ("leaks", "false sh.", f"{lead} FLIP", "dE2000", "PSNR dB")
    head += ("truth s",) + ((f"{lead} s",) if lead else ())
    for n in others:
        head += (f"{n} |F-V|", f"{n} FLIP", f"{n} s")
    # a technique's split of the error (Technique.split_parts), a column per part
    splits = [
        (n, p["key"])
        for n in names
        for p in result["techniques"][n].get("split_parts") or []
        if any("split" in f.get("techniques", {}).get(n, {}) for f in result["frames"])
    ]
    head += tuple(f"{n} {key}" for n, key in splits)

    def num(v, digits):
        return "-" if v is None else f"{v:.{digits}f}"

    def pct(v):
        return "-" if v is None else f"{100 * v:.2f}%"

    rows = []
    for f in result["frames"]:
        per = f.get("techniques", {})
        row = (f"{f['azimuth_deg']:+g}",)
        if lead:
            t = per.get(lead, {})
            row += (num(vis(t, "visibility_mae"), 4),) + (
                (num(t.get("perfect_parallax_mae"), 4),) if hits else ()
            )
            row += (
                pct(vis(t, "leak_fraction")),
                pct(vis(t, "false_shadow_fraction")),
                num(t.get("flip_mean"), 4),
                num(t.get("delta_e2000_mean"), 3),
                "inf" if t.get("psnr_db") is None else f"{t['psnr_db']:.2f}",
            )
        row += (num(f.get("truth_s"), 3),) + ((num(per.get(lead, {}).get("seconds"), 4),) if lead else ())
        for n in others:
            te = per.get(n, {})
            row += (num(vis(te, "visibility_mae"), 4), num(te.get("flip_mean"), 4), num(te.get("seconds"), 4))
        row += tuple(num(per.get(n, {}).get("split", {}).get(key), 4) for n, key in splits)
        rows.append(row)
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(head)]
    line = lambda cells: "  ".join(c.rjust(w) for c, w in zip(cells, widths))  # noqa: E731
    note = (
        [
            "|F-V|, leaks and false shadows over the pixels that face the light (metrics.json: *_facing; "
            "visibility_mae for the whole image)"
        ]
        if facing
        else []
    )
    if hits:
        note.append(
            "at hits: |F-V| with the technique read at the truth's own hits (no parallax); the gap to "
            "|F-V| is the flat surface's parallax, not its shadows"
        )
    return "\n".join([line(head), line(["-" * w for w in widths]), *map(line, rows), *note])
