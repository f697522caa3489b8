"""The sweep: the truth and every technique for every light of a scene, compared.

For a scene (:mod:`hzval.scene.spec`), :func:`run` bakes the material (or reuses
the bake in ``out/bake`` when input digest and parameters match), builds the
ground truth (:mod:`hzval.truth.plane`), the unshadowed shading
(:class:`hzval.techniques.surface.Unshadowed`, the report's "normal mapping only") and
every selected technique (:mod:`hzval.techniques.registry`: by default each one that
applies to the declared effects) once, then renders each light of the sweep
with all of them. Each technique's frame is compared with the same truth
(:mod:`hzval.metrics.compare`) and its images are written under ``out/frames``;
``metrics.json`` and the HTML report (:mod:`hzval.report.pages`) close the run.
Nothing here names a technique: each one's settings, scores and files are
under its name in ``metrics.json`` (``techniques.NAME``,
``frames[i].techniques.NAME``), and the bake holds only what the chosen
techniques read (:func:`hzval.techniques.registry.bake_needs`).

Output folder::

    index.html, metrics.json, plots/      the report
    bake/                                 the bake (cache)
    frames/az<azimuth>/                   per light: truth.exr, truth_variance.exr, visibility.exr
                                          (V), truth.png, plain.png; per technique
                                          <stem>_factor.exr (F), <stem>.png, <stem>_flip.png,
                                          <stem>_visdiff.png; previews/ (PNGs above 2048 px, at
                                          most 1024 px); with --all-files also plain.exr,
                                          <stem>.exr, visibility.png, <stem>_factor.png

Frame files (:class:`writing.FrameWriter`): EXRs in half float, ZIP (2^-11 relative,
below the previews' 8-bit quantisation; the metrics are computed before, in
float32); an image whose R, G and B are equal (every one of a grey material
under a white light) as one ``Y`` channel and a grey PNG, losslessly
(:func:`hzval.io.codecs.read_rgb_exr` reads R, G, B or Y); FLIP and
visibility-difference maps as palette PNGs, pixel for pixel the RGB ones.

Speed: the truth's display values, Lab and FLIP half are computed once per
frame for every comparison (:class:`hzval.metrics.compare.Reference`); the
unshadowed render once per frame for every technique that shades with it;
previews reuse the comparison's display values; PNG previews are compressed
at zlib level 1 (:data:`PNG_LEVEL`). None of this changes a value.

Memory: a sweep's peak is estimated before anything is allocated
(:func:`estimate_peak_bytes`, :func:`check_fits`); past 2^27 samples the
truth renders in bands (:mod:`hzval.truth.plane`, "Memory") and Dr.Jit's freed
buffers are handed back every frame; a frame keeps only the 8-bit previews
and FLIP maps of its comparisons until they are written. A sweep whose
estimate is at most half of the memory available keeps the memory it frees
for its next allocations until it ends (:data:`RETAIN_BELOW_SHARE`,
:func:`hzval.core.backend.retain_freed_memory`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

from hzval.bake import maps as bake
from hzval.bake.maps import BakeParams
from hzval.core import backend, interrupts, resources, shading, srgb
from hzval.core.errors import InputError
from hzval.io import documents, staging
from hzval.metrics import compare
from hzval.metrics import facing as hzfacing
from hzval.pipeline import records, writing
from hzval.report import pages as report
from hzval.scene import camera, lookup
from hzval.scene import spec as sc
from hzval.techniques import registry as technique
from hzval.techniques import surface
from hzval.truth import plane as truth
from hzval.truth.memory import (
    RETAIN_BELOW_SHARE,
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
    (KiB on Linux, bytes on macOS), which only ever grows."""
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    import resource

    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return int(rss if sys.platform == "darwin" else rss * 1024)


def reset_peak_rss() -> None:
    """Start :func:`peak_rss_bytes` afresh from the current resident memory (Linux 4.0+: writing 5 to
    ``/proc/self/clear_refs`` resets ``VmHWM``); a no-op where that is not possible."""
    try:
        with open("/proc/self/clear_refs", "w", encoding="ascii") as f:
            f.write("5")
    except OSError:
        pass


