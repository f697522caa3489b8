"""The ``horizon-fit`` technique: the horizon technique with the map fitted to the truth.

The fit is :mod:`hzval.techniques.fitted.fit`'s.

Beside ``horizon`` in a sweep it splits the horizon map's error per frame:
``baked - fitted`` is what the bake loses (a better baker could win it
back), ``fitted`` what eight interpolated directions and one ``k`` ramp
cannot hold. The map is fitted in the sweep's set-up on the training lights
(:data:`hzval.techniques.fitted.training.TRAINING_LIGHTS`, none at the default sweep's 30 degrees)
at the sweep's own samples, and cached in the sweep's ``fit/`` folder beside
its ``bake/`` by a digest of the height map, the bake's parameters, the
samples and the fit's settings (:func:`hzval.techniques.fitted.store.cache_key`).

It renders as ``horizon`` does on the exact path, with the same ``k`` and
``storage`` (``--horizon-k``, ``--horizon-storage``): the fit is quantisation-aware, and the
texture holds the stored map as the GPU samples it. ``--horizon-fit-k``
fits ``k`` too. It is opt-in (``--techniques horizon,horizon-fit``): a fit
takes tens of seconds, which a default sweep does not pay.
"""

from __future__ import annotations

import dataclasses

from typing_extensions import override

from hzval.scene.spec import Scene
from hzval.techniques.fitted import store as fitted_store
from hzval.techniques.fitted import training as fitted_training
from hzval.techniques.horizon import DEFAULT_K, Horizon
from hzval.techniques.registry import Context

__all__ = ["FittedHorizon"]


class FittedHorizon(Horizon):
    """:class:`hzval.techniques.horizon.Horizon` of the fitted map (module docstring)."""

    name = "horizon-fit"
    label = "fitted horizon map"
    summary = (
        "the horizon map fitted to the truth with Dr.Jit's AD (hzval fit): the representation's floor, "
        "beside the bake"
    )
    file_stem = "horizon_fit"
    fit_of = Horizon.name
    needs = ("shadow",)
    by_default = False
    not_on_models = "the fit trains on the plane's top view (docs/fit.md)"
    input_flags = ()  # it starts from the bake, never from --horizon-map
    flags = {"k": "--horizon-k", "storage": "--horizon-storage"}
    #: A frame's ``split`` of the baked map's mean |F - V|, from the bottom up (:meth:`frame_extras`).
    split_parts = (
        ("representation", "what eight directions cannot hold (fitted |F−V|)"),
        ("bake_loss", "what the bake loses (baked − fitted |F−V|)"),
    )

    @classmethod
    def bake_needs(cls, scene: Scene) -> frozenset[str]:
        """Return the horizon map it starts from, and the height map the truth it fits to is traced from."""
        return super().bake_needs(scene) | {"height"}

    @classmethod
    def build(
        cls,
        ctx: Context,
        *,
        k: float = DEFAULT_K,
        storage: str | None = None,
        fit_k: bool = False,
        lights: str = fitted_training.TRAINING_LIGHTS,
        held_out: str = fitted_training.HELD_OUT_LIGHTS,
        **settings,
    ) -> "FittedHorizon":
        """Build the technique from a context, its horizon map fitted or read from the cache.

        ``lights``/``held_out``: the fit's training and held-out lights
        (:func:`hzval.techniques.fitted.training.parse_lights`).
        """
        storage = storage or "float"
        _, sines, record, cached = fitted_store.cached_fit(
            ctx.height,
            ctx.bake,
            ctx.scene,
            ctx.cache,
            k=float(k),
            storage=storage,
            fit_k=bool(fit_k),
            lights=lights,
            held_out=held_out,
        )
        # the sines are the stored map, decoded: uploaded as they are
        own = cls(
            ctx.scene,
            dataclasses.replace(ctx.bake, horizon=sines),
            ctx.albedo,
            samples=ctx.samples(),
            k=float(record["k"]),
            storage="float",
            **settings,
        )
        own.storage = storage  # what parameters and storage_bytes report
        own.fit_record = {
            "cached": cached,
            "k": record["k"],
            "fit_k": record["fit_k"],
            "mae": {w: {k: v for k, v in m.items() if k != "per_light"} for w, m in record["mae"].items()},
            "epochs": record["epochs"],
            "converged": record["converged"],
            "seconds": record["seconds"],
        }
        return own

    @classmethod
    @override
    def add_arguments(cls, parser) -> None:
        parser.add_argument(
            "--horizon-fit-k",
            action="store_true",
            help="fitted horizon map: fit the shadow hardness k too (default: the horizon map's --horizon-k)",
        )

    @classmethod
    @override
    def settings_from_args(cls, args) -> dict:
        return {
            "k": args.horizon_k,
            "fit_k": bool(args.horizon_fit_k),
            **({"storage": args.horizon_storage} if args.horizon_storage else {}),
        }

    @classmethod
    def check_settings(cls, bake_params, settings: dict) -> None:
        """Nothing beyond the fit's own checks."""

    @classmethod
    @override
    def check_variants(cls) -> list:
        return []  # the regression check guards the bake's technique; a fit is its study

    @classmethod
    @override
    def tradeoff_variants(cls) -> list:
        return []

    @classmethod
    @override
    def fit(cls, ctx, settings, visibility, azimuths) -> dict:
        return settings

    @property
    @override
    def parameters(self) -> dict:
        return {
            **super().parameters,
            "bake": "fitted to the truth (hzval.techniques.fitted.fit)",
            "fit": self.fit_record,
        }

    @classmethod
    def frame_extras(cls, scores: dict) -> dict:
        """Return the ``split`` beside the baked map's scores: ``bake_loss`` and ``representation``.

        ``bake_loss`` is the baked map's mean ``|F - V|`` minus the fitted one's (what a better baker could
        win back) and ``representation`` the fitted map's (what eight interpolated directions and one ``k``
        ramp cannot hold); nothing without both.
        """
        baked, fitted = scores.get(Horizon.name), scores.get(cls.name)
        if (
            not baked
            or not fitted
            or baked.get("visibility_mae") is None
            or fitted.get("visibility_mae") is None
        ):
            return {}
        return {
            "split": {
                "bake_loss": baked["visibility_mae"] - fitted["visibility_mae"],
                "representation": fitted["visibility_mae"],
            }
        }
