"""Score an engine's own frames against a sweep's truth: ``hzval score FRAMES_DIR --against SWEEP_DIR``.

An engineer renders the sweep's frames with their own baker and shader,
from what ``SWEEP_DIR/frames.json`` says (camera, light directions in
tangent space, irradiance, exposure, image size; :func:`hzval.sweep.engine_frames`),
one image per light named after the frame folders: ``az+0.exr`` (linear
radiance, RGB or Y) or ``az-60.png`` (8- or 16-bit sRGB display values,
``display = srgb(clip(exposure * radiance))``, decoded back to radiance
here). :func:`score` scores each against the sweep's truth with the very
image metrics the sweep uses (:func:`hzval.compare.image_metrics`: FLIP,
RMSE, PSNR, CIEDE2000), beside that frame's perfect-shadows floor, and
:func:`write` writes ``OUT/metrics.json`` (``frames[i].azimuth_deg``,
``flip_mean``, ``rmse``, ``psnr_db``, ``delta_e2000_mean``) and a report
in which the external images are a technique beside the truth.

The truth is the sweep's ``truth.exr``, which holds it in half float
(2^-11 relative; the sweep scored its techniques in float32 before writing
it). So a sweep's own EXR images, themselves half, scored here come within
2e-5 of the sweep's FLIP and RMSE and 1e-4 of its CIEDE2000 (measured at
most 6e-6 FLIP, 1.3e-6 RMSE and 1.4e-5 CIEDE2000 at 48 x 48 texels, 8e-7
FLIP at 256 x 256), a thousandth of what its 8-bit PNG previews'
quantisation adds (2e-3 to 4e-3 FLIP, 0.07 CIEDE2000);
``tests/test_score.py`` holds it to that.

Bad input is one line naming the file: a folder that is not a sweep's, a
missing frame, a wrong size, a non-finite value, an unreadable image.
"""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

import numpy as np

from hzval import compare, files, images, report
from hzval import conventions as cv
from hzval.errors import InputError
from hzval.scene import Frame

__all__ = ["score", "write", "read_frame", "LABEL"]

#: What the report calls the scored images.
LABEL = "your renderer"


def _sweep(sweep_dir: Path) -> tuple[dict, dict]:
    """The sweep's ``metrics.json`` and ``frames.json``."""
    out = []
    for name in ("metrics.json", "frames.json"):
        path = sweep_dir / name
        try:
            out.append(json.loads(path.read_text(encoding="utf-8")))
        except FileNotFoundError:
            raise InputError(sweep_dir, f"not a sweep folder (no {name}): run hzval sweep --out {sweep_dir}") from None
        except (OSError, ValueError) as exc:
            raise InputError(path, f"unreadable ({files.first_line(exc)})") from None
    return out[0], out[1]


def _check_shape(metrics, engine, sweep_dir: Path) -> None:
    """Refuse, with one line naming the file and the key, a sweep folder whose ``frames.json`` or
    ``metrics.json`` is not of the shape :func:`hzval.sweep.run` writes (what :func:`score` reads)."""
    def need(ok: bool, name: str, key: str, what: str) -> None:
        if not ok:
            raise InputError(sweep_dir / name, f"not a sweep's {name}: {key} must be {what}")

    def number(v) -> bool:
        return isinstance(v, (int, float)) and not isinstance(v, bool)

    need(isinstance(engine, dict), "frames.json", "the file", "a JSON object")
    need(number(engine.get("exposure")), "frames.json", "exposure", "a number")
    size = engine.get("image_size")
    need(isinstance(size, list) and len(size) == 2 and all(isinstance(v, int) and v > 0 for v in size),
         "frames.json", "image_size", "[width, height]")
    frames = engine.get("frames")
    need(isinstance(frames, list) and frames and all(
        isinstance(f, dict) and isinstance(f.get("name"), str) and number(f.get("azimuth_deg"))
        and number(f.get("elevation_deg")) for f in frames), "frames.json", "frames",
        "a list of {name, azimuth_deg, elevation_deg}")
    need(isinstance(metrics, dict), "metrics.json", "the file", "a JSON object")
    swept = metrics.get("frames")
    need(isinstance(swept, list) and len(swept) == len(frames) and all(
        isinstance(f, dict) and isinstance(f.get("files"), dict) and isinstance(f["files"].get("truth"), str)
        for f in swept), "metrics.json", "frames", f"a list of {len(frames)} frames, each with files.truth")
    for key in ("material", "parameters", "exposure", "versions", "simulated"):
        need(isinstance(metrics.get(key, {}), dict), "metrics.json", key, "an object")


def read_frame(path: Path, exposure: float, shape: tuple[int, int]) -> np.ndarray:
    """An engine's frame as linear radiance ``(H, W, 3)`` float32: EXR as stored (RGB, or Y as grey),
    PNG decoded from sRGB and divided by the exposure."""
    if path.suffix.lower() == ".exr":
        img = files.read_rgb_exr(path)
    else:
        from PIL import Image

        try:
            with Image.open(path) as im:
                depth = 65535.0 if im.mode in ("I;16", "I;16B", "I", "I;16L") else 255.0
                arr = np.asarray(im.convert("RGB") if depth == 255.0 else im, dtype=np.float64) / depth
        except OSError as exc:
            raise InputError(path, f"not a readable PNG ({files.first_line(exc)})") from None
        arr = np.repeat(arr[..., None], 3, axis=-1) if arr.ndim == 2 else arr[..., :3]
        img = cv.srgb_decode(arr) / exposure
    img = np.asarray(img, np.float32)
    if img.shape[:2] != tuple(shape):
        raise InputError(path, f"is {img.shape[1]}x{img.shape[0]}, the sweep's frames are {shape[1]}x{shape[0]}")
    if not np.isfinite(img).all():
        raise InputError(path, f"has {int((~np.isfinite(img)).sum())} non-finite values (NaN or infinity)")
    return img


