"""Scoring of an engine's own frames against a sweep's truth, beside hzval's techniques on the same sweep.

The command is ``hzval score FRAMES_DIR --against SWEEP_DIR``.

An engineer renders the sweep's frames with their own baker and shader,
from what ``SWEEP_DIR/frames.json`` says (camera, light directions in
tangent space, irradiance, exposure, image size; :func:`hzval.pipeline.records.engine_frames`),
one image per light named after the frame folders: ``az+0.exr`` (linear
radiance, RGB or Y) or ``az-60.png`` (8- or 16-bit sRGB display values,
``display = srgb(clip(exposure * radiance))``, decoded back to radiance
here). :func:`score` scores each against the sweep's truth with the very
image metrics the sweep uses (:func:`hzval.metrics.compare.image_metrics`: FLIP,
RMSE, PSNR, CIEDE2000), beside that frame's perfect-shadows floor, and
:func:`write` writes ``OUT/metrics.json`` (``frames[i].azimuth_deg``,
``flip_mean``, ``rmse``, ``psnr_db``, ``delta_e2000_mean``) and a report
in which the external images are a technique beside the truth.

The design in full: docs/internals.md, "hzval.commands.score".
"""

from __future__ import annotations

import math
import shutil
import time
from pathlib import Path

import numpy as np
from PIL import Image

from hzval.core import errors, srgb, strict
from hzval.core.errors import InputError
from hzval.io import codecs, documents, paths, staging
from hzval.metrics import brightness, compare
from hzval.metrics import facing as hzfacing
from hzval.metrics.results import raw_techniques
from hzval.pipeline import bug_match
from hzval.report import images
from hzval.report import pages as report
from hzval.scene.spec import Frame

__all__ = [
    "score",
    "write",
    "read_frame",
    "read_factor",
    "read_sidecar",
    "sampling_flip",
    "ALIASING_FLIP",
    "LABEL",
    "NAME",
    "SIDECAR",
]

#: What the report calls the scored images, unless the sidecar names them.
LABEL = "your renderer"
#: The engine's name in metrics.json (``techniques.engine``, ``frames[i].techniques.engine``) and
# ``--fail-if``.
NAME = "engine"
#: The engine's sidecar in FRAMES_DIR: its label and its own parameters.
SIDECAR = "engine.toml"
#: Said when a frames folder holds the shadow factors and no images.
F_ONLY_LINE = (
    "scored the visibility alone: the frames folder holds each light's shadow factor f_<name> and no "
    "image (add <name>.exr or .png for the image scores)"
)


def _sweep(sweep_dir: Path) -> tuple[dict, dict]:
    """Return the sweep's ``metrics.json`` and ``frames.json``."""
    out = []
    for name in ("metrics.json", "frames.json"):
        path = sweep_dir / name
        if not path.is_file():
            raise InputError(
                "--against",
                f"{sweep_dir} is not a sweep's folder (no {name}): give the --out of an hzval sweep "
                "(FRAMES_DIR holds your frames; --against the sweep they render)",
            )
        out.append(documents.read_json(path))
    return out[0], out[1]


