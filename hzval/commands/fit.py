"""``hzval fit``: a technique's textures fitted to the truth, written in the bake's layout.

:func:`fit_horizon` fits the horizon map (:mod:`hzval.techniques.fitted.fit`), :func:`fit_technique`
a per-pixel technique's textures (:mod:`hzval.techniques.fitted.textures`); each writes its files
and ``fit.json`` with the key a sweep's cache reuses them by
(:func:`hzval.techniques.fitted.store.cache_key`).
"""

from __future__ import annotations

from pathlib import Path

from hzval.bake import maps as bake
from hzval.io import staging
from hzval.scene import spec as sc
from hzval.techniques.fitted import fit
from hzval.techniques.fitted import store as fitted_store
from hzval.techniques.fitted import textures as fitted_textures
from hzval.techniques.fitted import training as fitted_training
from hzval.techniques.horizon import Horizon
from hzval.truth import memory

__all__ = ["HORIZON", "fit_horizon", "fit_technique", "run", "summary"]

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
    result = fit.fit(height, baked, scene, progress=progress, **options)
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
    """Return one line's figures: each set's mean |F-V|, baked against fitted.

    For example ``training |F-V| 0.0524 baked -> 0.0306 fitted; held_out ...``. ``scope`` says what the means
    are over where it is not the pixels facing the light (the horizon fit's: ``" (whole image)"``).
    """
    return "; ".join(
        f"{w} |F-V|{scope} {m['baked']:.4f} baked -> {m['fitted']:.4f} fitted" for w, m in mae.items()
    )


def run(scene, params, technique: str, out: Path, *, lights, held_out, options: dict, what: str, **kw):
    """Bake ``scene``'s material with ``params``, fit ``technique``'s textures and write them to ``out``.

    Parameters
    ----------
    scene : hzval.scene.spec.Scene
    params : hzval.bake.maps.BakeParams
    technique : str
        :data:`HORIZON`, or a name of :func:`hzval.techniques.fitted.textures.fittable`.
    out : pathlib.Path
        The output folder (:func:`hzval.io.staging.output_folder`; ``force`` in ``kw``).
    lights, held_out : sequence of (elevation, azimuth)
        The training and the held-out lights, degrees (only their number is used here: the memory
        check); ``options`` carries them as the user gave them.
    options : dict
        :func:`fit_horizon`'s or :func:`fit_technique`'s ``options``.
    what : str
        The file or flag an error names.
    **kw
        ``force`` and ``progress``.

    Returns
    -------
    tuple
        ``(result, info)``: the fit's result and the material's record.
    """
    rows, cols = memory.material_shape(scene)
    bake.check_fits(what, rows, cols, params)
    guarded = technique == HORIZON and options.get("guard") is not None
    renders = len(lights) * (2 if guarded else 1) + len(held_out)
    fitted_training.check_fits(what, rows, cols, scene.spp, renders, scene)
    progress = kw.get("progress", True)
    with staging.output_folder(out, force=kw.get("force", False)):
        height, info = sc.material_record(scene)
        baked = bake.bake(height, params)
        info = {**info, "depth": params.depth, "boundary": params.boundary, "bake": params.record()}
        if technique == HORIZON:
            result = fit_horizon(height, baked, scene, info, out, options=options, progress=progress)
        else:
            result = fit_technique(
                height, baked, scene, technique, info, out, options=options, progress=progress
            )
    return result, info
