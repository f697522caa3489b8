"""The sweep: the truth and every technique for every light of a scene, compared.

The design in full: docs/internals.md, "hzval.pipeline.sweep".
"""

from __future__ import annotations

import dataclasses
import os
import platform
import resource
import sys
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from hzval.bake import maps as bake
from hzval.bake.maps import BakeParams
from hzval.core import backend, budget, interrupts, resources, shading
from hzval.core.errors import InputError
from hzval.geometry import model
from hzval.io import documents, staging
from hzval.metrics import facing as hzfacing
from hzval.metrics.results import FrameRecord
from hzval.pipeline import records, renders, writing
from hzval.report import pages as report
from hzval.scene import camera as hz_camera
from hzval.scene import lookup
from hzval.scene import spec as sc
from hzval.techniques import perpixel, surface
from hzval.techniques import registry as technique
from hzval.truth import model as model_truth
from hzval.truth import plane as truth
from hzval.truth.memory import (
    TruthPlan,
    check_fits,
    truth_plan,
)

__all__ = [
    "SCHEMA_VERSION",
    "Options",
    "peak_rss_bytes",
    "reset_peak_rss",
    "set_up",
    "truth_of",
    "view_errors",
    "run",
]
_BAKE_DEFAULTS = BakeParams()
#: The layout of ``metrics.json`` (docs/ARCHITECTURE.md, "metrics.json"). 2: every technique's
#: settings under ``techniques.NAME`` and its scores and files under ``frames[i].techniques.NAME``;
#: 1 (no ``schema_version``) had the horizon map's at the top level too.
SCHEMA_VERSION = 2


@dataclasses.dataclass(frozen=True)
class Options:
    """What the scene does not hold: the bake's settings, and which techniques with which settings.

    The bake's defaults are :class:`hzval.bake.maps.BakeParams`'s. ``techniques``:
    registry names (:data:`hzval.techniques.registry.REGISTRY`), or ``None`` for
    every technique that applies to the scene's effects; ``exclude`` leaves
    some out; ``settings``: per technique name, the keywords of its
    ``build`` (e.g. ``{"horizon": {"k": 4.0}, "pom": {"steps": 64}}``);
    ``all_files``: write a frame's derived files too (:class:`writing.FrameWriter`).
    """

    radius: int = _BAKE_DEFAULTS.radius
    angles: int = _BAKE_DEFAULTS.angles
    method: str = _BAKE_DEFAULTS.method  # horizon bake method: "seed" or "exact"
    directions: int = _BAKE_DEFAULTS.directions
    ssbump_lift: float = _BAKE_DEFAULTS.ssbump_lift
    techniques: tuple[str, ...] | None = None
    exclude: tuple[str, ...] = ()
    settings: dict = dataclasses.field(default_factory=dict)
    all_files: bool = False  # also the frame files that the others determine (writing.FrameWriter)

    def bake_params(self, scene) -> BakeParams:
        """Return the bake's parameters for ``scene`` under these options."""
        return BakeParams(
            depth=scene.material.depth,
            radius=self.radius,
            angles=self.angles,
            boundary=scene.material.boundary,
            method=self.method,
            directions=self.directions,
            ssbump_lift=self.ssbump_lift,
        ).validate()


def peak_rss_bytes() -> int:
    """Peak resident memory of this process since :func:`reset_peak_rss` (or its start), in bytes.

    Linux: ``VmHWM`` of ``/proc/self/status``, which :func:`reset_peak_rss` can reset, so that a
    second sweep in one process (``hzval suite``) reports its own peak; elsewhere ``ru_maxrss``
    (KiB on Linux, bytes on macOS), which only ever grows.
    """
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass

    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return int(rss if sys.platform == "darwin" else rss * 1024)


def reset_peak_rss() -> None:
    """Start :func:`peak_rss_bytes` afresh from the current resident memory.

    On Linux 4.0+, writing 5 to ``/proc/self/clear_refs`` resets ``VmHWM``; this is a no-op where that is not
    possible.
    """
    try:
        with open("/proc/self/clear_refs", "w", encoding="ascii") as f:
            f.write("5")
    except OSError:
        pass


def _machine() -> str:
    return f"{platform.system()} {platform.machine()}, {os.cpu_count()} CPUs, {platform.processor() or 'cpu'}"


