"""Unity HDRP's AO micro-shadowing: the ``microshadow-hdrp`` technique.

HDRP (``ComputeMicroShadowing``, ShaderLibrary/CommonLighting.hlsl) after Brinck & Maximov 2016,
"The Technical Art of Uncharted 4" (SIGGRAPH course):

    F = lerp(1, saturate(N.L + 2 AO^2 - 1), opacity)   where N.L > 0, else 1,

``N`` the normal map's normal, ``L`` the tangent-space light, ``AO`` the bake's cosine-weighted open
fraction (``ambient.exr``'s ``mean_cos2``; 8-bit with ``--ao-storage u8``) and ``opacity`` the
micro-shadow opacity (``--microshadow-hdrp-opacity``, HDRP's default 1). HDRP applies it only to
lit pixels; where ``N.L <= 0`` the direct term is 0 and ``F`` is 1, as HDRP leaves the shadow there.
"""

from __future__ import annotations

import math

from typing_extensions import override

from hzval.core.backend import dr, mi
from hzval.core.errors import InputError
from hzval.techniques.perpixel import PerPixelFactor, through

__all__ = ["MicroshadowHDRP", "DEFAULT_OPACITY"]

#: HDRP's default micro-shadow opacity.
DEFAULT_OPACITY = 1.0


class MicroshadowHDRP(PerPixelFactor):
    """``F = lerp(1, saturate(N.L + 2 AO^2 - 1), opacity)`` (module docstring)."""

    name = "microshadow-hdrp"
    label = "micro-shadows (HDRP)"
    summary = (
        "HDRP's AO micro-shadowing (Brinck & Maximov 2016): F = lerp(1, saturate(N.L + 2 AO^2 - 1), opacity)"
    )
    file_stem = "microshadow_hdrp"
    textures = ("ao",)
    flags = {"ao-storage": "--ao-storage", "opacity": "--microshadow-hdrp-opacity"}

    @classmethod
    @override
    def validate(cls, settings: dict) -> dict:
        opacity = settings.pop("opacity", None)
        super().validate(settings)
        opacity = DEFAULT_OPACITY if opacity is None else opacity
        if not (isinstance(opacity, (int, float)) and math.isfinite(opacity) and 0.0 <= opacity <= 1.0):
            raise InputError("opacity", f"the micro-shadow opacity must be in [0, 1], got {opacity!r}")
        return {"opacity": float(opacity)}

    @override
    def constants(self) -> dict:
        return {"opacity": dr.opaque(mi.Float, self.settings["opacity"])}

    @override
    def factor(self, tex: dict, n, L, c: dict):
        nl, ao = dr.dot(n, L), tex["ao"][0]
        ramp = nl + 2.0 * ao * ao - 1.0
        shadow = through(dr.clip(ramp, 0.0, 1.0), ramp, self.straight_through)
        return dr.select(nl > 0.0, dr.lerp(1.0, shadow, c["opacity"]), 1.0)

    @classmethod
    @override
    def add_arguments(cls, parser) -> None:
        super().add_arguments(parser)
        parser.add_argument(
            "--microshadow-hdrp-opacity",
            type=float,
            default=DEFAULT_OPACITY,
            metavar="O",
            help=f"HDRP micro-shadows: their opacity in [0, 1] (default {DEFAULT_OPACITY:g})",
        )

    @classmethod
    @override
    def settings_from_args(cls, args) -> dict:
        return {**super().settings_from_args(args), "opacity": args.microshadow_hdrp_opacity}
