"""A sweep's memory plan: its estimated peak, how the truth holds its mesh, and the refusal.

:func:`check_fits` is called before anything is allocated (and again once the map is read, with
the truth's own triangle count): a sweep that would not fit is refused in one line
(:func:`hzval.core.resources.refuse_over`). :func:`truth_plan` decides whether the truth builds its
mesh at once or in bands (:mod:`hzval.truth.bands`). The constants are fitted to peaks measured on
this machine (``python benchmarks/bench_production.py``; docs/truth-surface.md, "Cost"). The fit
(:mod:`hzval.techniques.fitted.fit`) and the commands past the sweep read the same estimate.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from hzval import materials
from hzval.bake import maps as bake
from hzval.bake.maps import BakeParams
from hzval.core import resources
from hzval.core.errors import InputError
from hzval.geometry import displace, model
from hzval.geometry import tile as mesh
from hzval.io import heightmap
from hzval.scene import spec as sc
from hzval.truth import bands as truth_bands
from hzval.truth import common as truth_common
from hzval.truth import model as model_truth
from hzval.truth import plane as truth
from hzval.truth import samples as truth_samples

__all__ = [
    "PEAK_BASE_BYTES",
    "PEAK_BYTES_PER_PIXEL",
    "PEAK_BYTES_PER_TECHNIQUE_PIXEL",
    "TECHNIQUES_BY_DEFAULT",
    "PEAK_BYTES_PER_TRIANGLE",
    "PEAK_BYTES_PER_SAMPLE",
    "PEAK_BYTES_PER_KEPT_SAMPLE",
    "PEAK_BYTES_PER_VIEW_SAMPLE",
    "TRIANGLES_PER_PIXEL_BEFORE_THE_MAP",
    "RETAIN_BELOW_SHARE",
    "PEAK_BAND_BYTES_PER_PIXEL",
    "PEAK_BYTES_PER_BAND_TRIANGLE",
    "MAX_FRAME_PIXELS",
    "TruthPlan",
    "estimate_peak_bytes",
    "band_peak_bytes",
    "truth_plan",
    "material_shape",
    "check_frame_pixels",
    "check_fits",
]


#: A sweep's peak memory: a base, a cost per pixel (images, comparisons), one per triangle of the
#: truth's mesh (its faces, vertices and Embree's BVH), one per sample for the techniques (the shared
#: uv, terrain's xy, the positions while they are set up) and one per sample the truth keeps between
#: frames (its hits: every sample up to hzval.truth.samples.KEEP_SAMPLES, one band's beyond). Fitted to the
#: peaks measured on this machine (``python benchmarks/bench_production.py``; docs/truth-surface.md, "Cost").
PEAK_BASE_BYTES = 0.3 * 2**30
PEAK_BYTES_PER_PIXEL = 115
#: What each technique adds per pixel at the peak: its frame (image and factor, float32) and what its
#: comparison keeps for the writers, held together until the frame is written. Fitted to the bricks
#: with the eight default techniques against three: 8.16 GiB against 7.35 at 2048 (41 bytes a pixel
#: each), 17.12 GiB against 11.94 at 4096 (65: its frame's comparison and files peak there,
#: ``benchmarks/memory_timeline.py``); the larger, with a margin.
PEAK_BYTES_PER_TECHNIQUE_PIXEL = 70
#: The techniques a sweep runs when none are named (``hzval.techniques.registry.defaults``; a test
#: keeps the two equal): what an estimate made before they are chosen charges.
TECHNIQUES_BY_DEFAULT = 8
#: The mesh's share of the peak, per triangle (hzval.truth.plane.mesh_triangles): the 2048 bricks' peak
#: grew by 2.0 GiB with 26M triangles more (37.5M against bd627d5's 11.5M); Embree holds about 94
#: bytes a triangle once built, 133 while it builds (hzval.geometry.tile.BYTES_PER_TRIANGLE), part
#: of which the peak, later, does not see.
PEAK_BYTES_PER_TRIANGLE = 83
#: Triangles a pixel before the map is known (:func:`estimate_peak_bytes` without ``triangles``): a
#: symmetric tessellation's fewest for a map of twisted cells (four a cell, hzval.geometry.tile.cell_levels),
#: so that the check before the map is generated refuses only what cannot fit; the sweep checks again with
#: the mesh's own count once the map is read (:func:`check_fits`).
TRIANGLES_PER_PIXEL_BEFORE_THE_MAP = 4
PEAK_BYTES_PER_SAMPLE = 24
PEAK_BYTES_PER_KEPT_SAMPLE = 52
#: What a view other than ``top`` adds per sample of a band (rays on the host, the hits).
PEAK_BYTES_PER_VIEW_SAMPLE = 64
#: A sweep whose estimated peak is at most this share of the memory available keeps what it frees
#: for its own next allocations until it ends (:func:`hzval.core.backend.retain_freed_memory`: 10-20%
#: faster at 2048 x 2048, for about 10% more peak); a larger one hands it back, as its peak needs.
RETAIN_BELOW_SHARE = 0.5


def estimate_peak_bytes(
    scene,
    rows: int,
    cols: int,
    triangles: int | None = None,
    keeps: bool | None = None,
    techniques: int = TECHNIQUES_BY_DEFAULT,
) -> int:
    """Return the peak resident memory, in bytes, a sweep of ``scene`` is expected to reach.

    The sweep is on a ``rows x cols`` map (:data:`PEAK_BYTES_PER_PIXEL` and the rest); ``triangles``: the
    truth's mesh's (:func:`hzval.truth.plane.mesh_triangles`), else :data:`TRIANGLES_PER_PIXEL_BEFORE_THE_MAP`
    a texel. ``metrics.json`` records it beside the measured peak. ``keeps``: whether the truth keeps its
    samples' camera hits (default :func:`hzval.truth.samples.keeps_samples`; a mesh in bands keeps none).
    ``techniques``: how many the sweep runs (:data:`PEAK_BYTES_PER_TECHNIQUE_PIXEL` each).
    """
    H, W = sc.image_shape(rows, cols, scene.camera)
    samples = H * W * scene.spp
    if triangles is None:
        triangles = TRIANGLES_PER_PIXEL_BEFORE_THE_MAP * rows * cols
    if truth_samples.keeps_samples(H, W, scene.spp) if keeps is None else keeps:
        kept = samples
    else:
        kept = max(b - a for a, b in truth_samples.bands(H, W, scene.spp)) * scene.spp
    view = 0
    if scene.camera.kind != "top":
        # a band's rays in float64 on the host, the truth's hits, the techniques built twice
        view = PEAK_BYTES_PER_VIEW_SAMPLE * kept + PEAK_BYTES_PER_SAMPLE * samples
    return int(
        PEAK_BASE_BYTES
        + (PEAK_BYTES_PER_PIXEL + PEAK_BYTES_PER_TECHNIQUE_PIXEL * techniques) * H * W
        + PEAK_BYTES_PER_TRIANGLE * triangles
        + PEAK_BYTES_PER_SAMPLE * samples
        + PEAK_BYTES_PER_KEPT_SAMPLE * kept
        + view
    )


#: The truth's peak while it builds its mesh in bands (:mod:`hzval.truth.bands`), before the techniques
#: are built: a base, the bake and the albedo per pixel, a band's triangles while Embree builds them
#: (their positions and faces, Embree's BVH and its build's own buffers; a band's samples come after,
#: once those are freed) and the visibility bits (one a sample a light). Fitted to the 4096 bricks
#: (docs/truth-surface.md, "Cost": 2.37 GiB before the first band, 11.57 GiB at its build's peak with
#: 75M triangles; 11.93 GiB with 79M and 16.26 GiB with one band of 111M, 134 bytes a triangle:
#: the larger, with a margin, so that a band whose build would pass the target is not chosen).
PEAK_BAND_BYTES_PER_PIXEL = 130
PEAK_BYTES_PER_BAND_TRIANGLE = 135


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
    """Return the peak of the truth's phase in bands (:data:`PEAK_BAND_BYTES_PER_PIXEL` and the rest)."""
    H, W = sc.image_shape(rows, cols, scene.camera)
    bits = H * W * scene.spp * len(scene.light.azimuths_deg) / 8
    return int(
        PEAK_BASE_BYTES
        + PEAK_BAND_BYTES_PER_PIXEL * rows * cols
        + PEAK_BYTES_PER_BAND_TRIANGLE * band_triangles
        + bits
    )


