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

Frame files (:func:`_write_frame`): EXRs in half float, ZIP (2^-11 relative,
below the previews' 8-bit quantisation; the metrics are computed before, in
float32); an image whose R, G and B are equal (every one of a grey material
under a white light) as one ``Y`` channel and a grey PNG, losslessly
(:func:`hzval.io.files.read_rgb_exr` reads R, G, B or Y); FLIP and
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

import dataclasses
import math
import os
import platform
import sys
import time
from functools import partial
from pathlib import Path

import numpy as np

from hzval.bake import maps as bake
from hzval.bake.maps import BakeParams
from hzval.core import backend, interrupts, resources, shading
from hzval.core import conventions as cv
from hzval.core.errors import InputError
from hzval.io import files
from hzval.metrics import compare
from hzval.metrics import facing as hzfacing
from hzval.report import images
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

__all__ = ["Options", "run", "frame_folder", "summary_table", "peak_rss_bytes", "reset_peak_rss", "PNG_LEVEL"]

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
    ``all_files``: write a frame's derived files too (:func:`_write_frame`).
    """

    radius: int = _BAKE_DEFAULTS.radius
    angles: int = _BAKE_DEFAULTS.angles
    method: str = _BAKE_DEFAULTS.method  # horizon bake method: "seed" or "exact"
    directions: int = _BAKE_DEFAULTS.directions
    techniques: tuple[str, ...] | None = None
    exclude: tuple[str, ...] = ()
    settings: dict = dataclasses.field(default_factory=dict)
    all_files: bool = False  # also the frame files that the others determine (_write_frame)

    def bake_params(self, scene) -> BakeParams:
        return BakeParams(
            depth=scene.material.depth,
            radius=self.radius,
            angles=self.angles,
            boundary=scene.material.boundary,
            method=self.method,
            directions=self.directions,
        ).validate()


def frame_folder(azimuth_deg: float) -> str:
    """Folder name of a frame: ``az-60``, ``az+0``, ``az+7.5``."""
    return f"az{azimuth_deg:+g}"


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
    view: dict = dataclasses.field(default_factory=dict)  # metrics.json's "view" (_view_errors)
    view_maps: dict = dataclasses.field(default_factory=dict)  # its per-pixel maps
    normal: np.ndarray | None = (
        None  # the top view's normal map: which pixels face the light (hzval.metrics.facing)
    )
    albedo_constant: float | None = None  # the linear albedo where it is one grey value (frames.json)


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
    check_fits(scene, params)  # before the map is generated or decoded
    hm = sc.load_material_height(scene.material)
    plan = truth_plan(scene, hm.height) if scene.mesh.is_plane else None
    estimate = check_fits(scene, params, hm.height, plan)  # the truth's own triangles, before they are made
    # from here on: the frames then reuse what the set-up frees, besides what they free themselves
    retained = estimate <= RETAIN_BELOW_SHARE * resources.available_bytes() and backend.retain_freed_memory()
    rows, cols = hm.height.shape
    material = {
        "name": scene.name,
        "source": hm.source,
        "digest": hm.digest,
        "rows": rows,
        "cols": cols,
        "path": files.report_path(hm.path, out),
    }
    t0 = time.perf_counter()
    notices: list[str] = []
    horizon = bake.needs_horizon(technique.bake_needs(chosen, scene))
    record = {**material, "path": files.report_path(hm.path, out / "bake")}  # relative to bake.json's folder
    baked, cached = bake.cached_bake(
        hm.height,
        hm.digest,
        params,
        out / "bake",
        record,
        notices,
        horizon=horizon,
        write_to=None if report_dir is None else report_dir / "bake",
    )
    timings = {"bake_s": time.perf_counter() - t0, "bake_cached": cached}
    t0 = time.perf_counter()
    albedo = sc.load_albedo(scene.material, rows, cols)
    the_truth, points = truth_of(scene, hm.height, albedo, plan)
    timings["truth_setup_s"] = time.perf_counter() - t0
    if points is not None:  # a model: its mesh (cut, displaced, its BVH) and camera rays
        timings.update({f"truth_{k}": v for k, v in the_truth.timings.items()})
    ctx = technique.Context(scene, hm.height, baked, albedo, points=points, cache=out / "fit")
    t0 = time.perf_counter()
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
    )
    if the_truth.hits is not None:
        t0 = time.perf_counter()
        _set_up_view(setup, ctx, chosen, options)
        timings["view_setup_s"] = time.perf_counter() - t0
    elif points is not None:
        # a model: every technique again at the truth's own hits (perfect parallax), as for a view
        perfect_ctx = dataclasses.replace(ctx, points=the_truth.samples("truth"), _shared={})
        setup.perfect = [t.build(perfect_ctx, **options.settings.get(t.name, {})) for t in chosen]
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

    base = model.load(scene.mesh.shape, uv_scale=scene.mesh.uv_scale, up=scene.mesh.up)
    the_truth = model_truth.ModelTruth(scene, height, base, albedo=albedo)
    return the_truth, the_truth.samples()


def _build_techniques(ctx, chosen, options: Options, timings: dict, notices: list) -> list:
    """Each chosen technique built from ``ctx`` (timed); one this machine cannot run
    (:class:`hzval.techniques.registry.Unavailable`) is skipped with its one-line notice."""
    built = []
    on_model = ctx.points is not None and ctx.points.frames is not None
    for t in chosen:
        if on_model and t.not_on_models:
            notices.append(f"{t.name}: not on a model: {t.not_on_models}")
            continue
        t0 = time.perf_counter()
        try:
            built.append(t.build(ctx, **options.settings.get(t.name, {})))
        except technique.Unavailable as e:
            notices.append(str(e))  # metrics.json's warnings; the command line prints them
            continue
        timings[f"{t.file_stem}_setup_s"] = time.perf_counter() - t0
    if not built:
        raise InputError(
            "--techniques", "no technique is left to score: " + "; ".join(notices[-len(chosen) :])
        )
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


def _write_view_maps(report_dir: Path, maps: dict, seen: np.ndarray) -> dict:
    """``view/<name>.exr`` (texels, NaN where no surface is seen) and a PNG of each of the view's
    maps (magma, 0 to the largest seen value, the unseen pixels in the background colour);
    their paths relative to ``report_dir``."""
    folder = report_dir / "view"
    rel = {}
    for name, values in maps.items():
        v = np.where(seen, values, np.float32(np.nan)).astype(np.float32)
        files.write_exr(folder / f"{name}.exr", {"Y": v}, half=False)
        top = float(np.nanmax(v)) if np.isfinite(v).any() else 1.0
        rgb = images.magma(np.nan_to_num(v / max(top, 1e-12)))
        rgb[~seen] = files.unit_to_u8(np.asarray(UNSEEN_DISPLAY))
        files.write_png(folder / f"{name}.png", rgb)
        rel[name] = f"view/{name}.exr"
        rel[f"{name}_png"] = f"view/{name}.png"
    return rel


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
    ``out`` must be new, empty or hzval's (:func:`hzval.io.files.output_folder`;
    ``force`` writes beside other files, which are kept); the run holds it: a
    second run into it fails at once. Signals are held from the swap on
    (:func:`hzval.core.interrupts.held`). ``gates`` (:class:`hzval.commands.gates.Gates`): tested on
    the result before the report is written, which lists their failures first (``metrics.json``'s ``gates``).
    """
    out = Path(out)
    reset_peak_rss()  # this sweep's own peak, even after others in this process
    try:
        with interrupts.held() as hold, files.output_folder(out, force=force):
            with files.Staging(out) as stage:
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
        setup.view["files"] = _write_view_maps(report_dir, setup.view_maps, setup.truth.seen)
    scale = shading.exposure(scene)
    clock = {"compare_s": 0.0, "write_s": 0.0, "plain_s": 0.0}
    bar = tqdm(
        scene.light.azimuths_deg,
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
    report.write_report(report_dir, result, command=command)
    timings["report_s"] = time.perf_counter() - t0
    timings["total_s"] = time.perf_counter() - t_start
    result["memory"] = {
        "peak_rss_bytes": peak_rss_bytes(),
        "estimate_bytes": setup.estimate,
        "retains_freed": setup.retained,
        **_band_record(setup.truth),
    }
    files.write_json(report_dir / "frames.json", engine_frames(scene, result, setup.albedo_constant))
    files.write_json(report_dir / "metrics.json", result)
    return result


def engine_frames(scene, result: dict, albedo_constant: float | None = None) -> dict:
    """``frames.json``: what an engine needs to render the sweep's frames itself, for ``hzval score``.

    Per light: the frame's name (``az+0``: the file ``hzval score`` looks for, ``az+0.exr`` linear
    or ``az+0.png`` sRGB, and ``f_az+0.exr`` its shadow factor F), azimuth and elevation, and ``L``
    in tangent space (toward the light); for all: the camera, the light's kind, irradiance and
    radiance, the albedo, the samples per pixel and the rule that places them, the display exposure
    and what it means for an EXR and a PNG, the image size and the material (:func:`_engine_notes`)."""
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
        **_engine_notes(scene, albedo_constant),
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


def _engine_notes(scene, albedo_constant) -> dict:
    """``frames.json``'s albedo, samples and exposure: what a frame scored against the truth must match
    besides the shadows (a one-sample shader loses 0.01-0.016 FLIP to aliasing alone; a frame pi times
    too bright, FLIP 0.68)."""
    if isinstance(albedo_constant, float):
        albedo = {"kind": "constant", "linear": albedo_constant}
    elif isinstance(scene.material.albedo, str):
        albedo = {"kind": "image", "path": scene.material.albedo, "encoding": "sRGB, decoded to linear"}
    else:
        albedo = {"kind": "image", "note": "the built-in material's own albedo image"}
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


def _frames(out: Path, scene, setup: _Setup, scale: float, clock: dict, all_files: bool, bar) -> list[dict]:
    """Every light of the sweep, as the progress bar ``bar`` (a ``tqdm`` of the azimuths) gives them:
    their ``metrics.json`` frames, in order, each rendered (:func:`_render`), then compared and
    written (:func:`_finish`).

    One frame at a time, every stage on all cores: the comparison and the truth are both Dr.Jit
    kernels, so overlapping them gains next to nothing and costs memory and clear stage timings."""
    frames: list[dict] = []
    for az in bar:
        bar.set_postfix_str(f"azimuth {az:+g} deg")
        # no name holds a frame's renders past its _finish: the next frame's renders would
        # otherwise be made beside them (1.8 GB at 4096 x 4096)
        frames.append(
            _finish(
                out,
                scene,
                setup,
                _render(setup, setup.truth.render(az), az, scale, clock),
                scale,
                clock,
                all_files,
            )
        )
    return frames


@dataclasses.dataclass
class _Rendered:
    """One light's renders: the truth, the unshadowed shading and its direct term, each technique's
    frame, and (a view other than ``top``) each technique's error at the truth's hit points."""

    azimuth_deg: float
    truth: object
    plain: object
    direct: np.ndarray
    techniques: list
    perfect: dict


def _render(setup: _Setup, t_frame, az: float, scale: float, clock: dict) -> _Rendered:
    """The techniques' renders of the light at ``az`` beside the truth's ``t_frame`` (a view's unseen
    pixels made the background in every image)."""
    plain, direct = setup.unshadowed.render(az)
    clock["plain_s"] += plain.seconds
    rendered = [(t, t.render(az)) for t in setup.techniques]
    mask = t_frame.mask
    perfect = {}
    if mask is not None:
        # a view: what no camera ray sees is the background in every image, and left out of the metrics
        bg = (cv.srgb_decode(np.asarray(UNSEEN_DISPLAY)) / scale).astype(np.float32)
        t_frame, plain = _unseen(t_frame, mask, bg), _unseen(plain, mask, bg)
        rendered = [(t, _unseen(f, mask, bg)) for t, f in rendered]
        V = t_frame.layers.get("visibility")
        for t in setup.perfect:
            F = t.render(az).layers.get("factor")
            if V is not None and F is not None:
                perfect[t.name] = compare.visibility_metrics(V, F, mask)[0]
    return _Rendered(az, t_frame, plain, direct, rendered, perfect)


def _finish(
    out: Path, scene, setup: _Setup, r: _Rendered, scale: float, clock: dict, all_files: bool
) -> dict:
    """Compare and write one light's renders; its ``metrics.json`` frame."""
    t_frame, az = r.truth, r.azimuth_deg
    # an image too large for the truth to keep its samples: hand Dr.Jit's freed buffers back before
    # the comparison, and after each of its steps, whose buffers differ in size and would each stay
    # cached (0.2 GiB of a 4096 sweep's peak); smaller images keep them: re-faulting the pages of
    # every frame's buffers cost 1 s a frame at 2048
    release = backend.release_memory if not setup.truth.keeps else (lambda: None)
    release()
    t0 = time.perf_counter()
    ref = compare.Reference(t_frame, scale)
    compared = []
    for t, f in r.techniques:
        release()
        metrics, maps = compare.compare(t_frame, f, scale, reference=ref)
        # only what the writers need, as small as it comes: the preview's 8-bit values (an eighth
        # of the float64 display values: 400 MB a technique at 4096 x 4096) and the FLIP map
        compared.append((t, f, metrics, {"shown": _shown(maps["display"]), "flip": maps["flip"]}))
        del maps
    release()
    floor = _floor(ref, r.direct, setup.unshadowed.ambient_image, t_frame.layers.get("visibility"))
    truth_shown = _shown(ref.display)
    del ref
    clock["compare_s"] += time.perf_counter() - t0
    rel, tech_files, seconds = _write_frame(
        out,
        frame_folder(az),
        t_frame,
        r.plain,
        compared,
        scale,
        truth_shown=truth_shown,
        all_files=all_files,
        mask=t_frame.mask,
    )
    clock["write_s"] += seconds
    frame = {"azimuth_deg": az, "elevation_deg": scene.light.elevation_deg, "truth_s": t_frame.seconds}
    if hasattr(setup.truth, "macro_shadowed"):
        frame["macro_shadowed"] = setup.truth.macro_shadowed(az)  # a model: the base mesh's own shadow
    if floor is not None:
        frame["floor"] = floor
    per = {
        t.name: {**_metrics(m), "seconds": f.seconds, "files": tech_files[t.name]} for t, f, m, _ in compared
    }
    for name, value in r.perfect.items():
        per[name]["perfect_parallax_mae"] = value
    for t in setup.techniques:
        per[t.name].update(type(t).frame_extras(per))
    _shadow_statistics(scene, setup, r, frame, per)
    if hasattr(setup.truth, "handedness"):
        _handedness_statistics(setup.truth.handedness, r, per)
    frame.update(files=rel, techniques=per)
    return frame


def _shadow_statistics(scene, setup: _Setup, r: _Rendered, frame: dict, per: dict) -> None:
    """The truth's shadowed and attached fractions (``frame["truth"]``) and each technique's visibility
    metrics over the pixels that face the light (:mod:`hzval.metrics.facing`)."""
    V = r.truth.layers.get("visibility")
    if V is None:
        return
    facing = None
    if setup.normal is not None:
        facing = hzfacing.facing_mask(
            setup.normal, scene.light.direction(r.azimuth_deg), scene.camera.supersampling
        )
    frame["truth"] = hzfacing.truth_statistics(V, facing, scene.spp, r.truth.mask)
    if facing is None:
        return
    for t, f in r.techniques:
        F = f.layers.get("factor")
        if F is not None:
            per[t.name].update(hzfacing.facing_metrics(V, F, facing, r.truth.mask))


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


#: The display (sRGB) colour of pixels that see no surface (a view's sky, or off an ``open`` tile).
UNSEEN_DISPLAY = (0.33, 0.42, 0.55)


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


def _view_parameters(scene) -> dict:
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


def _mesh_parameters(scene, out: Path) -> dict:
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
            **(
                {"split_parts": [{"key": k, "label": lb} for k, lb in t.split_parts]} if t.split_parts else {}
            ),
        }
        for t in setup.techniques
    }
    simulated = {"truth": list(setup.truth.simulated), **{n: v["simulated"] for n, v in techniques.items()}}
    return {
        "schema_version": SCHEMA_VERSION,
        "material": setup.material,
        "parameters": {
            "depth": scene.material.depth,
            "boundary": scene.material.boundary,
            "elevation_deg": scene.light.elevation_deg,
            "azimuths_deg": list(scene.light.azimuths_deg),
            "light": scene.light.kind,
            "light_radius_deg": scene.light.radius_deg,
            "effects": list(scene.effects),
            "spp": scene.spp,
            "seed": scene.seed,
            "supersampling": scene.camera.supersampling,
            "truth_tolerance": scene.material.truth_tolerance,
            **_view_parameters(scene),
            **_mesh_parameters(scene, out),
            "techniques": [t.name for t in setup.techniques],
        },
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


#: The frames' PNGs are written at zlib level 1: the renders' noise leaves zlib little to find, so a
#: higher level saves under 2% of a frame's bytes for several times the time (commit 'PNGs at
#: level 1' has the measurements).
PNG_LEVEL = 1


def _shown(display: np.ndarray) -> np.ndarray:
    """A preview's 8-bit values of display values ``(H, W, 3)``: ``(H, W)`` where they are grey.

    Grey display values are quantised once, not per channel: the same values, a third of the
    work, and :func:`hzval.io.files.write_png` takes the ``(H, W)`` result as the grey PNG it would
    have made of them."""
    return files.unit_to_u8(display[..., 0] if files.is_grey(display) else display)


def _write_frame(
    out: Path,
    name: str,
    truth_frame,
    plain,
    compared: list,
    scale: float,
    truth_shown: np.ndarray | None = None,
    all_files: bool = False,
    mask: np.ndarray | None = None,
) -> tuple[dict, dict, float]:
    """Write one frame's images; return ``(files, {technique: files}, seconds)``, the files as
    ``{key: path relative to out}`` (``metrics.json``'s ``files``).

    ``compared``: ``(technique, frame, metrics, maps)`` per technique; each
    technique's files are named after its ``file_stem``: ``<stem>.exr``,
    ``<stem>.png``, ``<stem>_factor.exr`` and ``.png``, ``<stem>_flip.png``,
    ``<stem>_visdiff.png``. Previews reuse the 8-bit values of the display values
    :func:`hzval.metrics.compare.compare` computed (``maps["shown"]``, ``truth_shown``: :func:`_shown`).

    What is written: the truth (``truth.exr``, its variance, ``visibility.exr``), each technique's
    ``F`` (``<stem>_factor.exr``), and the PNGs the report shows. The files that these determine
    are written only with ``all_files`` (``--all-files``): ``plain.exr`` (the report shows
    ``plain.png``), each technique's image ``<stem>.exr`` (``plain`` times ``F`` for the
    techniques that shade through :class:`hzval.techniques.surface.Unshadowed`; ``<stem>.png`` shows it) and
    the 8-bit PNGs of ``V`` and ``F`` (the EXRs hold them).

    Formats, each chosen to lose nothing a reader needs (the metrics were computed in float32
    before; docs/ARCHITECTURE.md, "metrics.json"): EXRs in half float, ZIP (2^-11 relative,
    finer than the previews' 8 bits; the variance's smallest values are rounded far inside the
    estimate's own relative error, sqrt(2 / (spp - 1))); an image with R == G == B as one ``Y``
    channel and an 8-bit grey PNG (lossless); FLIP and visibility-difference maps as palette PNGs
    (exact). ``mask``: the pixels a view's camera rays see; the layers' EXRs are NaN at the others.
    """
    t0 = time.perf_counter()
    w = _FrameWriter(out / "frames" / name, f"frames/{name}", scale, mask)
    rel = w.truth_files(truth_frame, plain, truth_shown, all_files)
    V = truth_frame.layers.get("visibility")
    per = {
        t.name: w.technique_files(t.file_stem, frame, maps, V, all_files) for t, frame, _, maps in compared
    }
    # Ctrl-C (or a writer's error): no writer outlives this frame to put a file into the staging
    # folder after run() has removed it
    files.run_writers(w.jobs)
    return rel, per, time.perf_counter() - t0


class _FrameWriter:
    """The writers of one frame's files (:func:`_write_frame`), queued to run on a thread per core:
    the encoders release the GIL (2 cores: 0.55x the time)."""

    def __init__(self, folder: Path, prefix: str, scale: float, mask: np.ndarray | None):
        self.folder, self.prefix, self.scale, self.mask = folder, prefix, scale, mask
        self.jobs: list = []

    def exr(self, rel: dict, key: str, filename: str, channels) -> None:
        self.jobs.append(partial(files.write_exr, self.folder / filename, channels, half=True, grey=True))
        rel[key] = f"{self.prefix}/{filename}"

    def png(self, rel: dict, key: str, filename: str, make, *args) -> None:
        self.jobs.append(partial(_write_png_of, self.folder / filename, make, *args))
        rel[key] = f"{self.prefix}/{filename}"

    def shown(self, img, values=None):
        # computed here, not in a writer: compare.display runs on the writers' own pool, and a writer
        # waiting for it holds its thread until the queue has drained (the rest of the frame on one)
        return _shown(compare.display(img, self.scale)) if values is None else values

    def layer(self, values):
        return (
            values
            if self.mask is None
            else np.where(self.mask, values, np.float32(np.nan)).astype(np.float32)
        )

    def truth_files(self, truth_frame, plain, truth_shown, all_files: bool) -> dict:
        """The truth's and the unshadowed render's files."""
        rel: dict = {}
        self.exr(rel, "truth", "truth.exr", {"RGB": truth_frame.image})
        if all_files:
            self.exr(rel, "plain", "plain.exr", {"RGB": plain.image})
        if "image" in truth_frame.variance:
            self.exr(rel, "truth_variance", "truth_variance.exr", {"RGB": truth_frame.variance["image"]})
        self.png(rel, "truth_png", "truth.png", _as_is, self.shown(truth_frame.image, truth_shown))
        self.png(rel, "plain_png", "plain.png", _as_is, self.shown(plain.image))
        V = truth_frame.layers.get("visibility")
        if V is not None:
            self.exr(rel, "visibility", "visibility.exr", {"Y": self.layer(V)})
            if all_files:
                self.png(rel, "visibility_png", "visibility.png", files.unit_to_u8, V)
        return rel

    def technique_files(self, stem: str, frame, maps: dict, V, all_files: bool) -> dict:
        """One technique's files, named after its ``stem``."""
        own: dict = {}
        if all_files:
            self.exr(own, "image", f"{stem}.exr", {"RGB": frame.image})
        self.png(own, "png", f"{stem}.png", _as_is, self.shown(frame.image, maps.get("shown")))
        self.png(own, "flip_png", f"{stem}_flip.png", images.flip_indexed, maps["flip"])
        F = frame.layers.get("factor")
        if F is not None:
            self.exr(own, "factor", f"{stem}_factor.exr", {"Y": self.layer(F)})
            if all_files:
                self.png(own, "factor_png", f"{stem}_factor.png", files.unit_to_u8, F)
            if V is not None:
                self.png(own, "visdiff_png", f"{stem}_visdiff.png", images.visibility_diff_indexed, V, F)
        return own


def _as_is(pixels):
    return pixels


def _write_png_of(path: Path, make, *args) -> None:
    """Write ``make(*args)`` (uint8 pixels or a palette image) at :data:`PNG_LEVEL`, grey RGB as grey,
    with the report's preview if it is large (:func:`hzval.io.files.write_png_with_preview`)."""
    files.write_png_with_preview(path, make(*args), compress_level=PNG_LEVEL, grey=True)


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
    head = ("azimuth",)
    if lead:
        head += (f"{lead} |F-V|", "leaks", "false sh.", f"{lead} FLIP", "dE2000", "PSNR dB")
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
            row += (
                num(vis(t, "visibility_mae"), 4),
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
    return "\n".join([line(head), line(["-" * w for w in widths]), *map(line, rows), *note])