def set_up(scene, out: Path, options: Options, report_dir: Path | None = None) -> renders.Setup:
    """Bake, then build the truth and every selected technique, timed.

    The bake in ``out/bake`` is reused where there is one; a new one goes into ``report_dir/bake``, swapped in
    with the report.
    """
    backend.variant()
    chosen = technique.select(
        list(options.techniques) if options.techniques is not None else None, scene, exclude=options.exclude
    )
    params = options.bake_params(scene)
    for t in chosen:  # settings are checked before anything is written
        t.check_settings(params, options.settings.get(t.name, {}))
    check_fits(scene, params, techniques=len(chosen))  # before the map is generated or decoded
    hm = sc.load_material_height(scene.material)
    plan = truth_plan(scene, hm.height, len(chosen)) if scene.mesh.is_plane else None
    # the truth's own triangles, before they are made
    estimate = check_fits(scene, params, hm.height, plan, techniques=len(chosen))
    # from here on: the frames then reuse what the set-up frees, besides what they free themselves
    retained = (
        estimate <= budget.RETAIN_BELOW_SHARE * resources.available_bytes() and backend.retain_freed_memory()
    )
    rows, cols = hm.height.shape
    material = {
        "name": scene.name,
        "source": hm.source,
        "digest": hm.digest,
        "rows": rows,
        "cols": cols,
        "path": staging.report_path(hm.path, out),
    }
    t0 = time.perf_counter()
    cpu: dict[str, float] = {}
    notices: list[str] = []
    if hm.colour:  # said on the terminal, not only in metrics.json: the user may not expect it
        notices.append(f"{hm.path}: a colour image, read as heights by its {hm.source.split('-> ')[-1]}")
    needs = technique.bake_needs(chosen, scene)
    horizon = bake.needs_horizon(needs)
    record = {
        **material,
        "path": staging.report_path(hm.path, out / "bake"),
    }  # relative to bake.json's folder
    with renders.cpu_time(cpu, "bake"):
        baked, cached = bake.cached_bake(
            hm.height,
            hm.digest,
            params,
            out / "bake",
            record,
            notices,
            horizon=horizon,
            occlusion=bake.needs_occlusion(needs),
            write_to=None if report_dir is None else report_dir / "bake",
        )
    timings = {"bake_s": time.perf_counter() - t0, "bake_cached": cached, "cpu_s": cpu}
    t0 = time.perf_counter()
    with renders.cpu_time(cpu, "truth_setup"):
        albedo = sc.load_albedo(scene.material, rows, cols)
        the_truth, points = truth_of(scene, hm.height, albedo, plan)
    timings["truth_setup_s"] = time.perf_counter() - t0
    if points is not None:  # a model: its mesh (cut, displaced, its BVH) and camera rays
        timings.update({f"truth_{k}": v for k, v in the_truth.timings.items()})
    ctx = technique.Context(scene, hm.height, baked, albedo, points=points, cache=out / "fit")
    t0 = time.perf_counter()
    with renders.cpu_time(cpu, "technique_setup"):
        plain = surface.unshadowed(ctx)
        timings["plain_setup_s"] = time.perf_counter() - t0
        built = _build_techniques(ctx, chosen, options, timings, notices)
    chosen = [type(t) for t in built]
    setup = renders.Setup(
        material,
        params,
        the_truth,
        plain,
        built,
        timings,
        baked.contents,
        notices,
        estimate,
        retained=retained,
        normal=baked.normal if scene.camera.kind == "top" else None,
        albedo_constant=_constant(ctx.albedo),
        albedo=None if _constant(ctx.albedo) is not None else ctx.albedo,
    )
    if the_truth.hits is not None:
        t0 = time.perf_counter()
        _set_up_view(setup, ctx, chosen, options)
        timings["view_setup_s"] = time.perf_counter() - t0
    elif points is not None:
        # a model: every technique again at the truth's own hits (perfect parallax), as for a view
        perfect_ctx = dataclasses.replace(ctx, points=the_truth.samples("truth"), _shared={})
        setup.perfect = [t.build(perfect_ctx, **options.settings.get(t.name, {})) for t in chosen]
    if points is not None and scene.declares("shadow"):
        setup.base_shadow = perpixel.BaseShadow.build(ctx)  # joins the context's factor kernel
    hz_camera.forget_sample_positions()
    lookup.forget()
    backend.release_memory()
    return setup


