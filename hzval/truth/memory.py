"""A sweep's memory plan: its estimated peak, how the truth holds its mesh, and the refusal.

:func:`check_fits` is called before anything is allocated (and again once the map is read, with
the truth's own triangle count): a sweep that would not fit is refused in one line
(:func:`hzval.core.resources.refuse_over`). :func:`truth_plan` decides whether the truth builds its
mesh at once or in bands (:mod:`hzval.truth.bands`). The figures and formulas are
:mod:`hzval.core.budget`'s; this module applies them to a scene. The fit
(:mod:`hzval.techniques.fitted.fit`) and the commands past the sweep read the same estimate.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from hzval import materials
from hzval.bake import maps as bake
from hzval.bake.maps import BakeParams
from hzval.core import budget, resources
from hzval.core.errors import InputError
from hzval.geometry import displace, model
from hzval.geometry import tile as mesh
from hzval.io import heightmap
from hzval.scene import spec as sc
from hzval.truth import bands as truth_bands
from hzval.truth import common as truth_common
from hzval.truth import plane as truth
from hzval.truth import samples as truth_samples

__all__ = [
    "TruthPlan",
    "estimate_peak_bytes",
    "band_peak_bytes",
    "truth_plan",
    "material_shape",
    "check_frame_pixels",
    "check_fits",
]


def estimate_peak_bytes(
    scene,
    rows: int,
    cols: int,
    triangles: int | None = None,
    keeps: bool | None = None,
    techniques: int = budget.TECHNIQUES_BY_DEFAULT,
) -> int:
    """Return the peak resident memory, in bytes, a sweep of ``scene`` is expected to reach.

    The sweep is on a ``rows x cols`` map; the bytes are :func:`hzval.core.budget.sweep_peak_bytes`'s.
    ``triangles``: the truth's mesh's (:func:`hzval.truth.plane.mesh_triangles`), else
    :data:`hzval.core.budget.TRIANGLES_PER_PIXEL_BEFORE_THE_MAP` a texel. ``metrics.json`` records it beside
    the measured peak. ``keeps``: whether the truth keeps its samples' camera hits (default
    :func:`hzval.truth.samples.keeps_samples`; a mesh in bands keeps none). ``techniques``: how many the sweep
    runs (:data:`hzval.core.budget.PEAK_BYTES_PER_TECHNIQUE_PIXEL` each).
    """
    H, W = sc.image_shape(rows, cols, scene.camera)
    samples = H * W * scene.spp
    if triangles is None:
        triangles = budget.TRIANGLES_PER_PIXEL_BEFORE_THE_MAP * rows * cols
    if truth_samples.keeps_samples(H, W, scene.spp) if keeps is None else keeps:
        kept = samples
    else:
        kept = max(b - a for a, b in truth_samples.bands(H, W, scene.spp)) * scene.spp
    view = scene.camera.kind != "top"
    return budget.sweep_peak_bytes(H * W, samples, kept, triangles, techniques, view)


@dataclasses.dataclass(frozen=True)
class TruthPlan:
    """How the truth of a sweep holds its mesh (:func:`truth_plan`).

    ``triangles`` is the whole mesh's; ``band_rows`` (pixel rows a band) and ``band_triangles`` (the largest
    band's) where it is built in bands, else ``None`` and 0; ``why_single``: why it cannot be built in bands
    (``None`` where it can).
    """

    triangles: int
    band_rows: int | None = None
    band_triangles: int = 0
    why_single: str | None = None


def band_peak_bytes(scene, rows: int, cols: int, band_triangles: int) -> int:
    """Return the peak of the truth's phase in bands (:func:`hzval.core.budget.band_peak_bytes`)."""
    H, W = sc.image_shape(rows, cols, scene.camera)
    bits = H * W * scene.spp * len(scene.light.azimuths_deg) / 8
    return budget.band_peak_bytes(rows * cols, band_triangles, bits)


def truth_plan(scene, height: np.ndarray, techniques: int = budget.TECHNIQUES_BY_DEFAULT) -> TruthPlan:
    """Return whether the truth builds its mesh at once or in bands, and the bands' rows.

    The truth is of ``scene`` on the normalised ``height`` map; bands are :mod:`hzval.truth.bands`. It is at
    once when the sweep's estimate with the whole mesh fits within :data:`hzval.core.budget.PEAK_TARGET_BYTES`
    and the memory available, or where a ray could leave a band (:func:`hzval.truth.bands.why_not`); else in
    the largest bands of whole sample bands whose phase (:func:`band_peak_bytes`) stays within the rest of the
    sweep's estimate (so that the bands do not raise its peak; within that target and the memory available, if
    lower): fewer, larger bands build fewer triangles twice (their covers overlap).
    """
    rows, cols = np.shape(height)
    g, levels, h_tex = truth.mesh_grid(scene, height)
    full = mesh.triangle_count(levels)
    limit = min(resources.available_bytes(), budget.PEAK_TARGET_BYTES)
    why = truth_bands.why_not(scene)
    if why is not None or estimate_peak_bytes(scene, rows, cols, full, techniques=techniques) <= limit:
        return TruthPlan(full, why_single=why)
    H, W = sc.image_shape(rows, cols, scene.camera)
    bands = truth_samples.bands(H, W, scene.spp)
    step = bands[0][1] // W - bands[0][0] // W
    z_min, z_max = float(h_tex.min()), float(h_tex.max())
    up, down = truth_bands.reach(
        scene, z_max - z_min, truth_common.lift_for(z_min, z_max), scene.light.azimuths_deg
    )
    wrap = scene.material.boundary == "wrap"
    room = min(limit, estimate_peak_bytes(scene, rows, cols, 0, keeps=False, techniques=techniques))
    best = None
    for band_rows in range(H - H % step if H > step else step, 0, -step):
        most = max(truth_bands.band_triangles(g, levels, rows, H, W, bands, band_rows, up, down, wrap))
        best = (band_rows, most)
        if band_peak_bytes(scene, rows, cols, most) <= room:
            break
    return TruthPlan(full, band_rows=best[0], band_triangles=best[1])


