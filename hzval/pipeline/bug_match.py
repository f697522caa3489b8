"""Which tangent-frame bug an engine's shadow factors look like (``hzval score`` on a model's sweep).

An engine's ``F`` per light (``f_az+0.exr``) is compared with hzval's horizon map rendered on the
sweep's own scene with each bug of :data:`hzval.geometry.tangent_bugs.BUGS` (the truth is not traced again
for this: only the techniques' surface and frames are needed, so the model's camera hits are built
once and each bug only changes the frames). The score of a bug is the mean ``|F_engine - F_bug|``
over the pixels the sweep saw, all lights together. The lowest wins; a bug is named ("consistent
with ignore-handedness") only when it beats the correct frames' match by :data:`MARGIN` (an engine's
own baker differs from hzval's, which moves every match alike; a bug moves the shadows themselves).

Sources: the bugs' definitions in :mod:`hzval.geometry.tangent_bugs`; the scene from ``metrics.json``'s
``parameters``, ``material`` and ``camera`` (what the sweep recorded, :func:`scene_of`).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from hzval.bake.maps import BakeParams, bake
from hzval.core.errors import InputError
from hzval.geometry import model, tangent_bugs
from hzval.io import paths
from hzval.metrics.results import SweepResult
from hzval.scene import spec as sc
from hzval.techniques import registry as technique
from hzval.truth.model import ModelTruth

__all__ = ["MARGIN", "scene_of", "bug_factors", "diagnose"]

#: A bug is named when its match is at most this share of the correct frames' match.
MARGIN = 0.67


def scene_of(metrics: dict, sweep_dir: Path):
    """Return the sweep's :class:`hzval.scene.spec.Scene` rebuilt from its ``metrics.json``, bug ``none``.

    It reads the keys a model's sweep records: material, depth, boundary, lights, camera, lookup plane, mesh.
    """
    p, m, cam = metrics["parameters"], metrics["material"], metrics["camera"]
    where = Path(sweep_dir) / "metrics.json"
    # inputs are recorded relative to the sweep's folder: found from any directory
    height = (
        str(paths.stored_input(sweep_dir, m["path"], where, "material.path")) if m.get("path") else m["name"]
    )
    mesh = p["mesh"]
    if mesh not in model.SHAPES:
        mesh = str(paths.stored_input(sweep_dir, mesh, where, "parameters.mesh"))
    scn = sc.override(
        sc.Scene(),
        height=height,
        size=int(m["cols"]),
        depth=p["depth"],
        boundary=p["boundary"],
        elevation=",".join(f"{e:g}" for e in p.get("elevations_deg") or [p["elevation_deg"]]),
        azimuths=",".join(f"{a:g}" for a in p["azimuths_deg"]),
        light=p["light"],
        light_radius=p.get("light_radius_deg"),
        effects=",".join(p["effects"]),
        spp=p["spp"],
        seed=p["seed"],
        truth_tolerance=p.get("truth_tolerance"),
        camera=p["camera"],
        view_elevation=p.get("view_elevation_deg"),
        view_azimuth=p.get("view_azimuth_deg"),
        fov=p.get("fov_deg"),
        distance=p.get("distance_tiles"),
        resolution=tuple(cam["resolution"]),
        plane=p.get("plane"),
        filter=p.get("filter"),
        parallax=p.get("parallax"),
        mesh=mesh,
        uv_scale=p.get("uv_scale"),
        up=p.get("up"),
    )
    return dataclasses.replace(scn, mesh=dataclasses.replace(scn.mesh, tangent_bug="none"))


def bug_factors(
    scene, height: np.ndarray, truth, bug: str, name: str, at: str = "camera"
) -> list[np.ndarray]:
    """Return technique ``name``'s ``F`` ``(H, W)`` per light of ``scene`` with the frames of ``bug``.

    They are computed on the model ``truth`` (:class:`hzval.truth.model.ModelTruth`) traced, at its samples
    ``at`` (``"camera"``, or ``"truth"``: perfect parallax; :meth:`ModelTruth.samples`).
    """
    truth.scene = dataclasses.replace(scene, mesh=dataclasses.replace(scene.mesh, tangent_bug=bug))
    b = bake(height, BakeParams(depth=scene.material.depth, boundary=scene.material.boundary))
    ctx = technique.Context(
        truth.scene, height, b, sc.load_albedo(scene.material, *height.shape), points=truth.samples(at=at)
    )
    tech = technique.get(name).build(ctx)
    # every light of the sweep, in its order (elevation by elevation, as the engine's frames)
    lights = [(e, az) for e in scene.light.elevations() for az in scene.light.azimuths_deg]
    return [tech.render(az, elevation_deg=e).layers["factor"] for e, az in lights]


def diagnose(metrics: dict, sweep_dir: Path, factors: list[np.ndarray]) -> dict | None:
    """Return which tangent-frame bug the engine's ``factors`` match, against the sweep's lead technique.

    The result is ``{"errors": {bug: mean |F - F_bug|}, "best", "named", "line"}``, or ``None`` where the
    sweep is not on a model. ``factors`` holds one ``(H, W)`` per light of the sweep; the lead technique is
    the sweep's first (the horizon map by default).
    """
    if "mesh" not in metrics or not (metrics.get("parameters") or {}).get("mesh"):
        return None

    scene = scene_of(metrics, sweep_dir)
    lead = SweepResult.of(metrics).chosen[0]
    hm = sc.load_material_height(scene.material)
    if hm.digest != metrics["material"].get("digest", hm.digest):
        raise InputError(
            Path(sweep_dir) / "metrics.json",
            f"material.path {hm.path}: not the height map the sweep read (its digest has changed)",
        )
    h = hm.height
    base = model.load(
        scene.mesh.shape, uv_scale=scene.mesh.uv_scale, up=scene.mesh.up, tangents=scene.mesh.tangents
    )
    mt = ModelTruth(scene, h, base)
    seen = mt.seen
    errors = {}
    for bug in tangent_bugs.NAMES:
        ours = bug_factors(scene, h, mt, bug, lead)
        errors[bug] = float(np.mean([np.abs(f - g)[seen].mean() for f, g in zip(factors, ours)]))
    best = min(errors, key=errors.get)
    named = best != "none" and errors[best] <= MARGIN * errors["none"]
    line = (
        (
            f"the engine's shadow factors are consistent with {best} (mean |F - F_bug| {errors[best]:.4f} "
            f"against {errors['none']:.4f} for the correct frames)"
        )
        if named
        else None
    )
    return {"errors": errors, "best": best, "named": bool(named), "line": line}