def _band_record(the_truth) -> dict:
    """Return ``metrics.json``'s ``memory.truth_bands`` of a truth whose mesh was built in bands.

    The bands are :mod:`hzval.truth.bands`'s. The record holds the pixel rows a band, the bands, and the
    triangles of the largest and of them all.
    """
    if getattr(the_truth, "mesh_bands", None) is None:
        return {}
    return {
        "truth_bands": {
            "band_rows": the_truth.mesh_band_rows,
            "bands": len(the_truth.mesh_bands),
            "largest_triangles": getattr(the_truth, "band_triangles_largest", None),
            "triangles_built": getattr(the_truth, "band_triangles_built", None),
        }
    }


def _constant(values: np.ndarray) -> float | None:
    """Return the one value of ``values`` if they are all equal, else ``None``."""
    v = np.asarray(values)
    first = float(v.flat[0]) if v.size else None
    return first if first is not None and bool(np.all(v == v.flat[0])) else None


def truth_of(scene, height: np.ndarray, albedo: np.ndarray, plan: TruthPlan | None = None):
    """Return the truth and the techniques' sample points, on the plane or on a model.

    The result is ``(truth, points)``. On the plane it is the plane's :class:`hzval.truth.plane.Truth` (the
    techniques read where the camera's rays meet their plane: ``points`` None; its mesh at once or in bands,
    as ``plan`` or :func:`truth_plan` says). On a model (``[mesh]``) it is its
    :class:`hzval.truth.model.ModelTruth` and the techniques' samples at its hits, with their frames.
    """
    if scene.mesh.is_plane:
        if scene.mesh.tangent_bug != "none":
            raise InputError(
                scene.source or "--tangent-bug",
                "a tangent bug needs a model's frames: add --mesh (the plane's frame is the world's)",
            )
        plan = truth_plan(scene, height) if plan is None else plan
        return truth.Truth(scene, height, mesh_band_rows=plan.band_rows), None

    base = model.load(
        scene.mesh.shape, uv_scale=scene.mesh.uv_scale, up=scene.mesh.up, tangents=scene.mesh.tangents
    )
    the_truth = model_truth.ModelTruth(scene, height, base, albedo=albedo)
    return the_truth, the_truth.samples()


def _build_techniques(ctx, chosen, options: Options, timings: dict, notices: list) -> list:
    """Build each chosen technique from ``ctx``, timed.

    One this machine cannot run (:class:`hzval.techniques.registry.Unavailable`) is skipped with its one-line
    notice.
    """
    built, sat_out = [], []
    on_model = ctx.points is not None and ctx.points.frames is not None
    for t in chosen:
        if on_model and t.not_on_models:
            if options.techniques is not None and t.name in options.techniques:  # asked for by name
                notices.append(f"{t.name}: not on a model: {t.not_on_models}")
            else:
                sat_out.append(t.name)
            continue
        t0 = time.perf_counter()
        try:
            built.append(t.build(ctx, **options.settings.get(t.name, {})))
        except technique.Unavailable as e:
            notices.append(str(e))  # metrics.json's warnings; the command line prints them
            continue
        timings[f"{t.file_stem}_setup_s"] = time.perf_counter() - t0
    if sat_out:  # defaults the user never asked for: one line, not a warning each
        notices.append(f"on a model, the default {', '.join(sat_out)} sit{'s' * (len(sat_out) == 1)} out")
    if not built:
        why = "; ".join(notices[-len(chosen) :]) if chosen and notices else "every one was left out"
        raise InputError("--techniques", f"no technique is left to score: {why}")
    return built


def _set_up_view(setup: renders.Setup, ctx, chosen, options: Options) -> None:
    """Set up a view other than ``top``: perfect-parallax techniques and the view's errors.

    Every technique is set up again at the truth's own hit points (perfect parallax,
    :attr:`hzval.pipeline.renders.Setup.perfect`), and the view's errors are :func:`view_errors`'s.
    """
    hits = setup.truth.hits
    own = ctx.samples()
    at_truth = lookup.from_points(hits[0], hits[1], own)
    perfect_ctx = technique.Context(
        ctx.scene, ctx.height, ctx.bake, ctx.albedo, points=at_truth, cache=ctx.cache
    )
    setup.perfect = [t.build(perfect_ctx, **options.settings.get(t.name, {})) for t in chosen]
    setup.view, setup.view_maps = view_errors(setup.truth, own)