def _model_peak_bytes(scene, rows: int, cols: int, techniques: int = budget.TECHNIQUES_BY_DEFAULT) -> int:
    """Return the peak of a sweep on a model (:mod:`hzval.truth.model`).

    It counts the displaced mesh's triangles (:func:`hzval.geometry.displace.estimate`), every sample's kept
    hit and frame, and the images.
    """
    base = model.load(
        scene.mesh.shape, uv_scale=scene.mesh.uv_scale, up=scene.mesh.up, tangents=scene.mesh.tangents
    )
    triangles, refined = displace.estimate(base, (rows, cols))
    H, W = sc.image_shape(rows, cols, scene.camera)
    reflection = scene.declares("reflection_occlusion")
    return budget.model_sweep_peak_bytes(refined, triangles, H * W * scene.spp, reflection, H * W, techniques)


def material_shape(scene) -> tuple[int, int]:
    """``(rows, cols)`` of the scene's height map, without generating or decoding it."""
    spec = scene.material
    if materials.is_builtin(spec.height):
        return spec.size, spec.size
    return heightmap.probe_shape(spec.height)


def check_frame_pixels(scene, rows: int, cols: int) -> int:
    """Return a sweep's frame pixels (lights times pixels) if within their bound.

    The bound is :data:`hzval.core.budget.MAX_FRAME_PIXELS`. The sweep is of ``scene`` on a ``rows x cols``
    map; its lights are azimuths times elevations. Otherwise the error is one line naming ``--azimuths``
    (``--elevation`` over several elevations).
    """
    H, W = sc.image_shape(rows, cols, scene.camera)
    lights = len(scene.light.azimuths_deg) * len(scene.light.elevations())
    n = lights * H * W
    if n > budget.MAX_FRAME_PIXELS:
        several = len(scene.light.elevations()) > 1
        raise InputError(
            "--elevation" if several else "--azimuths",
            f"{lights} lights of {W}x{H} pixels are {n:.3g} "
            f"frame pixels; at most {budget.MAX_FRAME_PIXELS:.3g} (fewer lights or a "
            "smaller image)",
        )
    return n


def check_fits(
    scene,
    params: BakeParams,
    height: np.ndarray | None = None,
    plan: TruthPlan | None = None,
    techniques: int = budget.TECHNIQUES_BY_DEFAULT,
) -> int:
    """Refuse a sweep that would not fit, before anything is allocated; return the estimate.

    A sweep is refused when it has more than :data:`hzval.core.budget.MAX_FRAME_PIXELS`, or when its bake or
    its estimated peak (:func:`estimate_peak_bytes`) would not fit in the memory available now. ``height``:
    the normalised map, once read: the estimate then counts the truth's own triangles
    (:func:`hzval.truth.plane.mesh_triangles`), and a refusal names ``--truth-tolerance`` as well. ``plan``:
    the truth's (:func:`truth_plan`, made here if not given): a mesh in bands is charged by its largest band,
    at the larger of the bands' phase and the rest of the sweep. ``techniques``: how many the sweep runs.
    """
    rows, cols = material_shape(scene) if height is None else np.shape(height)
    what = "--size" if materials.is_builtin(scene.material.height) else scene.material.height
    bake.check_fits(what, rows, cols, params)
    triangles = None
    if not scene.mesh.is_plane:
        need = _model_peak_bytes(scene, rows, cols, techniques)  # the model's truth counts its rings
    else:
        if height is not None and plan is None:
            plan = truth_plan(scene, height, techniques)
        triangles = None if plan is None else plan.triangles
        need = estimate_peak_bytes(scene, rows, cols, triangles, techniques=techniques)
        if plan is None and truth_bands.why_not(scene) is None:
            # before the map is read: its mesh may be built in bands, so only the rest of the sweep
            # is sure to be needed (this check refuses only what cannot fit; the next one knows)
            need = estimate_peak_bytes(scene, rows, cols, 0, keeps=False, techniques=techniques)
        if plan is not None and plan.band_rows is not None:
            need = max(
                estimate_peak_bytes(scene, rows, cols, 0, keeps=False, techniques=techniques),
                band_peak_bytes(scene, rows, cols, plan.band_triangles),
            )
    mesh = ""
    if triangles is not None:
        mesh = (
            f" with the truth's {triangles / 1e6:.0f}M triangles at "
            f"--truth-tolerance {scene.material.truth_tolerance:g}"
        )
    if plan is not None and plan.band_rows is not None:
        mesh += f" (built in bands of {plan.band_rows} rows, {plan.band_triangles / 1e6:.0f}M triangles)"
    elif plan is not None and plan.why_single is not None:
        mesh += f" (at once, not in bands: {plan.why_single})"
    resources.refuse_over(
        what,
        need,
        f"a sweep of {cols}x{rows} texels at {scene.spp} spp{mesh}",
        f"fewer --spp, a smaller map{'' if triangles is None else ', a larger --truth-tolerance'} "
        "or a larger machine",
    )
    check_frame_pixels(scene, rows, cols)
    return need
