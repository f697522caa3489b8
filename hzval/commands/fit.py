"""``hzval fit``: a technique's textures fitted to the truth, written in the bake's layout.

:func:`fit_horizon` fits the horizon map (:mod:`hzval.techniques.fitted.fit`), :func:`fit_technique`
a per-pixel technique's textures (:mod:`hzval.techniques.fitted.textures`); each writes its files
and ``fit.json`` with the key a sweep's cache reuses them by
(:func:`hzval.techniques.fitted.store.cache_key`).
"""

from __future__ import annotations

from pathlib import Path

from hzval.techniques.fitted import fit as horizon_fit
from hzval.techniques.fitted import store as fitted_store
from hzval.techniques.fitted import textures as fitted_textures
from hzval.techniques.horizon import Horizon

__all__ = ["HORIZON", "fit_horizon", "fit_technique", "summary"]

#: ``--technique``'s name for the horizon map (the registry's ``horizon``).
HORIZON = Horizon.name


def fit_horizon(height, baked, scene, info: dict, out: Path, *, options: dict, progress: bool = True):
    """Fit a bake's horizon map and write it to ``out``.

    Parameters
    ----------
    height : numpy.ndarray
        The normalised height map.
    baked : hzval.bake.maps.Bake
        Its bake.
    scene : hzval.scene.spec.Scene
        The scene.
    info : dict
        What ``fit.json`` records of the input.
    out : pathlib.Path
        The folder.
    options : dict
        :func:`hzval.techniques.fitted.fit.fit`'s keywords (``lights`` and ``held_out`` as typed).
    progress : bool
        Show progress bars.

    Returns
    -------
    hzval.techniques.fitted.fit.FitResult
    """
    result = horizon_fit.fit(height, baked, scene, progress=progress, **options)
    keyed = {k: v for k, v in options.items() if k != "guard" or v is not None}
    key = fitted_store.cache_key(height, baked, scene, keyed)
    fitted_store.write_fit(result, out, input_info={**info, "key": key})
    return result


def fit_technique(
    height, baked, scene, name: str, info: dict, out: Path, *, options: dict, progress: bool = True
):
    """Fit a per-pixel technique's textures and write them to ``out``.

    Parameters
    ----------
    height, baked, scene, info, out, progress
        As :func:`fit_horizon`.
    name : str
        The technique (:func:`hzval.techniques.fitted.textures.fittable`).
    options : dict
        :func:`hzval.techniques.fitted.textures.fit_textures`'s keywords.

    Returns
    -------
    hzval.techniques.fitted.textures.TextureFit
    """
    result = fitted_textures.fit_textures(height, baked, scene, name, progress=progress, **options)
    key = fitted_store.cache_key(height, baked, scene, {"technique": name, **options})
    fitted_store.write_texture_fit(result, out, input_info={**info, "key": key})
    return result


def summary(mae: dict, scope: str = "") -> str:
    """``training |F-V| 0.0524 baked -> 0.0306 fitted; held_out ...``: one line's figures; ``scope``
    says what the means are over where it is not the pixels facing the light (the horizon fit's:
    ``" (whole image)"``)."""
    return "; ".join(
        f"{w} |F-V|{scope} {m['baked']:.4f} baked -> {m['fitted']:.4f} fitted" for w, m in mae.items()
    )