def view_errors(the_truth, samples: lookup.Samples) -> tuple[dict, dict]:
    """``(record, maps)``: where the techniques' lookups land against what the truth sees.

    ``parallax_error``: per pixel, the mean distance in texels (``wrap``: the shortest, across
    tiles) between the point a technique shades and the truth's hit point of the same sample;
    ``footprint``: per pixel, ``max(|dP/dcol|, |dP/drow|)`` on the technique's plane, the texels
    a pixel covers (OpenGL's ``rho``). The record has their means and quantiles over the pixels
    that see the surface.
    """
    rows, cols, spp = samples.rows, samples.cols, samples.spp
    hx, hy = the_truth.hits
    dx = samples.x.astype(np.float64) - hx
    dy = samples.y.astype(np.float64) - hy
    if the_truth.scene.material.boundary == "wrap":
        dx, dy = (dx + cols / 2) % cols - cols / 2, (dy + rows / 2) % rows - rows / 2
    seen = the_truth.seen_samples.reshape(-1, spp)
    dist = np.where(seen, np.hypot(dx, dy).reshape(-1, spp), 0.0)
    per_pixel = (dist.sum(axis=1) / np.maximum(seen.sum(axis=1), 1)).reshape(the_truth.shape)
    mask = the_truth.seen
    maps = {"parallax_error": per_pixel.astype(np.float32)}
    record = {"seen_fraction": float(mask.mean()), "parallax_error_texels": _spread(per_pixel[mask])}
    fp = samples.footprint if samples.footprint is not None else the_truth.view.footprints(samples.plane_z)
    rho = np.maximum(np.hypot(fp[:, 0], fp[:, 1]), np.hypot(fp[:, 2], fp[:, 3])).reshape(the_truth.shape)
    maps["footprint"] = rho.astype(np.float32)
    record["footprint_texels"] = _spread(rho[mask & np.isfinite(rho)])
    record["plane_z"] = float(samples.plane_z)
    return record, maps


def _spread(values: np.ndarray) -> dict:
    """Mean and quantiles of ``values`` (empty: nulls)."""
    if values.size == 0:
        return {"mean": None, "p50": None, "p95": None, "max": None}
    q = np.quantile(values, [0.5, 0.95])
    return {"mean": float(values.mean()), "p50": float(q[0]), "p95": float(q[1]), "max": float(values.max())}


def run(
    scene,
    out: str | Path,
    *,
    options: Options = Options(),
    command: str = "",
    progress: bool = True,
    force: bool = False,
    gates=None,
) -> dict:
    """Run the sweep of ``scene`` into ``out``; return the ``metrics.json`` content.

    All or nothing: the report (frames, plots, ``index.html``, ``metrics.json``,
    ``frames.json``) is written into a staging folder inside ``out`` and swapped
    in whole at the end, so an error, Ctrl-C or SIGTERM leaves ``out`` as it was,
    its bake included (a new bake is staged too), and a new ``out`` not at all.
    ``out`` must be new, empty or hzval's (:func:`hzval.io.staging.output_folder`;
    ``force`` writes beside other files, which are kept); the run holds it: a
    second run into it fails at once. Signals are held from the swap on
    (:func:`hzval.core.interrupts.held`). ``gates`` (:class:`hzval.commands.gates.Gates`): tested on
    the result before the report is written, which lists their failures first (``metrics.json``'s ``gates``).
    """
    out = Path(out)
    reset_peak_rss()  # this sweep's own peak, even after others in this process
    try:
        with interrupts.held() as hold, staging.output_folder(out, force=force):
            with staging.Staging(out) as stage:
                with interrupts.unwrapped():  # a stop inside Dr.Jit's tracing unwinds as a stop
                    result = _run(scene, out, stage.dir, options, command, progress, gates)
                hold.start()  # the last signal check: from here the run completes
                stage.swap()
    finally:
        backend.hand_back_freed_memory()  # what the sweep kept (budget.RETAIN_BELOW_SHARE), for what follows
    return result


