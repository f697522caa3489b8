"""The sweep: truth and approximation for every light of a scene, compared.

For a scene (:mod:`hzval.scene`), :func:`run` bakes the material (or reuses
the bake in ``out/bake`` when input digest and parameters match), builds the
ground truth (:mod:`hzval.truth`) and the approximation (:mod:`hzval.approx`)
once, then renders each light of the sweep with both, and with plain normal
mapping (no shadows) for the report's comparison. Each frame is compared
(:mod:`hzval.compare`) and its images are written under ``out/frames``;
``metrics.json`` and the HTML report (:mod:`hzval.report`) close the run.

Output folder::

    index.html, metrics.json, plots/      the report
    bake/                                 the bake (cache)
    frames/az<azimuth>/                   per light: truth.exr, approx.exr, plain.exr,
                                          visibility.exr (V), factor.exr (F), truth_variance.exr,
                                          and PNG previews of each, flip.png, visdiff.png;
                                          terrain.exr, terrain_factor.exr and PNGs, terrain_flip.png,
                                          terrain_visdiff.png (the terrain technique)

The third technique (:mod:`hzval.terrain`, Raudins' per-light shadow
boundary, ``Options.terrain``, on by default when the scene declares
``shadow``) is rendered for every light beside the horizon-mapped one, from
the same plain normal-mapped render, and compared with the same truth. Its
metrics go under ``frames[i]["terrain"]`` (the DESIGN.md keys of a frame stay
the horizon map's) and ``simulated["terrain"]``.

Speed: the truth's display values and Lab are computed once per frame for
both comparisons (:class:`hzval.compare.Reference`); previews reuse the
comparison's display values; PNG previews are compressed at zlib
level 1 (:data:`PNG_LEVEL`). None of this changes a value. The comparison
stays in this process: ``flip-evaluator`` already runs on both cores of the
2-core machine (0.40 s wall, 0.75 s CPU a 512 x 512 frame), and moving FLIP
and CIEDE2000 into a worker process a frame ahead was measured to gain
nothing (24.8 s against 24.9 s for the default sweep).
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

from hzval import backend, compare, files
from hzval.bake import BakeParams
from hzval.errors import InputError

#: Colours of the visibility-difference map (sRGB 8-bit): where the technique
#: lights what the truth shadows, and where it shadows what the truth lights.
LEAK_RGB = (255, 127, 14)
FALSE_SHADOW_RGB = (31, 119, 180)


@dataclasses.dataclass(frozen=True)
class Options:
    """Settings of the approximation and the bake that the scene does not hold."""

    k: float = 8.0
    path: str = "exact"          # "exact" or "gpu" (8-bit emulation)
    ambient: str = "mean_cos2"   # which ambient-map definition the approximation uses
    radius: int = 16
    angles: int = 32
    method: str = "seed"         # horizon bake method: "seed" or "exact" (BakeParams.method)
    directions: int = 8          # stored horizon directions: 8 or 16 (BakeParams.directions)
    terrain: bool = True         # also render and compare Raudins' terrain shadows (hzval.terrain)


def frame_folder(azimuth_deg: float) -> str:
    """Folder name of a frame: ``az-60``, ``az+0``, ``az+7.5``."""
    return f"az{azimuth_deg:+g}"


def visibility_diff_image(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """8-bit RGB map: grey where truth and technique agree (darker in shadow),
    :data:`LEAK_RGB` for leaks, :data:`FALSE_SHADOW_RGB` for false shadows."""
    grey = files.unit_to_u8(0.25 + 0.5 * np.clip(V, 0, 1))
    img = np.repeat(grey[..., None], 3, axis=-1)
    lit_truth, lit_approx = V >= 0.5, F >= 0.5
    img[lit_approx & ~lit_truth] = LEAK_RGB
    img[~lit_approx & lit_truth] = FALSE_SHADOW_RGB
    return img


def flip_image(error: np.ndarray) -> np.ndarray:
    """FLIP error map in [0, 1] as 8-bit RGB through matplotlib's magma (FLIP's own colour map)."""
    from matplotlib import colormaps

    return (colormaps["magma"](np.clip(error, 0, 1))[..., :3] * 255 + 0.5).astype(np.uint8)


def peak_rss_bytes() -> int:
    """Peak resident memory of this process so far, in bytes (Linux reports KiB, macOS bytes)."""
    import resource

    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return int(rss if sys.platform == "darwin" else rss * 1024)


def _machine() -> str:
    return f"{platform.system()} {platform.machine()}, {os.cpu_count()} CPUs, {platform.processor() or 'cpu'}"


def _finite(x):
    """JSON has no infinity: a perfect PSNR is written as null."""
    return None if isinstance(x, float) and not math.isfinite(x) else x


def run(scene, out: str | Path, *, options: Options = Options(), command: str = "", progress: bool = True) -> dict:
    """Run the sweep of ``scene`` into ``out``; return the ``metrics.json`` content."""
    from tqdm import tqdm

    from hzval import approx, backend, bake, report, scene as sc, truth

    out = Path(out)
    t_start = time.perf_counter()
    backend.variant()
    params = BakeParams(depth=scene.material.depth, radius=options.radius, angles=options.angles,
                        boundary=scene.material.boundary, method=options.method,
                        directions=options.directions).validate()
    if options.path == "gpu" and params.directions != 8:   # before anything is written
        raise InputError("--path", f"the gpu path emulates Lengyel's 8-channel weight cube map; a bake of "
                                   f"{params.directions} directions needs --path exact")
    if scene.material.height == "bricks":     # estimate before generating the built-in map
        n = scene.material.size
        bake.check_fits("--size", n, n, params)
    hm = sc.load_material_height(scene.material)
    rows, cols = hm.height.shape
    bake.check_fits(hm.path or "material", rows, cols, params)
    material_info = {"name": scene.name, "source": hm.source, "digest": hm.digest,
                     "rows": rows, "cols": cols, "path": hm.path}

    t0 = time.perf_counter()
    baked, cached = bake.cached_bake(hm.height, hm.digest, params, out / "bake", material_info)
    timings = {"bake_s": time.perf_counter() - t0, "bake_cached": cached}

    t0 = time.perf_counter()
    the_truth = truth.Truth(scene, hm.height)
    timings["truth_setup_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    albedo = sc.load_albedo(scene.material, rows, cols)
    the_approx = approx.Approximation(scene, baked, albedo, path=options.path, k=options.k,
                                      ambient=options.ambient)
    timings["approx_setup_s"] = time.perf_counter() - t0
    the_terrain = None
    if options.terrain and scene.declares("shadow"):
        from hzval import terrain

        t0 = time.perf_counter()
        the_terrain = terrain.TerrainShadow(scene, hm.height, bake=baked, albedo=albedo, approximation=the_approx)
        timings["terrain_setup_s"] = time.perf_counter() - t0

    scale = compare.exposure(scene)
    frames, compare_s, write_s = [], 0.0, 0.0
    bar = tqdm(scene.light.azimuths_deg, desc="sweep", unit="frame", disable=not progress,
               file=sys.stderr, leave=False)

    try:
        for az in bar:
            bar.set_postfix_str(f"azimuth {az:+g} deg")
            t_frame = the_truth.render(az)
            a_frame = the_approx.render(az)
            plain = the_approx.render(az, shadows=False)
            te_frame = the_terrain.render(az, plain=plain) if the_terrain is not None else None
            t0 = time.perf_counter()
            ref = compare.Reference(t_frame, scale)
            metrics, maps = compare.compare(t_frame, a_frame, scale, reference=ref)
            te = compare.compare(t_frame, te_frame, scale, reference=ref) if te_frame is not None else None
            compare_s += time.perf_counter() - t0
            rel, te_rel, seconds = _write_frame(out, frame_folder(az), t_frame, a_frame, plain, maps, scale,
                                                te_frame, te[1] if te is not None else None,
                                                truth_display=ref.display)
            write_s += seconds
            frame = {"azimuth_deg": az, "elevation_deg": scene.light.elevation_deg,
                     **{k: _finite(v) for k, v in metrics.as_dict().items()},
                     "truth_s": t_frame.seconds, "approx_s": a_frame.seconds, "files": rel}
            if te is not None:
                frame["terrain"] = {**{k: _finite(v) for k, v in te[0].as_dict().items()},
                                    "seconds": te_frame.seconds, "files": te_rel}
            frames.append(frame)
    finally:
        bar.close()

    timings.update(truth_s=sum(f["truth_s"] for f in frames), approx_s=sum(f["approx_s"] for f in frames),
                   compare_s=compare_s, write_s=write_s)
    if the_terrain is not None:
        timings["terrain_s"] = sum(f["terrain"]["seconds"] for f in frames)
    result = {
        "material": material_info,
        "parameters": {"depth": scene.material.depth, "boundary": scene.material.boundary,
                       "method": params.method, "radius": params.record()["radius"],
                       "angles": params.record()["angles"], "directions": params.directions,
                       "elevation_deg": scene.light.elevation_deg,
                       "azimuths_deg": list(scene.light.azimuths_deg), "k": options.k,
                       "light": scene.light.kind, "light_radius_deg": scene.light.radius_deg,
                       "effects": list(scene.effects), "spp": scene.spp, "seed": scene.seed,
                       "supersampling": scene.camera.supersampling, "path": options.path,
                       "ambient": options.ambient,
                       **({"terrain_ramp_texels": the_terrain.ramp} if the_terrain is not None else {})},
        "versions": {**backend.versions(), "python": platform.python_version(), "machine": _machine()},
        "timings": timings,
        "simulated": {"truth": list(the_truth.simulated), "approx": list(the_approx.simulated),
                      **({"terrain": list(the_terrain.simulated)} if the_terrain is not None else {})},
        "frames": frames,
    }
    t0 = time.perf_counter()
    report.write_report(out, result, command=command)
    timings["report_s"] = time.perf_counter() - t0
    timings["total_s"] = time.perf_counter() - t_start
    result["memory"] = {"peak_rss_bytes": peak_rss_bytes()}
    files.write_json(out / "metrics.json", result)
    return result


#: PNG previews are written at zlib level 1: on these renders it is several
#: times faster than the default 6 and the files are about 10% larger.
PNG_LEVEL = 1


def _write_frame(out: Path, name: str, truth, approx, plain, maps: dict, scale: float,
                 terrain=None, terrain_maps: dict | None = None,
                 truth_display: np.ndarray | None = None) -> tuple[dict, dict, float]:
    """Write one frame's images; return ``(files, terrain_files, seconds)``, the
    files as ``{key: path relative to out}`` (``metrics.json``'s ``files``).

    Previews reuse the display values :func:`hzval.compare.compare` computed
    (``maps["display"]``, ``truth_display``) where given."""
    t0 = time.perf_counter()
    folder = out / "frames" / name
    jobs = []       # written on a thread per core: the encoders release the GIL (2 cores: 0.55x the time)

    def exr(rel: dict, key: str, filename: str, channels):
        jobs.append(partial(files.write_exr, folder / filename, channels))
        rel[key] = f"frames/{name}/{filename}"

    def png(rel: dict, key: str, filename: str, make, *args):
        jobs.append(partial(_write_png_of, folder / filename, make, *args))
        rel[key] = f"frames/{name}/{filename}"

    def preview(img, shown=None):
        return files.unit_to_u8(compare.display(img, scale) if shown is None else shown)

    rel, te_rel = {}, {}
    exr(rel, "truth", "truth.exr", {"RGB": truth.image})
    exr(rel, "approx", "approx.exr", {"RGB": approx.image})
    exr(rel, "plain", "plain.exr", {"RGB": plain.image})
    if "image" in truth.variance:
        exr(rel, "truth_variance", "truth_variance.exr", {"RGB": truth.variance["image"]})
    for stem, img, shown in (("truth", truth.image, truth_display), ("approx", approx.image, maps.get("display")),
                             ("plain", plain.image, None)):
        png(rel, f"{stem}_png", f"{stem}.png", preview, img, shown)
    V, F = truth.layers.get("visibility"), approx.layers.get("factor")
    if V is not None:
        exr(rel, "visibility", "visibility.exr", {"Y": V})
        png(rel, "visibility_png", "visibility.png", files.unit_to_u8, V)
    if F is not None:
        exr(rel, "factor", "factor.exr", {"Y": F})
        png(rel, "factor_png", "factor.png", files.unit_to_u8, F)
    if V is not None and F is not None:
        png(rel, "visdiff_png", "visdiff.png", visibility_diff_image, V, F)
    png(rel, "flip_png", "flip.png", flip_image, maps["flip"])
    if terrain is not None:
        exr(te_rel, "image", "terrain.exr", {"RGB": terrain.image})
        png(te_rel, "png", "terrain.png", preview, terrain.image, terrain_maps.get("display"))
        png(te_rel, "flip_png", "terrain_flip.png", flip_image, terrain_maps["flip"])
        TF = terrain.layers.get("factor")
        if TF is not None:
            exr(te_rel, "factor", "terrain_factor.exr", {"Y": TF})
            png(te_rel, "factor_png", "terrain_factor.png", files.unit_to_u8, TF)
            if V is not None:
                png(te_rel, "visdiff_png", "terrain_visdiff.png", visibility_diff_image, V, TF)
    for done in [backend.host_pool().submit(job) for job in jobs]:
        done.result()                       # re-raises a writer's error here
    return rel, te_rel, time.perf_counter() - t0


def _write_png_of(path: Path, make, *args) -> None:
    files.write_png(path, make(*args), compress_level=PNG_LEVEL)


def summary_table(result: dict) -> str:
    """The sweep's metrics as a plain-text table for the terminal."""
    terrain = any("terrain" in f for f in result["frames"])
    head = ("azimuth", "|F-V|", "leaks", "false sh.", "FLIP", "dE2000", "PSNR dB", "truth s", "approx s")
    if terrain:
        head += ("terrain |F-V|", "terrain s")
    rows = []
    for f in result["frames"]:
        def pct(v):
            return "-" if v is None else f"{100 * v:.2f}%"
        row = (f"{f['azimuth_deg']:+g}", "-" if f["visibility_mae"] is None else f"{f['visibility_mae']:.4f}",
               pct(f["leak_fraction"]), pct(f["false_shadow_fraction"]), f"{f['flip_mean']:.4f}",
               f"{f['delta_e2000_mean']:.3f}", "inf" if f["psnr_db"] is None else f"{f['psnr_db']:.2f}",
               f"{f['truth_s']:.3f}", f"{f['approx_s']:.4f}")
        if terrain:
            te = f.get("terrain") or {}
            mae = te.get("visibility_mae")
            row += ("-" if mae is None else f"{mae:.4f}", "-" if "seconds" not in te else f"{te['seconds']:.4f}")
        rows.append(row)
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(head)]
    line = lambda cells: "  ".join(c.rjust(w) for c, w in zip(cells, widths))  # noqa: E731
    return "\n".join([line(head), line(["-" * w for w in widths]), *map(line, rows)])
