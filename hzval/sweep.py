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
                                          and PNG previews of each, flip.png, visdiff.png
"""

from __future__ import annotations

import dataclasses
import math
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

from hzval import compare, files
from hzval.bake import BakeParams

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
    if scene.material.height == "bricks":     # estimate before generating the built-in map
        n = scene.material.size
        bake.check_fits("--size", n, n, BakeParams(depth=scene.material.depth, radius=options.radius,
                                                   angles=options.angles, boundary=scene.material.boundary,
                                                   method=options.method).validate())
    hm = sc.load_material_height(scene.material)
    rows, cols = hm.height.shape
    params = BakeParams(depth=scene.material.depth, radius=options.radius, angles=options.angles,
                        boundary=scene.material.boundary, method=options.method).validate()
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

    scale = compare.exposure(scene)
    frames, compare_s, write_s = [], 0.0, 0.0
    bar = tqdm(scene.light.azimuths_deg, desc="sweep", unit="frame", disable=not progress,
               file=sys.stderr, leave=False)
    for az in bar:
        bar.set_postfix_str(f"azimuth {az:+g} deg")
        t_frame = the_truth.render(az)
        a_frame = the_approx.render(az)
        plain = the_approx.render(az, shadows=False)
        t0 = time.perf_counter()
        metrics, maps = compare.compare(t_frame, a_frame, scale)
        compare_s += time.perf_counter() - t0
        t0 = time.perf_counter()
        rel = _write_frame(out, frame_folder(az), t_frame, a_frame, plain, maps, scale)
        write_s += time.perf_counter() - t0
        frames.append({"azimuth_deg": az, "elevation_deg": scene.light.elevation_deg,
                       **{k: _finite(v) for k, v in metrics.as_dict().items()},
                       "truth_s": t_frame.seconds, "approx_s": a_frame.seconds, "files": rel})
    bar.close()

    timings.update(truth_s=sum(f["truth_s"] for f in frames), approx_s=sum(f["approx_s"] for f in frames),
                   compare_s=compare_s, write_s=write_s)
    result = {
        "material": material_info,
        "parameters": {"depth": scene.material.depth, "boundary": scene.material.boundary,
                       "method": params.method, "radius": params.record()["radius"],
                       "angles": params.record()["angles"],
                       "elevation_deg": scene.light.elevation_deg,
                       "azimuths_deg": list(scene.light.azimuths_deg), "k": options.k,
                       "light": scene.light.kind, "light_radius_deg": scene.light.radius_deg,
                       "effects": list(scene.effects), "spp": scene.spp, "seed": scene.seed,
                       "supersampling": scene.camera.supersampling, "path": options.path,
                       "ambient": options.ambient},
        "versions": {**backend.versions(), "python": platform.python_version(), "machine": _machine()},
        "timings": timings,
        "simulated": {"truth": list(the_truth.simulated), "approx": list(the_approx.simulated)},
        "frames": frames,
    }
    t0 = time.perf_counter()
    report.write_report(out, result, command=command)
    timings["report_s"] = time.perf_counter() - t0
    timings["total_s"] = time.perf_counter() - t_start
    result["memory"] = {"peak_rss_bytes": peak_rss_bytes()}
    files.write_json(out / "metrics.json", result)
    return result


def _write_frame(out: Path, name: str, truth, approx, plain, maps: dict, scale: float) -> dict:
    """Write one frame's images; return their paths relative to ``out``."""
    folder = out / "frames" / name
    rel = {}

    def put(key: str, filename: str, writer, data):
        writer(folder / filename, data)
        rel[key] = f"frames/{name}/{filename}"

    put("truth", "truth.exr", files.write_exr, {"RGB": truth.image})
    put("approx", "approx.exr", files.write_exr, {"RGB": approx.image})
    put("plain", "plain.exr", files.write_exr, {"RGB": plain.image})
    if "image" in truth.variance:
        put("truth_variance", "truth_variance.exr", files.write_exr, {"RGB": truth.variance["image"]})
    for key, img in (("truth_png", truth.image), ("approx_png", approx.image), ("plain_png", plain.image)):
        put(key, key.removesuffix("_png") + ".png", files.write_png, files.unit_to_u8(compare.display(img, scale)))
    V, F = truth.layers.get("visibility"), approx.layers.get("factor")
    if V is not None:
        put("visibility", "visibility.exr", files.write_exr, {"Y": V})
        put("visibility_png", "visibility.png", files.write_png, files.unit_to_u8(V))
    if F is not None:
        put("factor", "factor.exr", files.write_exr, {"Y": F})
        put("factor_png", "factor.png", files.write_png, files.unit_to_u8(F))
    if V is not None and F is not None:
        put("visdiff_png", "visdiff.png", files.write_png, visibility_diff_image(V, F))
    put("flip_png", "flip.png", files.write_png, flip_image(maps["flip"]))
    return rel


def summary_table(result: dict) -> str:
    """The sweep's metrics as a plain-text table for the terminal."""
    head = ("azimuth", "|F-V|", "leaks", "false sh.", "FLIP", "dE2000", "PSNR dB", "truth s", "approx s")
    rows = []
    for f in result["frames"]:
        def pct(v):
            return "-" if v is None else f"{100 * v:.2f}%"
        rows.append((f"{f['azimuth_deg']:+g}", "-" if f["visibility_mae"] is None else f"{f['visibility_mae']:.4f}",
                     pct(f["leak_fraction"]), pct(f["false_shadow_fraction"]), f"{f['flip_mean']:.4f}",
                     f"{f['delta_e2000_mean']:.3f}", "inf" if f["psnr_db"] is None else f"{f['psnr_db']:.2f}",
                     f"{f['truth_s']:.3f}", f"{f['approx_s']:.4f}"))
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(head)]
    line = lambda cells: "  ".join(c.rjust(w) for c, w in zip(cells, widths))  # noqa: E731
    return "\n".join([line(head), line(["-" * w for w in widths]), *map(line, rows)])