def _check_shape(metrics, engine, sweep_dir: Path) -> None:
    """Refuse a sweep folder whose ``frames.json`` or ``metrics.json`` is not of the expected shape.

    The refusal is one line naming the file and the key. The expected shape is the one
    :func:`hzval.pipeline.sweep.run` writes (what :func:`score` reads).
    """

    def need(ok: bool, name: str, key: str, what: str) -> None:
        if not ok:
            raise InputError(sweep_dir / name, f"not a sweep's {name}: {key} must be {what}")

    def number(v) -> bool:
        return isinstance(v, (int, float)) and not isinstance(v, bool)

    need(isinstance(engine, dict), "frames.json", "the file", "a JSON object")
    # the exposure scales the engine's frames: zero, negative or infinite would make any frame pass
    need(
        number(engine.get("exposure")) and math.isfinite(engine["exposure"]) and engine["exposure"] > 0,
        "frames.json",
        "exposure",
        "a finite number > 0",
    )
    size = engine.get("image_size")
    need(
        isinstance(size, list) and len(size) == 2 and all(isinstance(v, int) and v > 0 for v in size),
        "frames.json",
        "image_size",
        "[width, height]",
    )
    frames = engine.get("frames")
    need(
        isinstance(frames, list)
        and frames
        and all(
            isinstance(f, dict)
            and isinstance(f.get("name"), str)
            and number(f.get("azimuth_deg"))
            and number(f.get("elevation_deg"))
            for f in frames
        ),
        "frames.json",
        "frames",
        "a list of {name, azimuth_deg, elevation_deg}",
    )
    need(isinstance(metrics, dict), "metrics.json", "the file", "a JSON object")
    swept = metrics.get("frames")
    need(
        isinstance(swept, list)
        and len(swept) == len(frames)
        and all(
            isinstance(f, dict)
            and isinstance(f.get("files"), dict)
            and isinstance(f["files"].get("truth"), str)
            for f in swept
        ),
        "metrics.json",
        "frames",
        f"a list of {len(frames)} frames, each with files.truth",
    )
    for key in ("material", "parameters", "exposure", "versions", "simulated", "camera", "techniques"):
        need(isinstance(metrics.get(key, {}), dict), "metrics.json", key, "an object")
    for i, f in enumerate(frames):
        paths.file_name(f["name"], sweep_dir / "frames.json", f"frames[{i}].name")
    for i, f in enumerate(swept):
        _check_stored_paths(f, sweep_dir, f"frames[{i}]")
    _check_agrees(metrics, engine, sweep_dir)


def _check_agrees(metrics: dict, engine: dict, sweep_dir: Path) -> None:
    """Refuse a ``frames.json`` whose settings that change an image are not ``metrics.json``'s.

    Those settings are the exposure, the material's digest, the effects, the samples and every frame's light.
    An edited exposure scored an engine's frames against the truth at another brightness: FLIP 0 at 646 dB.
    """
    params = metrics.get("parameters") or {}
    samples = engine.get("samples") if isinstance(engine.get("samples"), dict) else {}
    pairs = [
        ("exposure", engine.get("exposure"), (metrics.get("exposure") or {}).get("scale")),
        (
            "material.digest",
            (engine.get("material") or {}).get("digest"),
            (metrics.get("material") or {}).get("digest"),
        ),
        ("effects", engine.get("effects"), params.get("effects")),
        ("samples.spp", samples.get("spp"), params.get("spp")),
        ("samples.seed", samples.get("seed"), params.get("seed")),
    ]
    for i, (f, m) in enumerate(zip(engine["frames"], metrics["frames"])):
        pairs += [
            (f"frames[{i}].azimuth_deg", f.get("azimuth_deg"), m.get("azimuth_deg")),
            (f"frames[{i}].elevation_deg", f.get("elevation_deg"), m.get("elevation_deg")),
        ]
    for key, a, b in pairs:
        if a is None or b is None:
            continue  # an older sweep's files: what they do not record is not compared
        same = math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12) if _is_number(a) and _is_number(b) else a == b
        if not same:
            raise InputError(
                sweep_dir / "frames.json",
                f"{key} is {a!r}, the sweep's metrics.json says {b!r}: frames.json was edited or comes "
                "from another sweep (sweep again)",
            )


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _check_stored_paths(frame: dict, sweep_dir: Path, key: str) -> None:
    """Check that every file a sweep's frame names resolves inside the sweep folder.

    The files are the frame's own and its techniques' (:func:`hzval.io.paths.inside`); the check runs before
    anything is read or copied.
    """
    where = sweep_dir / "metrics.json"
    tables = [(f"{key}.files", frame["files"])]
    techniques = raw_techniques(frame)
    if techniques is None:
        raise InputError(where, f"not a sweep's metrics.json: {key}.techniques must be an object")
    for name, per in techniques.items():
        if not isinstance(per, dict) or not isinstance(per.get("files") or {}, dict):
            raise InputError(where, f"not a sweep's metrics.json: {key}.techniques.{name} must be an object")
        tables.append((f"{key}.techniques.{name}.files", per.get("files") or {}))
    for prefix, table in tables:
        for k, rel in table.items():
            if rel is not None:
                paths.inside(sweep_dir, rel, where, f"{prefix}.{k}")