def _find(frames_dir: Path, name: str) -> Path:
    for ext in (".exr", ".png"):
        if (frames_dir / f"{name}{ext}").is_file():
            return frames_dir / f"{name}{ext}"
    raise InputError(frames_dir / f"{name}.exr", f"missing: the frame for light {name} (an .exr or .png)")


def score(frames_dir: str | Path, sweep_dir: str | Path) -> tuple[dict, list[tuple[str, dict, dict]]]:
    """Score every frame of ``frames_dir`` against ``sweep_dir``'s truth.

    Returns ``(result, maps)``: the ``metrics.json`` content (without the
    report) and, per frame, ``(name, the sweep's frame, image_maps)`` for
    :func:`write`. Every frame is read and checked before any is scored.
    """
    frames_dir, sweep_dir = Path(frames_dir), Path(sweep_dir)
    if not frames_dir.is_dir():
        raise InputError(frames_dir, "no such folder of frames")
    metrics, engine = _sweep(sweep_dir)
    _check_shape(metrics, engine, sweep_dir)
    exposure = float(engine["exposure"])
    W, H = engine["image_size"]
    todo = [(f, _find(frames_dir, f["name"])) for f in engine["frames"]]
    loaded = [(f, p, read_frame(p, exposure, (H, W))) for f, p in todo]
    t0 = time.perf_counter()
    frames, maps = [], []
    for (f, path, img), swept in zip(loaded, metrics["frames"]):
        # R, G, B or (the sweep's grey truth) Y, in half float: see the module's docstring
        truth = Frame(f["azimuth_deg"], f["elevation_deg"], files.read_rgb_exr(sweep_dir / swept["files"]["truth"]))
        scores, image_maps = compare.image_metrics(compare.Reference(truth, exposure), img)
        scores = {k: (None if isinstance(v, float) and not np.isfinite(v) else v) for k, v in scores.items()}
        frames.append({"azimuth_deg": f["azimuth_deg"], "elevation_deg": f["elevation_deg"], **scores,
                       "file": str(path), **({"floor": swept["floor"]} if "floor" in swept else {})})
        maps.append((f["name"], swept, image_maps))
    result = {"material": metrics.get("material", {}), "against": str(sweep_dir), "frames_dir": str(frames_dir),
              "parameters": metrics.get("parameters", {}), "exposure": metrics.get("exposure", {}),
              "versions": metrics.get("versions", {}), "timings": {"score_s": time.perf_counter() - t0},
              "simulated": {"truth": metrics.get("simulated", {}).get("truth", [])}, "frames": frames}
    return result, maps


def write(result: dict, maps: list, out: str | Path, *, command: str = "", force: bool = False) -> Path:
    """``out/metrics.json`` and ``out/index.html``: the external images as a technique beside the
    sweep's truth (whose previews are copied in, so the report stands alone). Returns the index.
    The folder is held while they are written (:func:`hzval.files.output_folder`)."""
    out = Path(out)
    with files.output_folder(out, force=force):
        return _write(result, maps, out, command)


def _write(result: dict, maps: list, out: Path, command: str) -> Path:
    sweep_dir = Path(result["against"])
    page_frames = []
    for frame, (name, swept_frame, image_maps) in zip(result["frames"], maps):
        rel = {}
        for key in ("truth_png", "plain_png", "visibility_png"):
            if key in swept_frame["files"]:
                dst = f"frames/{name}/{Path(swept_frame['files'][key]).name}"
                (out / dst).parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(sweep_dir / swept_frame["files"][key], out / dst)
                rel[key] = dst
        own = {"png": f"frames/{name}/external.png", "flip_png": f"frames/{name}/external_flip.png"}
        files.write_png(out / own["png"], files.unit_to_u8(image_maps["display"]))
        files.write_png(out / own["flip_png"], images.flip_image(image_maps["flip"]))
        metrics = {k: frame[k] for k in compare.IMAGE_METRICS}
        page_frames.append({"azimuth_deg": frame["azimuth_deg"], "elevation_deg": frame["elevation_deg"],
                            "truth_s": None, "files": rel, **({"floor": frame["floor"]} if "floor" in frame else {}),
                            "techniques": {"external": {**metrics, "visibility_mae": None, "leak_fraction": None,
                                                        "false_shadow_fraction": None, "seconds": None,
                                                        "files": own}}})
    page = {**{k: result[k] for k in ("material", "parameters", "versions", "timings")},
            "simulated": {**result["simulated"], "external": list(result["parameters"].get("effects", []))},
            "techniques": {"external": {"label": LABEL, "file_stem": "external", "summary": result["frames_dir"]}},
            "frames": page_frames}
    index = report.write_report(out, page, command=command)
    # the paths relative to the report's folder: a shared report carries no absolute folders
    portable = {**result, "against": files.report_path(result["against"], out),
                "frames_dir": files.report_path(result["frames_dir"], out),
                "frames": [{**f, "file": files.report_path(f["file"], out)} for f in result["frames"]]}
    files.write_json(out / "metrics.json", portable)
    return index