def _machine() -> str:
    return f"{platform.system()} {platform.machine()}, {os.cpu_count()} CPUs, {platform.processor() or 'cpu'}"


def _finite(x):
    """JSON has no infinity: a perfect PSNR is written as null."""
    return None if isinstance(x, float) and not math.isfinite(x) else x


def _metrics(m: compare.FrameMetrics) -> dict:
    return {k: _finite(v) for k, v in m.as_dict().items()}


@dataclasses.dataclass
class _Setup:
    """What :func:`run` builds once before the frames."""

    material: dict
    params: BakeParams
    truth: truth.Truth
    unshadowed: surface.Unshadowed
    techniques: list  # built Technique objects, registry order
    timings: dict
    bake_contents: tuple = ()  # what was baked (hzval.bake.maps.CONTENTS)
    notices: list = dataclasses.field(default_factory=list)  # one-line warnings of the set-up
    estimate: int = 0  # estimated peak memory, bytes
    retained: bool = False  # freed memory kept (RETAIN_BELOW_SHARE, backend.retain_freed_memory)
    perfect: list = dataclasses.field(default_factory=list)  # the techniques at the truth's hits
    base_shadow: object = (
        None  # a model's no-shadows factor: its base mesh's own shadow (perpixel.BaseShadow)
    )
    view: dict = dataclasses.field(default_factory=dict)  # metrics.json's "view" (_view_errors)
    view_maps: dict = dataclasses.field(default_factory=dict)  # its per-pixel maps
    normal: np.ndarray | None = (
        None  # the top view's normal map: which pixels face the light (hzval.metrics.facing)
    )
    albedo_constant: float | None = None  # the linear albedo where it is one grey value (frames.json)
    albedo: np.ndarray | None = None  # the albedo image where it is not one value (written for engines)


@contextlib.contextmanager
def _cpu(seconds: dict, stage: str):
    """Add the process's CPU time (every thread's: Dr.Jit's workers and the writers' too) over the
    block to ``seconds[stage]``: ``metrics.json``'s ``timings.cpu_s``, beside the stages' wall time."""
    c0 = time.process_time()
    try:
        yield
    finally:
        seconds[stage] = seconds.get(stage, 0.0) + time.process_time() - c0


@contextlib.contextmanager
def _stage(clock: dict, stage: str):
    """Add the block's wall time to ``clock[stage + "_s"]`` and its CPU time to ``clock["cpu_s"][stage]``
    (:func:`_cpu`): a stage that runs in parts, such as each technique's render between comparisons."""
    t0 = time.perf_counter()
    try:
        with _cpu(clock["cpu_s"], stage):
            yield
    finally:
        clock[f"{stage}_s"] += time.perf_counter() - t0