def read_frame(path: Path, exposure: float, shape: tuple[int, int]) -> np.ndarray:
    """Return an engine's frame as linear radiance ``(H, W, 3)`` float32.

    EXR is read as stored (RGB, or Y as grey); PNG is decoded from sRGB and divided by the exposure.
    """
    if path.suffix.lower() == ".exr":
        img = codecs.read_rgb_exr(path)
    else:
        try:
            with Image.open(path) as im:
                depth = 65535.0 if im.mode in ("I;16", "I;16B", "I", "I;16L") else 255.0
                arr = np.asarray(im.convert("RGB") if depth == 255.0 else im, dtype=np.float64) / depth
        except OSError as exc:
            raise InputError(path, f"not a readable PNG ({errors.first_line(exc)})") from None
        arr = np.repeat(arr[..., None], 3, axis=-1) if arr.ndim == 2 else arr[..., :3]
        img = srgb.decode(arr) / exposure
    img = np.asarray(img, np.float32)
    if img.shape[:2] != tuple(shape):
        raise InputError(
            path, f"is {img.shape[1]}x{img.shape[0]}, the sweep's frames are {shape[1]}x{shape[0]}"
        )
    if not np.isfinite(img).all():
        raise InputError(path, f"has {int((~np.isfinite(img)).sum())} non-finite values (NaN or infinity)")
    return img


#: How far above the brightest radiance the scene can produce an engine's frame may go before it is
#: refused (a slip of pi, of a gamma, of sRGB twice stays far below; it gets a warning instead).
BRIGHTEST_FACTOR = 1000.0


def _bounded(path: Path, img: np.ndarray, metrics: dict) -> np.ndarray:
    _check_brightness(path, img, metrics)
    return img


def _check_brightness(path: Path, img: np.ndarray, metrics: dict) -> None:
    """Refuse a frame far brighter than the scene can be.

    The limit is ``metrics.json``'s ``exposure.max_radiance`` times :data:`BRIGHTEST_FACTOR`: such a frame's
    squared errors overflow, and no score of it means anything.
    """
    brightest = (metrics.get("exposure") or {}).get("max_radiance")
    if not _is_number(brightest) or brightest <= 0:
        return
    top = float(np.max(np.abs(img)))
    if top > BRIGHTEST_FACTOR * brightest:
        raise InputError(
            path,
            f"has radiance up to {top:.3g}, {top / brightest:.3g} times the brightest the scene can produce "
            f"({brightest:.3g}, metrics.json exposure.max_radiance): not a frame of this scene's units",
        )


def _find(frames_dir: Path, name: str, prefix: str = "", required: bool = True) -> Path | None:
    found = [frames_dir / f"{prefix}{name}{ext}" for ext in (".exr", ".png")]
    found = [p for p in found if p.is_file()]
    if len(found) == 2:
        raise InputError(
            found[0], f"and {found[1].name} are both the frame for light {name}: keep the one to score"
        )
    if found:
        return found[0]
    if not required:
        return None
    raise InputError(
        frames_dir / f"{prefix}{name}.exr", f"missing: the frame for light {name} (an .exr or .png)"
    )


def _one_value(path: Path, planes: list) -> None:
    """Refuse a shadow factor stored in colour channels that differ.

    F is one value a pixel, and reading one channel of a colour image would score something else in silence.
    """
    if len(planes) > 1 and any(not np.array_equal(planes[0], p) for p in planes[1:]):
        raise InputError(
            path, "a shadow factor is one value a pixel: its R, G and B differ (store F as grey)"
        )


