"""The per-pixel techniques with their textures fitted to the truth: ``NAME-fit`` beside ``NAME``.

Each renders as its technique does, from the textures :func:`hzval.techniques.fitted.textures.fit_textures`
finds on the training lights (:data:`hzval.techniques.fitted.training.TRAINING_LIGHTS`) at the sweep's
own samples, in the technique's storage, cached in the sweep's ``fit/<file_stem>/`` by the digest of
:func:`hzval.techniques.fitted.store.cache_key`. Beside the shipped technique a frame's error splits
into what the bake loses (shipped minus fitted) and what the representation cannot hold (the
fitted error, its floor), over the pixels facing the light. Opt-in, as ``horizon-fit`` is.
"""

from __future__ import annotations

import dataclasses
from typing import ClassVar

import numpy as np

from hzval.scene.spec import Scene
from hzval.techniques.bent_cone import BentCone
from hzval.techniques.fitted import store as fitted_store
from hzval.techniques.fitted import training as fitted_training
from hzval.techniques.microshadow_filament import MicroshadowFilament
from hzval.techniques.microshadow_hdrp import MicroshadowHDRP
from hzval.techniques.registry import Context
from hzval.techniques.ssbump import SSBump

__all__ = ["FittedTextures", "FittedFilament", "FittedHDRP", "FittedBentCone", "FittedSSBump", "split"]

#: The score a split reads: the headline ``|F - V|`` over the pixels facing the light.
SCORE = "visibility_mae_facing"


def split(shipped: dict | None, fitted: dict | None, key: str = SCORE) -> dict:
    """Return a frame's ``split`` of the shipped technique's error.

    It holds ``bake_loss`` (shipped minus fitted) and ``representation`` (the fitted error); ``{}`` without
    both scores.

    Examples
    --------
    >>> split({"visibility_mae_facing": 0.12}, {"visibility_mae_facing": 0.05})["split"]["bake_loss"]
    0.07
    """
    if not shipped or not fitted or shipped.get(key) is None or fitted.get(key) is None:
        return {}
    return {"split": {"bake_loss": round(shipped[key] - fitted[key], 12), "representation": fitted[key]}}