def set_up(scene, out: Path, options: Options, report_dir: Path | None = None) -> _Setup:
    """Bake (or reuse the bake in ``out/bake``; a new one goes into ``report_dir/bake``, swapped in
    with the report), build the truth and every selected technique; timed."""
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
    retained = estimate <= RETAIN_BELOW_SHARE * resources.available_bytes() and backend.retain_freed_memory()
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
    with _cpu(cpu, "bake"):
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
    with _cpu(cpu, "truth_setup"):
        albedo = sc.load_albedo(scene.material, rows, cols)
        the_truth, points = truth_of(scene, hm.height, albedo, plan)
    timings["truth_setup_s"] = time.perf_counter() - t0
    if points is not None:  # a model: its mesh (cut, displaced, its BVH) and camera rays
        timings.update({f"truth_{k}": v for k, v in the_truth.timings.items()})
    ctx = technique.Context(scene, hm.height, baked, albedo, points=points, cache=out / "fit")
    t0 = time.perf_counter()
    with _cpu(cpu, "technique_setup"):
        plain = surface.unshadowed(ctx)
        timings["plain_setup_s"] = time.perf_counter() - t0
        built = _build_techniques(ctx, chosen, options, timings, notices)
    chosen = [type(t) for t in built]
    setup = _Setup(
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
        from hzval.techniques import perpixel

        setup.base_shadow = perpixel.BaseShadow.build(ctx)  # joins the context's factor kernel
    camera.forget_sample_positions()
    lookup.forget()
    backend.release_memory()
    return setup


def _band_record(the_truth) -> dict:
    """``metrics.json`` ``memory.truth_bands`` of a truth whose mesh was built in bands
    (:mod:`hzval.truth.bands`): pixel rows a band, bands, triangles of the largest and of them all."""
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
    """The one value of ``values`` if they are all equal, else ``None``."""
    v = np.asarray(values)
    first = float(v.flat[0]) if v.size else None
    return first if first is not None and bool(np.all(v == v.flat[0])) else None


def truth_of(scene, height: np.ndarray, albedo: np.ndarray, plan: TruthPlan | None = None):
    """``(truth, points)``: the plane's :class:`hzval.truth.plane.Truth` (the techniques read where the
    camera's rays meet their plane: ``points`` None; its mesh at once or in bands, as ``plan`` or
    :func:`truth_plan` says), or on a model (``[mesh]``) its
    :class:`hzval.truth.model.ModelTruth` and the techniques' samples at its hits, with their frames."""
    if scene.mesh.is_plane:
        if scene.mesh.tangent_bug != "none":
            raise InputError(
                scene.source or "--tangent-bug",
                "a tangent bug needs a model's frames: add --mesh (the plane's frame is the world's)",
            )
        plan = truth_plan(scene, height) if plan is None else plan
        return truth.Truth(scene, height, mesh_band_rows=plan.band_rows), None
    from hzval.geometry import model
    from hzval.truth import model as model_truth

    base = model.load(
        scene.mesh.shape, uv_scale=scene.mesh.uv_scale, up=scene.mesh.up, tangents=scene.mesh.tangents
    )
    the_truth = model_truth.ModelTruth(scene, height, base, albedo=albedo)
    return the_truth, the_truth.samples()


def _build_techniques(ctx, chosen, options: Options, timings: dict, notices: list) -> list:
    """Each chosen technique built from ``ctx`` (timed); one this machine cannot run
    (:class:`hzval.techniques.registry.Unavailable`) is skipped with its one-line notice."""
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


def _set_up_view(setup: _Setup, ctx, chosen, options: Options) -> None:
    """A view other than ``top``: every technique again at the truth's own hit points (perfect
    parallax, :attr:`_Setup.perfect`) and the view's errors (:func:`view_errors`)."""
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
    that see the surface."""
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
        backend.hand_back_freed_memory()  # what the sweep kept (RETAIN_BELOW_SHARE), for what follows
    return result


def _run(
    scene, out: Path, report_dir: Path, options: Options, command: str, progress: bool, gates=None
) -> dict:
    """:func:`run`'s work: the bake into ``out/bake``, everything else into ``report_dir``."""
    from tqdm import tqdm

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
        lights(scene),
        desc="sweep",
        unit="frame",
        disable=not progress,
        file=sys.stderr,
        leave=False,
    )
    try:
        frames = _frames(report_dir, scene, setup, scale, clock, options.all_files, bar)
    finally:
        bar.close()
    timings = {**setup.timings, "truth_s": sum(f["truth_s"] for f in frames), **clock}
    for t in setup.techniques:
        timings[f"{t.file_stem}_s"] = sum(f["techniques"][t.name]["seconds"] for f in frames)
    result = _result(scene, options, setup, timings, frames, out)
    if gates:
        gates.apply(result)  # a baseline of other settings raises here: nothing is swapped in
    t0 = time.perf_counter()
    with _cpu(clock["cpu_s"], "report"):
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


def lights(scene) -> list[tuple[float | None, float]]:
    """The sweep's lights, ``(elevation, azimuth)`` in degrees: every azimuth at each elevation of
    :meth:`hzval.scene.spec.Light.elevations` in turn; the elevation ``None`` where there is one (its
    frames keep their azimuth's name, :func:`hzval.pipeline.records.frame_folder`)."""
    light = scene.light
    several = len(light.elevations()) > 1
    return [(e if several else None, az) for e in light.elevations() for az in light.azimuths_deg]