def read_factor(path: Path, shape: tuple[int, int]) -> np.ndarray:
    """Return an engine's shadow factor ``F`` as ``(H, W)`` float32 in [0, 1].

    It is an EXR's one channel (Y, R or the only one), or a grey PNG's values over 255 or 65535 (data, no sRGB
    decoding).
    """
    if path.suffix.lower() == ".exr":
        ch = codecs.read_exr(path)
        key = next((k for k in ("Y", "R", "F", "V") if k in ch), next(iter(ch)) if len(ch) == 1 else None)
        if key is None:
            raise InputError(path, f"a shadow factor needs one channel (Y), has {', '.join(sorted(ch))}")
        F = np.asarray(ch[key], np.float32)
        _one_value(path, [ch[k] for k in "RGB" if k in ch])
    else:
        try:
            with Image.open(path) as im:
                depth = 65535.0 if im.mode in ("I;16", "I;16B", "I", "I;16L") else 255.0
                if im.mode in ("RGB", "RGBA", "P"):
                    rgb = np.asarray(im.convert("RGB"))
                    _one_value(path, [rgb[..., 0], rgb[..., 1], rgb[..., 2]])
                F = np.asarray(im if depth != 255.0 else im.convert("L"), np.float64) / depth
        except OSError as exc:
            raise InputError(path, f"not a readable PNG ({errors.first_line(exc)})") from None
        F = F.astype(np.float32)
    if F.shape != tuple(shape):
        raise InputError(path, f"is {F.shape[1]}x{F.shape[0]}, the sweep's frames are {shape[1]}x{shape[0]}")
    if not np.isfinite(F).all() or F.min() < -1e-6 or F.max() > 1 + 1e-6:
        raise InputError(path, "a shadow factor must be finite and in [0, 1]")
    return np.clip(F, 0.0, 1.0)


def read_sidecar(frames_dir: Path) -> dict:
    """Return ``FRAMES_DIR/engine.toml`` as ``{label, summary, parameters, path}`` (module docstring).

    Without the file, the defaults are returned. Unknown tables or keys are refused in one line
    (:mod:`hzval.core.strict`).
    """
    path = frames_dir / SIDECAR
    out = {"label": LABEL, "summary": str(frames_dir), "parameters": {}, "path": None}
    if not path.is_file():
        return out
    data = documents.read_toml(path)
    strict.check_keys(data, {"engine", "parameters"}, path)
    engine = strict.check_table(data.get("engine", {}), {"label": str, "summary": str}, path, "engine")
    params = data.get("parameters", {})
    if not isinstance(params, dict):
        raise InputError(path, f"parameters must be a table ([parameters]), got {params!r}")
    return {**out, **engine, "parameters": params, "path": str(path)}


def _normal(sweep_dir: Path, metrics: dict) -> np.ndarray | None:
    """Return the sweep's normal map for the facing pixels.

    The map is ``bake/normal.exr`` (``(rows, cols, 3)``), returned if the sweep kept its bake and its view is
    ``top``.
    """
    if (metrics.get("camera") or {}).get("kind", "top") != "top":
        return None
    path = sweep_dir / "bake" / "normal.exr"
    if not path.is_file():
        return None
    ch = codecs.read_exr(path)
    keys = [k for k in ("X", "Y", "Z") if k in ch] or [k for k in ("R", "G", "B") if k in ch]
    return np.stack([ch[k] for k in keys], axis=-1) if len(keys) == 3 else None


def unexpected_files(frames_dir: Path, names: list[str]) -> list[str]:
    """Return the files of ``frames_dir`` that ``score`` would ignore.

    Those are the files that are none of ``<name>.exr|png``, ``f_<name>.exr|png`` (``names``: the sweep's
    frames) or :data:`SIDECAR`; hidden files and folders (a report inside it) aside.

    Parameters
    ----------
    frames_dir : pathlib.Path
    names : list of str
        The frame names of the sweep's ``frames.json``.

    Returns
    -------
    list of str
        Their names, sorted.
    """
    expected = {SIDECAR} | {f"{p}{n}{e}" for n in names for p in ("", "f_") for e in (".exr", ".png")}
    return sorted(
        p.name
        for p in frames_dir.iterdir()
        if p.is_file() and not p.name.startswith(".") and p.name not in expected
    )