class FittedTextures:
    """The mix-in of a ``NAME-fit`` technique: its textures are the fit's (module docstring)."""

    #: The shipped technique whose textures are fitted.
    fitted_from: ClassVar[type]
    by_default = False
    not_on_models = "the fit trains on the plane's top view (docs/fit.md)"
    split_parts = (
        ("representation", "what the representation cannot hold (fitted |F−V|, facing pixels)"),
        ("bake_loss", "what the bake loses (shipped − fitted |F−V|)"),
    )
    fitted: dict | None = None
    fit_record: dict | None = None

    def __init_subclass__(cls, **kw):
        """Name the shipped technique a fitted subclass fits (``fit_of``)."""
        super().__init_subclass__(**kw)
        cls.fit_of = cls.fitted_from.name

    @classmethod
    def bake_needs(cls, scene: Scene) -> frozenset[str]:
        """Return the textures it starts from, and the height map the truth it fits to is traced from."""
        return super().bake_needs(scene) | {"height"}

    @classmethod
    def build(
        cls,
        ctx: Context,
        *,
        lights: str = fitted_training.TRAINING_LIGHTS,
        held_out: str = fitted_training.HELD_OUT_LIGHTS,
        **settings,
    ):
        """Build the technique from a context, its textures fitted or read from the cache.

        ``lights``/``held_out``: the fit's training and held-out lights; ``settings``: the shipped technique's
        (its storage and variant, which the fit keeps).
        """
        folder = None if ctx.cache is None else ctx.cache / cls.file_stem
        planes, record, cached = fitted_store.cached_texture_fit(
            ctx.height,
            ctx.bake,
            ctx.scene,
            folder,
            cls.fitted_from.name,
            settings=settings,
            lights=lights,
            held_out=held_out,
        )
        own = super().build(ctx, **settings)
        own.fitted = planes
        own.fit_record = {
            "cached": cached,
            "mae": {w: {k: v for k, v in m.items() if k != "per_light"} for w, m in record["mae"].items()},
            "steps": record["options"].get("steps"),
            "epochs": record["epochs"],
            "converged": record["converged"],
            "seconds": record["seconds"],
        }
        return own

    def plane(self, name: str) -> np.ndarray:
        """Return texture ``name``: the fitted one once the fit has run, else the bake's."""
        return self.fitted[name] if self.fitted is not None else super().plane(name)

    def plane_name(self, name: str) -> str:
        """Return the fitted planes are its own, never shared with the shipped technique's."""
        return f"{super().plane_name(name)}:{self.name}"

    def stored_plane(self, name: str) -> np.ndarray:
        """Return the fit's planes are what the GPU samples already (the storage, decoded)."""
        return (
            np.asarray(self.plane(name), np.float32)
            if self.fitted is not None
            else super().stored_plane(name)
        )

    @classmethod
    def check_settings(cls, bake_params, settings: dict) -> None:
        """Run the shipped technique's checks, the fit's lights aside."""
        own = {k: v for k, v in settings.items() if k not in ("lights", "held_out")}
        super().check_settings(bake_params, own)
        for key in ("lights", "held_out"):
            if settings.get(key):
                fitted_training.parse_lights(settings[key], key)

    @classmethod
    def check_variants(cls) -> list:
        """Return no check variants: the regression check guards the shipped technique."""
        return []  # the regression check guards the shipped technique; a fit is its study

    @classmethod
    def tradeoff_variants(cls) -> list:
        """Return the shipped technique's storages, each fitted (``hzval tradeoff --fits``)."""
        shipped = cls.fitted_from
        return [
            dataclasses.replace(v, name=v.name.replace(shipped.label, cls.label, 1))
            for v in shipped.tradeoff_variants()
        ]

    @classmethod
    def add_arguments(cls, parser) -> None:
        """Its flags are the shipped technique's."""

    @property
    def parameters(self) -> dict:
        """Return the shipped technique's parameters, with the fit's record and its bake named."""
        return {**super().parameters, "bake": "fitted to the truth (hzval fit)", "fit": self.fit_record}

    @classmethod
    def frame_extras(cls, scores: dict) -> dict:
        """``split`` beside the shipped technique's scores (:func:`split`)."""
        return split(scores.get(cls.fitted_from.name), scores.get(cls.name))


class FittedFilament(FittedTextures, MicroshadowFilament):
    """Filament's micro-shadowing from the fitted AO."""

    fitted_from = MicroshadowFilament
    name = "microshadow-filament-fit"
    label = "fitted micro-shadows (Filament)"
    summary = "Filament's micro-shadowing with its AO fitted to the truth (hzval fit): the formula's floor"
    file_stem = "microshadow_filament_fit"


class FittedHDRP(FittedTextures, MicroshadowHDRP):
    """HDRP's micro-shadowing from the fitted AO."""

    fitted_from = MicroshadowHDRP
    name = "microshadow-hdrp-fit"
    label = "fitted micro-shadows (HDRP)"
    summary = "HDRP's micro-shadowing with its AO fitted to the truth (hzval fit): the formula's floor"
    file_stem = "microshadow_hdrp_fit"


class FittedBentCone(FittedTextures, BentCone):
    """Bent cones from the fitted bent normal and AO."""

    fitted_from = BentCone
    name = "bent-cone-fit"
    label = "fitted bent cone"
    summary = "bent cones with the bent normal and AO fitted to the truth (hzval fit): the formula's floor"
    file_stem = "bent_cone_fit"


class FittedSSBump(FittedTextures, SSBump):
    """The self-shadowed bump map fitted to the truth."""

    fitted_from = SSBump
    name = "ssbump-fit"
    label = "fitted self-shadowed bump map"
    summary = "Valve's self-shadowed bump map fitted to the truth (hzval fit): the formula's floor"
    file_stem = "ssbump_fit"
