"""A fit kept on disk, and the cache a sweep reuses a fit from.

The fit's files are in the bake's layout, with ``fit.json`` (:func:`write_fit`, :func:`read_fit`); the cache
is :func:`cache_key` and :func:`cached_fit`.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from hzval.core import backend
from hzval.core import conventions as cv
from hzval.core.errors import InputError
from hzval.io import codecs, documents, paths, staging
from hzval.techniques import registry as technique
from hzval.techniques.fitted import fit, textures

__all__ = [
    "FIT_VERSION",
    "write_fit",
    "read_fit",
    "write_texture_fit",
    "read_texture_fit",
    "cache_key",
    "cached_fit",
    "cached_texture_fit",
]

#: Bumped when the fit changes what it finds: a cached fit of another version is made anew.
FIT_VERSION = 2


def write_fit(result: fit.FitResult, out: str | Path, *, input_info: dict) -> list[Path]:
    """Write a fit, all or nothing: its horizon maps and ``fit.json``.

    The maps are ``horizon0.exr``, ``horizon1.exr`` (and 8-bit PNGs) in :func:`hzval.bake.maps.write_bake`'s
    layout.

    Parameters
    ----------
    result : FitResult
        The fit.
    out : str or path-like
        The folder.
    input_info : dict
        What ``fit.json`` records of the input (the material, the bake, the cache key).

    Returns
    -------
    list of pathlib.Path
        The files written.
    """
    layers = [
        result.horizon[..., c : c + cv.CHANNELS_PER_LAYER]
        for c in range(0, result.horizon.shape[-1], cv.CHANNELS_PER_LAYER)
    ]
    images = {f"horizon{i}": ({"RGBA": layer}, layer) for i, layer in enumerate(layers)}
    return _write(out, images, result.record(), input_info)


def _write(out, images: dict, record: dict, input_info: dict) -> list[Path]:
    """Write ``NAME.exr`` and ``NAME.png`` of each image, and ``fit.json``, all or nothing.

    ``images[NAME]`` is ``(EXR channels, PNG values in [0, 1])``; ``fit.json`` holds ``record``, the input,
    the versions and every file's digest.
    """
    with staging.Staging(out) as stage:
        for name, (channels, shown) in images.items():
            codecs.write_exr(stage.path(f"{name}.exr"), channels, atomic=False, compression="none")
            codecs.write_png(stage.path(f"{name}.png"), codecs.unit_to_u8(shown), atomic=False)
        digests = {
            p.relative_to(stage.dir).as_posix(): staging.file_digest(p)
            for p in sorted(stage.dir.rglob("*"))
            if p.is_file()
        }
        documents.write_json(
            stage.path("fit.json"),
            {"input": input_info, **record, "versions": backend.versions(), "files": digests},
            atomic=False,
        )
        return stage.commit()


def read_fit(folder: str | Path) -> tuple[np.ndarray, dict]:
    """Return a fit written by :func:`write_fit`.

    Parameters
    ----------
    folder : str or path-like
        Its folder.

    Returns
    -------
    sines : numpy.ndarray
        ``(rows, cols, D)`` float32, from the EXRs.
    record : dict
        ``fit.json``.

    Raises
    ------
    hzval.core.errors.InputError
        For a missing or malformed ``fit.json``.
    """
    folder = Path(folder)
    record = documents.read_json(folder / "fit.json")
    layers = [
        codecs.read_exr(folder / f"horizon{i}.exr")
        for i in range(len([n for n in record["files"] if n.endswith(".exr")]))
    ]
    return np.stack([layer[c] for layer in layers for c in "RGBA"], axis=-1), record


def write_texture_fit(result, out: str | Path, *, input_info: dict) -> list[Path]:
    """Write a texture fit (:class:`hzval.techniques.fitted.textures.TextureFit`), all or nothing.

    The files are ``<texture>.exr`` (one channel ``Y``, or ``RGB``) and an 8-bit PNG of each, and
    ``fit.json``.

    Parameters
    ----------
    result : hzval.techniques.fitted.textures.TextureFit
        The fit.
    out : str or path-like
        The folder.
    input_info : dict
        What ``fit.json`` records of the input.

    Returns
    -------
    list of pathlib.Path
        The files written.
    """
    images = {}
    for t, plane in result.planes.items():
        channels = {"Y": plane} if plane.ndim == 2 else {"RGB": plane}
        signed = technique.get(result.technique).texture(t).signed  # a unit vector: 0.5 + 0.5 v
        images[t.replace("-", "_")] = (channels, 0.5 + 0.5 * plane if signed else plane)
    return _write(out, images, result.record(), input_info)


def read_texture_fit(folder: str | Path) -> tuple[dict, dict]:
    """Return a texture fit written by :func:`write_texture_fit`: ``(planes by texture, fit.json)``.

    Parameters
    ----------
    folder : str or path-like
        Its folder.

    Returns
    -------
    tuple
        ``({texture: float32 array}, record)``.
    """
    folder = Path(folder)
    record = documents.read_json(folder / "fit.json")
    planes = {}
    for t in record["textures"]:
        layers = codecs.read_exr(folder / f"{t.replace('-', '_')}.exr")
        planes[t] = layers["Y"] if "Y" in layers else np.stack([layers[c] for c in "RGB"], axis=-1)
    return planes, record


def cache_key(height: np.ndarray, bake, scene, settings: dict) -> str:
    """Return the digest a cached fit is reused by.

    Parameters
    ----------
    height : numpy.ndarray
        The normalised height map.
    bake : hzval.bake.maps.Bake
        Its bake (its parameters).
    scene : hzval.scene.spec.Scene
        The scene (its samples, lookup and supersampling).
    settings : dict
        The fit's own settings.

    Returns
    -------
    str
        A SHA-256 hex digest of all of them and :data:`FIT_VERSION`.
    """
    h = hashlib.sha256(np.ascontiguousarray(height, np.float32).tobytes())
    meta = {
        "bake": bake.params.record(),
        "spp": scene.spp,
        "seed": scene.seed,
        "lookup": repr(scene.lookup),
        "supersampling": scene.camera.supersampling,
        "fit": settings,
        "version": FIT_VERSION,
    }
    h.update(json.dumps(meta, sort_keys=True, default=str).encode())
    return h.hexdigest()


def cached_fit(
    height: np.ndarray, bake, scene, folder: str | Path | None, *, progress: bool = False, **settings
) -> tuple[fit.FitResult | None, np.ndarray, dict, bool]:
    """Return the fit in ``folder`` when its key and file digests match, else a new one written there.

    Parameters
    ----------
    height, bake, scene
        As :func:`fit`.
    folder : str or path-like or None
        The cache's folder (``None``: fit and keep nothing). A missing, damaged or hand-edited cache is
        fitted anew; nothing outside the folder is read.
    progress : bool
        Show progress bars.
    **settings
        :func:`fit`'s keywords.

    Returns
    -------
    tuple
        ``(result or None, sines, record, cached)``: ``result`` is ``None`` for a cached fit.
    """
    key = cache_key(height, bake, scene, settings)
    if _holds(folder, key):
        sines, record = read_fit(folder)
        return None, sines, record, True
    result = fit.fit(height, bake, scene, progress=progress, **settings)
    record = result.record()
    if folder is not None:
        write_fit(result, folder, input_info={"key": key})
    return result, result.horizon, record, False


def _holds(folder, key: str) -> bool:
    """Whether ``folder`` holds the fit of ``key``, every file as written.

    A missing, damaged or hand-edited cache does not; nothing outside the folder is read.
    """
    if folder is None:
        return False
    folder = Path(folder)
    try:
        record = documents.read_json(folder / "fit.json")
        return record["input"]["key"] == key and all(
            staging.file_digest(paths.inside(folder, n, folder / "fit.json", "files")) == d
            for n, d in record["files"].items()
        )
    except (InputError, OSError, ValueError, KeyError, TypeError, AttributeError):
        return False


def cached_texture_fit(
    height: np.ndarray,
    bake,
    scene,
    folder: str | Path | None,
    name: str,
    *,
    progress: bool = False,
    **settings,
) -> tuple[dict, dict, bool]:
    """Return a technique's texture fit from ``folder``, else a new one written there.

    The cached fit is taken when its key and file digests match (:func:`cached_fit`'s rules).

    Parameters
    ----------
    height, bake, scene
        As :func:`hzval.techniques.fitted.textures.fit_textures`.
    folder : str or path-like or None
        The cache's folder (``None``: keep nothing).
    name : str
        The technique.
    progress : bool
        Show progress bars.
    **settings
        :func:`hzval.techniques.fitted.textures.fit_textures`'s keywords.

    Returns
    -------
    tuple
        ``(planes, record, cached)``.
    """
    key = cache_key(height, bake, scene, {"technique": name, **settings})
    if _holds(folder, key):
        planes, record = read_texture_fit(folder)
        return planes, record, True
    result = textures.fit_textures(height, bake, scene, name, progress=progress, **settings)
    if folder is not None:
        write_texture_fit(result, folder, input_info={"key": key})
    return result.planes, result.record(), False