def _check_every_light(frames_dir: Path, names: list[str], found: list, prefix: str, ignored: list[str]):
    """Refuse, in one line, frames for some lights only.

    The line names the lights that have none and the files that match no light's name (a misnamed
    ``az+30_F.exr`` is named, not a light it is not).
    """
    missing = [n for n, p in zip(names, found) if p is None]
    if not missing:
        return
    what = "image" if not prefix else "shadow factor"
    lights = ", ".join(missing[:4]) + (" ..." if len(missing) > 4 else "")
    stray = (
        f"; {', '.join(ignored[:3])} {'match' if len(ignored) > 1 else 'matches'} no light's name"
        if ignored
        else ""
    )
    raise InputError(
        frames_dir / f"{prefix}{missing[0]}.exr",
        f"missing: no {what} for {len(missing)} of {len(names)} lights ({lights}){stray} (expected "
        f"{prefix}<name>.exr or .png, with the names of frames.json: {', '.join(names[:3])}"
        f"{' ...' if len(names) > 3 else ''})",
    )


def _ignored_line(frames_dir: Path, ignored: list[str], names: list[str]) -> str:
    shown = ", ".join(ignored[:4]) + (" ..." if len(ignored) > 4 else "")
    return (
        f"{frames_dir}: {len(ignored)} files match no frame and are ignored ({shown}); expected "
        f"<name>.exr or .png and, for F, f_<name>.exr per light, with the names of frames.json "
        f"({', '.join(names[:3])}{' ...' if len(names) > 3 else ''})"
    )


def score(
    frames_dir: str | Path, sweep_dir: str | Path, *, strict: bool = False
) -> tuple[dict, list[tuple[str, dict, dict]]]:
    """Score every frame of ``frames_dir`` against ``sweep_dir``'s truth, beside the sweep's techniques.

    Returns ``(result, maps)``: the ``metrics.json`` content (without the
    report) and, per frame, ``(name, the sweep's frame, maps)`` for
    :func:`write`. Every frame is read and checked before any is scored. Files that match no
    frame (:func:`unexpected_files`) are a warning naming them, or with ``strict`` an error.
    """
    frames_dir, sweep_dir = Path(frames_dir), Path(sweep_dir)
    if not frames_dir.is_dir():
        raise InputError(frames_dir, "no such folder of frames")
    metrics, engine = _sweep(sweep_dir)
    _check_shape(metrics, engine, sweep_dir)
    sidecar = read_sidecar(frames_dir)
    names = [f["name"] for f in engine["frames"]]
    ignored = unexpected_files(frames_dir, names)
    if ignored and strict:
        raise InputError("--strict", _ignored_line(frames_dir, ignored, names))
    exposure = float(engine["exposure"])
    W, H = engine["image_size"]
    factors = [_find(frames_dir, f["name"], "f_", required=False) for f in engine["frames"]]
    images = [_find(frames_dir, n, required=False) for n in names]
    # F alone (no image for any light): the visibility scores only
    f_only = any(factors) and not any(images)
    _check_every_light(frames_dir, names, factors if f_only else images, "f_" if f_only else "", ignored)
    todo = [(f, None if f_only else p, fp) for f, p, fp in zip(engine["frames"], images, factors)]
    given = [t for t in todo if t[2] is not None]
    if given and len(given) < len(todo):
        missing = next(f["name"] for f, _, fp in todo if fp is None)
        raise InputError(
            frames_dir / f"f_{missing}.exr",
            f"missing: F is given for {len(given)} of {len(todo)} "
            "lights (give f_<name>.exr for every light, or none)",
        )
    loaded = [
        (
            f,
            p,
            None if p is None else _bounded(p, read_frame(p, exposure, (H, W)), metrics),
            None if fp is None else read_factor(fp, (H, W)),
            fp,
        )
        for f, p, fp in todo
    ]
    normal = _normal(sweep_dir, metrics) if given else None
    t0 = time.perf_counter()
    frames, maps, warnings = [], [], []
    for (f, path, img, F, fpath), swept in zip(loaded, metrics["frames"]):
        frame, image_maps, warning = _score_frame(
            sweep_dir, metrics, engine, f, path, img, F, fpath, swept, normal
        )
        frames.append(frame)
        maps.append((f["name"], swept, image_maps))
        warnings += [warning] if warning else []
    match = _tangent_bug(metrics, sweep_dir, [F for _, _, _, F, _ in loaded]) if given else None
    techniques = {
        NAME: {
            "label": sidecar["label"],
            "summary": sidecar["summary"],
            "file_stem": NAME,
            "parameters": sidecar["parameters"],
            "parameters_from": sidecar["path"],
            "simulated": list((metrics.get("parameters") or {}).get("effects", [])),
        },
        **{k: v for k, v in (raw_techniques(metrics) or {}).items() if k != NAME},
    }
    result = {
        "material": metrics.get("material", {}),
        "against": str(sweep_dir),
        "frames_dir": str(frames_dir),
        "parameters": metrics.get("parameters", {}),
        "exposure": metrics.get("exposure", {}),
        "camera": metrics.get("camera", {}),
        "versions": metrics.get("versions", {}),
        "timings": {"score_s": time.perf_counter() - t0},
        "simulated": {**metrics.get("simulated", {}), NAME: techniques[NAME]["simulated"]},
        "techniques": techniques,
        "warnings": ([_ignored_line(frames_dir, ignored, names)] if ignored else [])
        + ([F_ONLY_LINE] if f_only else [])
        + _brightness_summary(warnings)
        + [w for w in (_sampling_warning(frames),) if w],
        "frames": frames,
    }
    if match is not None:
        result["tangent_bug"] = match
        result["warnings"] += [match["line"]] if match["named"] else []
    return result, maps