def _run(
    scene, out: Path, report_dir: Path, options: Options, command: str, progress: bool, gates=None
) -> dict:
    """:func:`run`'s work: the bake into ``out/bake``, everything else into ``report_dir``."""
    t_start = time.perf_counter()
    setup = set_up(scene, out, options, report_dir)
    if setup.view_maps:
        setup.view["files"] = writing.write_view_maps(report_dir, setup.view_maps, setup.truth.seen)
    scale = shading.exposure(scene)
    clock = {
        "compare_s": 0.0,
        "write_s": 0.0,
        "plain_s": 0.0,
        "technique_frames_s": 0.0,
        "cpu_s": setup.timings["cpu_s"],
    }
    bar = tqdm(
        renders.lights(scene),
        desc="sweep",
        unit="frame",
        disable=not progress,
        file=sys.stderr,
        leave=False,
    )
    try:
        frames = renders.render_frames(report_dir, scene, setup, scale, clock, options.all_files, bar)
    finally:
        bar.close()
    timings = {**setup.timings, "truth_s": sum(f["truth_s"] for f in frames), **clock}
    for t in setup.techniques:
        timings[f"{t.file_stem}_s"] = sum(FrameRecord(f).techniques[t.name]["seconds"] for f in frames)
    result = _result(scene, options, setup, timings, frames, out)
    if gates:
        gates.apply(result)  # a baseline of other settings raises here: nothing is swapped in
    t0 = time.perf_counter()
    with renders.cpu_time(clock["cpu_s"], "report"):
        albedo_files = None if setup.albedo is None else writing.write_albedo(report_dir, setup.albedo)
        plot_files = report.write_plots(report_dir, result)
    result["memory"] = {
        "peak_rss_bytes": peak_rss_bytes(),
        "estimate_bytes": setup.estimate,
        "retains_freed": setup.retained,
        **_band_record(setup.truth),
    }
    # the clock stops before the page, which shows it (the page and the JSON take milliseconds): the
    # report's total time and the terminal's are the same
    timings["report_s"] = time.perf_counter() - t0
    timings["total_s"] = time.perf_counter() - t_start
    report.write_page(report_dir, result, plot_files, command=command)
    frames = records.engine_frames(scene, result, setup.albedo_constant, albedo_files)
    documents.write_json(report_dir / "frames.json", frames)
    documents.write_json(report_dir / "metrics.json", result)
    return result


def _result(
    scene, options: Options, setup: renders.Setup, timings: dict, frames: list[dict], out: Path
) -> dict:
    """Return the content of ``metrics.json`` (docs/ARCHITECTURE.md, "metrics.json").

    ``out`` is the folder it is written to.
    """
    techniques = {
        t.name: {
            "label": t.label,
            "summary": t.summary,
            "file_stem": t.file_stem,
            "parameters": t.parameters,
            "simulated": list(t.simulated),
            "texture_bytes_per_texel": t.storage_bytes() / (setup.material["rows"] * setup.material["cols"]),
            **(
                {"split_parts": [{"key": k, "label": lb} for k, lb in t.split_parts]} if t.split_parts else {}
            ),
            **({"fit_of": t.fit_of} if t.fit_of else {}),
        }
        for t in setup.techniques
    }
    simulated = {"truth": list(setup.truth.simulated), **{n: v["simulated"] for n, v in techniques.items()}}
    return {
        "schema_version": SCHEMA_VERSION,
        "material": setup.material,
        "parameters": records.scene_parameters(scene, out, [t.name for t in setup.techniques]),
        "bake": {"contents": list(setup.bake_contents)},
        "versions": {**backend.versions(), "python": platform.python_version(), "machine": _machine()},
        "camera": setup.truth.view.record(),
        **({"mesh": setup.truth.record()} if hasattr(setup.truth, "model") else {}),
        **({"view": setup.view} if setup.view else {}),
        "exposure": {
            "scale": shading.exposure(scene),
            "max_radiance": shading.max_radiance(scene),
            "note": "display = clip(scale * radiance); the largest radiance the declared effects "
            "can produce shows as 1",
        },
        "timings": timings,
        "simulated": simulated,
        "techniques": techniques,
        **{k: v for t in setup.techniques for k, v in t.extras.items()},
        "warnings": setup.notices
        + [w for t in setup.techniques for w in t.warnings]
        + [w for w in (hzfacing.few_shadows_warning(frames),) if w],
        "frames": frames,
    }