def _frames(out: Path, scene, setup: _Setup, scale: float, clock: dict, all_files: bool, bar) -> list[dict]:
    """Every light of the sweep, as the progress bar ``bar`` (a ``tqdm`` of :func:`lights`) gives
    them: their ``metrics.json`` frames, in order, each rendered (:func:`_render`), then its techniques
    rendered and compared one by one, and written (:func:`_finish`).

    One frame at a time, every stage on all cores: the comparison and the truth are both Dr.Jit
    kernels, so overlapping them gains next to nothing and costs memory and clear stage timings."""
    frames: list[dict] = []
    for el, az in bar:
        bar.set_postfix_str(f"azimuth {az:+g} deg" + ("" if el is None else f", elevation {el:g}"))
        if el is not None:
            setup.truth.light_at(el)
        # no name holds a frame's renders past its _finish: the next frame's renders would
        # otherwise be made beside them (1.8 GB at 4096 x 4096)
        with _cpu(clock["cpu_s"], "truth_frames"):
            t_frame = setup.truth.render(az)
        # the techniques' renders as they ran (technique_frames_s): a technique's own frame time
        # (<stem>_s) includes the unshadowed shading it composes its image from, which they share
        with _stage(clock, "technique_frames"):
            rendered = _render(setup, t_frame, az, el, scale, clock)
        del t_frame
        frames.append(_finish(out, scene, setup, rendered, scale, clock, all_files))
        del rendered
    return frames


@dataclasses.dataclass
class _Rendered:
    """One light's renders: the truth, the unshadowed shading and its direct term, (a view other than
    ``top``) each technique's error at the truth's hit points, and, once :func:`_score_light` has
    rendered and compared them, each technique's frame without its image (kept only for
    ``--all-files``: the comparison has what the report shows of it)."""

    azimuth_deg: float
    elevation_deg: float | None  # None: the scene's one elevation
    truth: object
    plain: object
    direct: np.ndarray
    perfect: dict
    base: object = None  # a model's no-shadows frame: the base mesh's own shadow alone
    background: np.ndarray | None = None  # a view: the linear colour of the pixels it does not see
    techniques: list = dataclasses.field(default_factory=list)


def _render(setup: _Setup, t_frame, az: float, el: float | None, scale: float, clock: dict) -> _Rendered:
    """The renders of the light at ``(el, az)`` beside the truth's ``t_frame`` that every technique's
    comparison reads: the unshadowed shading, a model's base shadow, a view's perfect-parallax errors
    (a view's unseen pixels made the background in every image). The techniques' own frames are
    rendered one at a time as they are compared (:func:`_score_light`): holding all of them at once
    was 2 GB at 4096 x 4096 with eight techniques."""
    plain, direct = setup.unshadowed.render(az, el)
    clock["plain_s"] += plain.seconds
    base = None if setup.base_shadow is None else setup.base_shadow.render(az, elevation_deg=el)
    mask = t_frame.mask
    perfect, bg = {}, None
    if mask is not None:
        # a view: what no camera ray sees is the background in every image, and left out of the metrics
        bg = (srgb.decode(np.asarray(writing.UNSEEN_DISPLAY)) / scale).astype(np.float32)
        t_frame, plain = _unseen(t_frame, mask, bg), _unseen(plain, mask, bg)
        base = None if base is None else _unseen(base, mask, bg)
        V = t_frame.layers.get("visibility")
        for t in setup.perfect:
            F = t.render(az, elevation_deg=el).layers.get("factor")
            if V is not None and F is not None:
                perfect[t.name] = compare.visibility_metrics(V, F, mask)[0]
    return _Rendered(az, el, t_frame, plain, direct, perfect, base, bg)


