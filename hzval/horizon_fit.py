"""The ``horizon-fit`` technique: the horizon technique with the map fitted to the truth (:mod:`hzval.fit`).

Beside ``horizon`` in a sweep it splits the horizon map's error per frame:
``baked - fitted`` is what the bake loses (a better baker could win it
back), ``fitted`` what eight interpolated directions and one ``k`` ramp
cannot hold. The map is fitted in the sweep's set-up on the training lights
(:data:`hzval.fit.TRAINING_LIGHTS`, none at the default sweep's 30 degrees)
at the sweep's own samples, and cached in the sweep's ``fit/`` folder beside
its ``bake/`` by a digest of the height map, the bake's parameters, the
samples and the fit's settings (:func:`hzval.fit.cache_key`).

It renders as ``horizon`` does on the exact path, with the same ``k`` and
``storage`` (``--k``, ``--storage``): the fit is quantisation-aware, and the
texture holds the stored map as the GPU samples it. ``--horizon-fit-k``
fits ``k`` too. It is opt-in (``--techniques horizon,horizon-fit``): a fit
takes tens of seconds, which a default sweep does not pay.
"""

from __future__ import annotations

import dataclasses

from hzval import fit
from hzval.approx import DEFAULT_K, Approximation
from hzval.technique import Context

__all__ = ["FittedHorizon", "split"]


class FittedHorizon(Approximation):
    """:class:`hzval.approx.Approximation` of the fitted map (module docstring)."""

    name = "horizon-fit"
    label = "fitted horizon map"
    summary = ("the horizon map fitted to the truth with Dr.Jit's AD (hzval fit): the representation's floor, "
               "beside the bake")
    file_stem = "horizon_fit"
    needs = ("shadow",)
    opt_in = True

    @classmethod
    def build(cls, ctx: Context, *, k: float = DEFAULT_K, storage: str | None = None, fit_k: bool = False,
              lights: str = fit.TRAINING_LIGHTS, held_out: str = fit.HELD_OUT_LIGHTS, **settings) -> "FittedHorizon":
        """``lights``/``held_out``: the fit's training and held-out lights (:func:`hzval.fit.parse_lights`)."""
        storage = storage or "float"
        _, sines, record, cached = fit.cached_fit(ctx.height, ctx.bake, ctx.scene, ctx.cache, k=float(k),
                                                  storage=storage, fit_k=bool(fit_k), lights=lights,
                                                  held_out=held_out)
        # the sines are the stored map, decoded: uploaded as they are
        own = cls(ctx.scene, dataclasses.replace(ctx.bake, horizon=sines), ctx.albedo, samples=ctx.samples(),
                  k=float(record["k"]), storage="float", **settings)
        own.storage = storage           # what parameters and storage_bytes report
        own.fit_record = {"cached": cached, "k": record["k"], "fit_k": record["fit_k"], "mae": record["mae"],
                   "epochs": record["epochs"], "converged": record["converged"], "seconds": record["seconds"]}
        return own

    @classmethod
    def add_arguments(cls, parser) -> None:
        parser.add_argument("--horizon-fit-k", action="store_true",
                            help="fitted horizon map: fit the shadow hardness k too (default: the horizon map's --k)")

    @classmethod
    def settings_from_args(cls, args) -> dict:
        return {"k": args.k, "fit_k": bool(args.horizon_fit_k), **({"storage": args.storage} if args.storage else {})}

    @classmethod
    def check_settings(cls, bake_params, settings: dict) -> None:
        """Nothing beyond the fit's own checks."""

    @classmethod
    def check_variants(cls) -> list:
        return []           # the regression check guards the bake's technique; a fit is its study

    @classmethod
    def tradeoff_variants(cls) -> list:
        return []

    @classmethod
    def fit(cls, ctx, settings, visibility, azimuths) -> dict:
        return settings

    @property
    def parameters(self) -> dict:
        return {**super().parameters, "bake": "fitted to the truth (hzval.fit)", "fit": self.fit_record}


def split(per_technique: dict) -> dict | None:
    """A frame's split of the horizon map's mean ``|F - V|``: ``bake_loss`` (baked minus fitted) and
    ``representation`` (the fitted map's), from its techniques' metrics; ``None`` without both."""
    baked, fitted = per_technique.get(Approximation.name), per_technique.get(FittedHorizon.name)
    if not baked or not fitted or baked.get("visibility_mae") is None or fitted.get("visibility_mae") is None:
        return None
    return {"bake_loss": baked["visibility_mae"] - fitted["visibility_mae"],
            "representation": fitted["visibility_mae"]}