def _tangent_bug(metrics: dict, sweep_dir: Path, factors: list) -> dict | None:
    """Return the tangent-frame bug that the engine's F matches, on a model's sweep.

    See :mod:`hzval.pipeline.bug_match`.
    """
    return bug_match.diagnose(metrics, sweep_dir, factors)


def _score_frame(sweep_dir, metrics, engine, f, path, img, F, fpath, swept, normal):
    """Score one light: the engine's scores beside the sweep's techniques' own.

    The engine's scores are the image's and, with F, the visibility's, whole and facing. Returns ``(frame,
    maps, brightness warning or None)``.
    """
    exposure = float(engine["exposure"])
    # R, G, B or (the sweep's grey truth) Y, in half float: see the module's docstring
    truth = Frame(
        f["azimuth_deg"], f["elevation_deg"], codecs.read_rgb_exr(sweep_dir / swept["files"]["truth"])
    )
    if img is None:  # F alone: no image to score
        scores, image_maps = dict.fromkeys(compare.IMAGE_METRICS), {}
    else:
        scores, image_maps = compare.image_metrics(compare.Reference(truth, exposure), img)
    own = {k: (None if isinstance(v, float) and not np.isfinite(v) else v) for k, v in scores.items()}
    vis = swept["files"].get("visibility")
    if F is not None and vis:
        V = codecs.read_exr(sweep_dir / vis)["Y"].astype(np.float32)
        own.update(
            zip(
                ("visibility_mae", "leak_fraction", "false_shadow_fraction"),
                (float(v) for v in compare.visibility_metrics(V, F, np.isfinite(V))),
            )
        )  # a model's
        # sweep leaves the pixels that see no surface NaN in V: scored over the seen ones, as the sweep did
        if normal is not None:
            ss = int((metrics.get("parameters") or {}).get("supersampling") or 1)
            own.update(hzfacing.facing_metrics(V, F, hzfacing.facing_mask(normal, f["light_direction"], ss)))
        image_maps = {**image_maps, "V": V, "F": F}
    own["files"] = {}
    per = {
        NAME: own,
        **{
            k: {kk: vv for kk, vv in v.items()} for k, v in (raw_techniques(swept) or {}).items() if k != NAME
        },
    }
    frame = {
        "name": f["name"],
        "azimuth_deg": f["azimuth_deg"],
        "elevation_deg": f["elevation_deg"],
        **{k: own[k] for k in compare.IMAGE_METRICS},
        "file": None if path is None else str(path),
        **({"factor_file": str(fpath)} if fpath is not None else {}),
        "truth_s": swept.get("truth_s"),
        **({"floor": swept["floor"]} if "floor" in swept else {}),
        **({"no_shadows": swept["no_shadows"]} if "no_shadows" in swept else {}),
        **({"truth": swept["truth"]} if "truth" in swept else {}),
        "techniques": per,
    }
    slip = None if img is None else brightness.diagnose(img, truth.image, exposure, png=path.suffix == ".png")
    if slip:
        frame["brightness"] = slip
    sampling = None if img is None else sampling_flip(sweep_dir, swept, img, exposure, F)
    if sampling is not None:
        frame["sampling"] = sampling
    return frame, image_maps, None if slip is None else (f["name"], slip)