def truth_plan(scene, height: np.ndarray, techniques: int = TECHNIQUES_BY_DEFAULT) -> TruthPlan:
    """Return whether the truth builds its mesh at once or in bands, and the bands' rows.

    The truth is of ``scene`` on the normalised ``height`` map; bands are :mod:`hzval.truth.bands`. It is at
    once when the sweep's estimate with the whole mesh fits within :data:`hzval.truth.bands.PEAK_TARGET_BYTES`
    and the memory available, or where a ray could leave a band (:func:`hzval.truth.bands.why_not`); else in
    the largest bands of whole sample bands whose phase (:func:`band_peak_bytes`) stays within the rest of the
    sweep's estimate (so that the bands do not raise its peak; within that target and the memory available, if
    lower): fewer, larger bands build fewer triangles twice (their covers overlap).
    """
    rows, cols = np.shape(height)
    g, levels, h_tex = truth.mesh_grid(scene, height)
    full = mesh.triangle_count(levels)
    limit = min(resources.available_bytes(), truth_bands.PEAK_TARGET_BYTES)
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


def _model_peak_bytes(scene, rows: int, cols: int, techniques: int = TECHNIQUES_BY_DEFAULT) -> int:
    """Return the peak of a sweep on a model (:mod:`hzval.truth.model`).

    It counts the displaced mesh's triangles (:func:`hzval.geometry.displace.estimate`), every sample's kept
    hit and frame, and the images.
    """
    base = model.load(
        scene.mesh.shape, uv_scale=scene.mesh.uv_scale, up=scene.mesh.up, tangents=scene.mesh.tangents
    )
    triangles, mesh_bytes = displace.estimate(base, (rows, cols))
    H, W = sc.image_shape(rows, cols, scene.camera)
    return int(
        PEAK_BASE_BYTES
        + mesh_bytes
        + model_truth.BYTES_PER_TRIANGLE * triangles
        + model_truth.bytes_per_sample(scene) * H * W * scene.spp
        + (PEAK_BYTES_PER_PIXEL + PEAK_BYTES_PER_TECHNIQUE_PIXEL * techniques) * H * W
    )