def _finish(
    out: Path, scene, setup: _Setup, r: _Rendered, scale: float, clock: dict, all_files: bool
) -> dict:
    """Compare and write one light's renders; its ``metrics.json`` frame."""
    t_frame, az = r.truth, r.azimuth_deg
    folder = records.frame_folder(az, r.elevation_deg)
    # the truth's files start once its display values are made (a large image's after the
    # techniques), each technique's as soon as it is compared; the frame's end waits for them all
    # (write_s: starting the truth's and the techniques' files, and that wait)
    with writing.FrameWriter(out, folder, scale, t_frame.mask, all_files) as writer:
        compared, floor, none, rel = _score_light(setup, r, scale, clock, writer)
        with _stage(clock, "write"):
            writer.wait()
    frame = {
        "name": folder,
        "azimuth_deg": az,
        "elevation_deg": t_frame.elevation_deg,
        "truth_s": t_frame.seconds,
    }
    if hasattr(setup.truth, "macro_shadowed"):
        frame["macro_shadowed"] = setup.truth.macro_shadowed(az)  # a model: the base mesh's own shadow
    if floor is not None:
        frame["floor"] = floor
    if none is not None:
        frame["no_shadows"] = none
    per = {t.name: {**_metrics(m), "seconds": f.seconds, "files": own} for t, f, m, own in compared}
    for name, value in r.perfect.items():
        per[name]["perfect_parallax_mae"] = value
    for t in setup.techniques:
        per[t.name].update(type(t).frame_extras(per))
    _shadow_statistics(scene, setup, r, frame, per)
    if hasattr(setup.truth, "handedness"):
        _handedness_statistics(setup.truth.handedness, r, per)
    frame.update(files=rel, techniques=per)
    return frame


def _score_light(setup: _Setup, r: _Rendered, scale: float, clock: dict, writer) -> tuple:
    """One light's techniques, each rendered, compared and its files started in turn (timed as
    ``technique_frames`` and ``compare``; ``writer``: the frame's :class:`writing.FrameWriter`),
    the truth's files started before them (after them where the truth does not keep its samples,
    a large image): ``(technique, frame, metrics, its files)`` per technique,
    the perfect-shadows floor, the no-shadows baseline and the truth's files. ``r.techniques`` gets
    each technique's frame, its image dropped unless the writer writes every file
    (``--all-files``)."""
    t_frame = r.truth
    # an image too large for the truth to keep its samples: hand Dr.Jit's freed buffers back before
    # the comparison, and after each of its steps, whose buffers differ in size and would each stay
    # cached (0.2 GiB of a 4096 sweep's peak); smaller images keep them: re-faulting the pages of
    # every frame's buffers cost 1 s a frame at 2048
    release = backend.release_memory if not setup.truth.keeps else (lambda: None)
    release()
    with _stage(clock, "compare"):
        ref = compare.Reference(t_frame, scale)

    def truth_files() -> dict:
        with _stage(clock, "write"):
            return writer.truth_files(t_frame, r.plain, writing.shown(ref.display))

    # the truth's files are written while the techniques are rendered and compared; a large image's
    # are started at the end instead, as before, where the techniques' buffers are freed and the
    # encoders' own do not add to the sweep's peak
    early = truth_files() if setup.truth.keeps else None
    compared = []
    for t in setup.techniques:
        with _stage(clock, "technique_frames"):
            f = t.render(r.azimuth_deg, elevation_deg=r.elevation_deg)
            f = f if r.background is None else _unseen(f, t_frame.mask, r.background)
        release()
        with _stage(clock, "compare"):
            metrics, maps = compare.compare(t_frame, f, scale, reference=ref)
            # only what the writers need, as small as it comes: the preview's 8-bit values (an eighth
            # of the float64 display values: 400 MB a technique at 4096 x 4096) and the FLIP map
            kept = {"shown": writing.shown(maps["display"]), "flip": maps["flip"]}
        del maps
        with _stage(clock, "write"):  # starting its files (the frame's visibility map's truth half once)
            own = writer.technique_files(t.file_stem, f, kept, t_frame.layers.get("visibility"))
        del kept  # the writers hold it until its files are written
        compared.append((t, f if writer.all_files else dataclasses.replace(f, image=None), metrics, own))
        del f
    r.techniques = [(t, f) for t, f, _, _ in compared]
    release()
    V = t_frame.layers.get("visibility")
    with _stage(clock, "compare"):
        floor = _floor(ref, r.direct, setup.unshadowed.ambient_image, V)
        none = _no_shadows(ref, r.plain if r.base is None else r.base, V, t_frame.mask)
    return compared, floor, none, early if early is not None else truth_files()