#: How much more than the sweep's own technique an engine's frame may differ from the sweep's
#: unshadowed shading where both are fully lit, in FLIP, before ``score`` says it aliases.
ALIASING_FLIP = 0.005


def sampling_flip(sweep_dir: Path, swept: dict, img: np.ndarray, exposure: float, F) -> dict | None:
    """Return how far, in mean FLIP, the engine's frame is from the sweep's unshadowed shading.

    The unshadowed shading is ``plain.png`` (the sweep's own samples); the comparison is on the pixels the
    truth lights fully (and the engine, where its F is given). It sits beside the same for the sweep's lead
    technique: shadows cannot differ there, so what does is the sampling (or the shading). The result is
    ``{engine, sweep, technique}``; ``None`` where the sweep kept no such files.
    """
    files_ = swept.get("files") or {}
    techniques = raw_techniques(swept) or {}
    lead = next((n for n, t in techniques.items() if (t.get("files") or {}).get("png")), None)
    if not files_.get("plain_png") or not files_.get("visibility") or lead is None:
        return None
    V = codecs.read_exr(sweep_dir / files_["visibility"])["Y"]
    lit = V >= 1.0
    if F is not None:
        lit &= F >= 1.0
    own_F = techniques[lead]["files"].get("factor")
    own_lit = lit if own_F is None else lit & (next(iter(codecs.read_exr(sweep_dir / own_F).values())) >= 1.0)
    if lit.sum() < 64 or own_lit.sum() < 64:
        return None
    plain = _display_png(sweep_dir / files_["plain_png"])
    flip_map = compare.flip(plain, compare.display(img, exposure))[0]
    own = compare.flip(plain, _display_png(sweep_dir / techniques[lead]["files"]["png"]))[0]
    return {"engine": float(flip_map[lit].mean()), "sweep": float(own[own_lit].mean()), "technique": lead}


def _display_png(path: Path) -> np.ndarray:

    with Image.open(path) as im:
        arr = np.asarray(im.convert("RGB"), np.float64) / 255.0
    return arr


def _sampling_warning(frames: list[dict]) -> str | None:
    """Return one line where the engine's frames alias more than the sweep's own technique.

    See :func:`sampling_flip`.
    """
    found = [f["sampling"] for f in frames if f.get("sampling")]
    if not found:
        return None
    engine = sum(x["engine"] for x in found) / len(found)
    sweep = sum(x["sweep"] for x in found) / len(found)
    if engine - sweep <= ALIASING_FLIP:
        return None
    return (
        f"the frames differ from the sweep's unshadowed shading by FLIP {engine:.3f} on the pixels both "
        f"light fully, the sweep's own {found[0]['technique']} by {sweep:.3f}: about {engine - sweep:.3f} "
        "of the engine's FLIP is its sampling (aliasing), not its shadows; render frames.json's samples "
        "per pixel, or compare shadows by |F - V| (f_<name>.exr)"
    )