def material_shape(scene) -> tuple[int, int]:
    """``(rows, cols)`` of the scene's height map, without generating or decoding it."""
    spec = scene.material
    if materials.is_builtin(spec.height):
        return spec.size, spec.size
    return heightmap.probe_shape(spec.height)


#: The most frame pixels (lights x the image's pixels) a sweep renders: 2^31, e.g. 128 lights at
#: 4096 x 4096 or the 361 lights of MAX_LIGHTS at 2400 x 2400. A frame's files take about 17 bytes a
#: pixel (72 MB at 2048 x 2048) and its renders about 0.5 us a pixel here: 2^31 is 36 GB of files and
#: a quarter of an hour to hours of rendering, the most a report is worth waiting for.
MAX_FRAME_PIXELS = 2**31


def check_frame_pixels(scene, rows: int, cols: int) -> int:
    """Return a sweep's frame pixels, lights times pixels, if at most :data:`MAX_FRAME_PIXELS`.

    The sweep is of ``scene`` on a ``rows x cols`` map; its lights are azimuths times elevations. Otherwise
    the error is one line naming ``--azimuths`` (``--elevation`` over several elevations).
    """
    H, W = sc.image_shape(rows, cols, scene.camera)
    lights = len(scene.light.azimuths_deg) * len(scene.light.elevations())
    n = lights * H * W
    if n > MAX_FRAME_PIXELS:
        several = len(scene.light.elevations()) > 1
        raise InputError(
            "--elevation" if several else "--azimuths",
            f"{lights} lights of {W}x{H} pixels are {n:.3g} "
            f"frame pixels; at most {MAX_FRAME_PIXELS:.3g} (fewer lights or a "
            "smaller image)",
        )
    return n


def check_fits(
    scene,
    params: BakeParams,
    height: np.ndarray | None = None,
    plan: TruthPlan | None = None,
    techniques: int = TECHNIQUES_BY_DEFAULT,
) -> int:
    """Refuse a sweep that would not fit, before anything is allocated; return the estimate.

    A sweep is refused when it has more than :data:`MAX_FRAME_PIXELS`, or when its bake or its estimated peak
    (:func:`estimate_peak_bytes`) would not fit in the memory available now. ``height``: the normalised map,
    once read: the estimate then counts the truth's own triangles (:func:`hzval.truth.plane.mesh_triangles`),
    and a refusal names ``--truth-tolerance`` as well. ``plan``: the truth's (:func:`truth_plan`, made here if
    not given): a mesh in bands is charged by its largest band, at the larger of the bands' phase and the rest
    of the sweep. ``techniques``: how many the sweep runs.
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