def _shadow_statistics(scene, setup: _Setup, r: _Rendered, frame: dict, per: dict) -> None:
    """The truth's shadowed and attached fractions (``frame["truth"]``) and each technique's visibility
    metrics over the pixels that face the light (:mod:`hzval.metrics.facing`)."""
    V = r.truth.layers.get("visibility")
    if V is None:
        return
    facing = None
    if setup.normal is not None:
        facing = hzfacing.facing_mask(
            setup.normal,
            scene.light.direction(r.azimuth_deg, frame["elevation_deg"]),
            scene.camera.supersampling,
        )
    frame["truth"] = hzfacing.truth_statistics(V, facing, scene.spp, r.truth.mask)
    if facing is None:
        return
    for t, f in r.techniques:
        F = f.layers.get("factor")
        if F is not None:
            per[t.name].update(hzfacing.facing_metrics(V, F, facing, r.truth.mask))
    if "no_shadows" in frame:
        F = np.ones_like(V) if r.base is None else r.base.layers["factor"]
        frame["no_shadows"].update(hzfacing.facing_metrics(V, F, facing, r.truth.mask))


def _handedness_statistics(sign: np.ndarray, r: _Rendered, per: dict) -> None:
    """On a model with mirrored UVs, each technique's |F - V| over the pixels whose UVs are mirrored
    (``visibility_mae_mirrored``) and over those as drawn (``visibility_mae_unmirrored``): where a
    tangent bug of the handedness would show (:mod:`hzval.geometry.tangent_bugs`)."""
    V = r.truth.layers.get("visibility")
    if V is None or not (sign < 0).any():
        return
    for t, f in r.techniques:
        F = f.layers.get("factor")
        if F is not None:
            for key, mask in (("visibility_mae_mirrored", sign < 0), ("visibility_mae_unmirrored", sign > 0)):
                per[t.name][key] = float(compare.visibility_metrics(V, F, mask)[0]) if mask.any() else None


def _unseen(frame, mask: np.ndarray, background: np.ndarray):
    """``frame`` with ``background`` (linear) where ``mask`` is false and its layers 0 there."""
    image = np.where(mask[..., None], frame.image, background).astype(np.float32)
    layers = {k: np.where(mask, v, 0.0).astype(np.float32) for k, v in frame.layers.items()}
    return dataclasses.replace(frame, image=image, layers=layers, mask=mask)


def _floor(ref: compare.Reference, direct: np.ndarray, ambient: np.ndarray | None, V: np.ndarray | None):
    """The perfect-shadows floor of a frame: the techniques' unshadowed shading times the truth's own
    visibility, ``direct * V + ambient``, scored against the truth (``compare.IMAGE_METRICS``).

    No technique can score better than its shadows being exactly right, so
    this is the part of every image score that is not the shadows' (the
    shading's difference from the truth's, and the truth's noise); ``None``
    without ``shadow``."""
    if V is None:
        return None
    scores, _ = compare.image_metrics(ref, shading.compose(direct, V, ambient))
    return {k: _finite(v) for k, v in scores.items()}


def _no_shadows(ref: compare.Reference, none, V: np.ndarray | None, mask) -> dict | None:
    """The baseline of a frame, no technique's shadows (``F = 1``: the unshadowed shading, the
    report's normal mapping only; on a model ``F`` is the base mesh's own shadow, which every
    technique's factor holds too): its image scores and ``|F - V|``. A technique worse than it at
    some light elevation does harm there. ``none``: its frame; ``None`` without ``shadow``."""
    if V is None:
        return None
    scores, _ = compare.image_metrics(ref, none.image)
    F = none.layers.get("factor", np.ones_like(V))
    mae, leaks, false_shadows = compare.visibility_metrics(V, F, mask)
    return {k: _finite(v) for k, v in scores.items()} | {
        "visibility_mae": mae,
        "leak_fraction": leaks,
        "false_shadow_fraction": false_shadows,
    }


def _result(scene, options: Options, setup: _Setup, timings: dict, frames: list[dict], out: Path) -> dict:
    """The content of ``metrics.json`` (docs/ARCHITECTURE.md, "metrics.json"); ``out`` the folder it is
    written to."""
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