def _brightness_summary(found: list) -> list[str]:
    """One line per cause of the frames off the truth's brightness (:mod:`hzval.metrics.brightness`)."""
    lines = []
    for slip in dict.fromkeys(s["slip"] for _, s in found):
        names = [n for n, s in found if s["slip"] == slip]
        first = next(s for _, s in found if s["slip"] == slip)
        lines.append(
            f"{len(names)} frame(s) ({', '.join(names[:4])}{' ...' if len(names) > 4 else ''}) "
            f"{first['line']} (mean brightness {first['ratio']:.3g}x the truth's)"
        )
    return lines


def write(
    result: dict, maps: list, out: str | Path, *, command: str = "", force: bool = False, gates=None
) -> Path:
    """Write ``out/metrics.json`` and ``out/index.html`` and return the index.

    The report shows the engine's images as the lead technique beside the sweep's truth and the sweep's
    techniques (whose images are copied in, so the report stands alone). The folder is held while they are
    written (:func:`hzval.io.staging.output_folder`); ``gates`` (:class:`hzval.commands.gates.Gates`) are
    tested first and listed at the top of the report.
    """
    out = Path(out)
    if gates:
        gates.apply(result)
    # all or nothing, as the sweep: written into a staging folder inside out and swapped in whole, so
    # a failure or an interrupt leaves an earlier report byte for byte, and no link in out is followed
    with staging.swapped_in(out, force=force) as work:
        _write(result, maps, out, work, command)
    return out / "index.html"


def _copy(sweep_dir: Path, stage: Path, name: str, rel: str | None) -> str | None:
    """Copy a sweep's file into ``frames/<name>/`` of the staged report; return its path relative to it.

    The file was checked inside the sweep by :func:`score`.
    """
    if not rel or not (sweep_dir / rel).is_file():
        return None
    dst = f"frames/{name}/{Path(rel).name}"
    (stage / dst).parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(sweep_dir / rel, stage / dst)
    return dst


def _write(result: dict, maps: list, out: Path, stage: Path, command: str) -> Path:
    """Write the report's files into ``stage``, with their recorded paths relative to ``out``.

    ``out`` is where they land.
    """
    sweep_dir = Path(result["against"])
    for frame, (name, swept_frame, image_maps) in zip(result["frames"], maps):
        frame["files"] = {
            k: d
            for k in ("truth_png", "plain_png", "visibility_png")
            if (d := _copy(sweep_dir, stage, name, swept_frame["files"].get(k)))
        }
        own = {}
        if "display" in image_maps:  # not when F alone was given
            own = {"png": f"frames/{name}/{NAME}.png", "flip_png": f"frames/{name}/{NAME}_flip.png"}
            codecs.write_png(stage / own["png"], codecs.unit_to_u8(image_maps["display"]))
            codecs.write_png(stage / own["flip_png"], images.flip_image(image_maps["flip"]))
        if "F" in image_maps:
            own["visdiff_png"] = f"frames/{name}/{NAME}_visdiff.png"
            codecs.write_png(
                stage / own["visdiff_png"], images.visibility_diff_image(image_maps["V"], image_maps["F"])
            )
        scored = raw_techniques(frame) or {}
        scored[NAME]["files"] = own
        for tname, per in scored.items():
            if tname != NAME:
                theirs = (raw_techniques(swept_frame) or {}).get(tname, {}).get("files") or {}
                per["files"] = {
                    k: d
                    for k in ("png", "flip_png", "visdiff_png")
                    if (d := _copy(sweep_dir, stage, name, theirs.get(k)))
                }
    index = report.write_report(stage, result, command=command)
    # the paths relative to the report's folder: a shared report carries no absolute folders
    portable = {
        **result,
        "against": staging.report_path(result["against"], out),
        "frames_dir": staging.report_path(result["frames_dir"], out),
        "frames": [
            {
                **f,
                "file": f["file"] and staging.report_path(f["file"], out),
                **({"factor_file": staging.report_path(f["factor_file"], out)} if "factor_file" in f else {}),
            }
            for f in result["frames"]
        ],
    }
    if "gates" in portable and portable["gates"].get("baseline"):
        portable["gates"] = {
            **portable["gates"],
            "baseline": staging.report_path(portable["gates"]["baseline"], out),
        }
    documents.write_json(stage / "metrics.json", portable)
    return index
