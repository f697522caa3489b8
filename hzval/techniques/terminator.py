"""The bump-terminator term of offline renderers: the ``terminator`` technique.

A shading normal ``N`` (the normal map's) tilted from the geometric normal ``Ng`` lights what the
surface's own plane would leave dark; offline renderers soften that with a shadowing term:

``conty`` (default)
    Conty Estevez et al. 2019, "A Microfacet-Based Shadowing Function to Solve the Bump Terminator
    Problem" (Ray Tracing Gems, ch. 12): ``cos_d = N . Ng``,
    ``alpha^2 = clamp(tan^2(theta_d) / 8, 0, 1)``, ``cos_i = Ng . L``,
    ``F = 2 / (1 + sqrt(1 + alpha^2 tan^2(theta_i)))``; 0 where ``Ng . L <= 0``.
``chiang`` (``--terminator-variant chiang``)
    Chiang et al. 2019, "Taming the Shadow Terminator" (SIGGRAPH talk; Blender Cycles'
    ``bump_shadowing_term``):
    ``g = (Ng . L) / ((N . L)(Ng . N))``, ``F = -g^3 + g^2 + g`` for ``g`` in (0, 1), 1 above and 0
    below; 1 where ``N . L <= 0`` (the limit from the lit side; the direct term is 0 there).

``Ng`` is the base surface's normal: the tile's ``+z``; on a model the interpolated vertex normal,
which is ``+z`` in each sample's tangent frame too.
"""

from __future__ import annotations

from typing_extensions import override

from hzval.core.backend import dr
from hzval.techniques.perpixel import PerPixelFactor
from hzval.techniques.registry import Variant

__all__ = ["Terminator", "VARIANTS", "conty", "chiang"]

#: The shadowing terms, by the first author's name.
VARIANTS: tuple[str, ...] = ("conty", "chiang")


def conty(cos_d, cos_i):
    """Conty Estevez et al.'s term (module docstring) of ``cos_d = N . Ng`` and ``cos_i = Ng . L``."""
    cd = dr.maximum(cos_d, 1e-6)
    ci = dr.maximum(cos_i, 1e-6)
    alpha2 = dr.clip((1.0 / (cd * cd) - 1.0) * 0.125, 0.0, 1.0)
    tan2_i = 1.0 / (ci * ci) - 1.0
    G = 2.0 / (1.0 + dr.sqrt(1.0 + alpha2 * tan2_i))
    return dr.select(cos_i > 0.0, G, 0.0)


def chiang(nl, cos_i, cos_d):
    """Chiang et al.'s term (module docstring) of ``N . L``, ``Ng . L`` and ``Ng . N``."""
    g = cos_i / dr.maximum(nl * cos_d, 1e-12)
    smooth = (-g * g + g + 1.0) * g  # -g^3 + g^2 + g
    F = dr.select(g >= 1.0, 1.0, dr.select(g <= 0.0, 0.0, smooth))
    return dr.select(nl > 0.0, F, 1.0)


class Terminator(PerPixelFactor):
    """The bump-terminator shadowing term (module docstring)."""

    name = "terminator"
    label = "bump-terminator term"
    summary = "offline renderers' bump shadowing: Conty Estevez et al. 2019 (or Chiang et al. 2019)"
    file_stem = "terminator"
    flags = {"variant": "--terminator-variant"}

    @classmethod
    @override
    def validate(cls, settings: dict) -> dict:
        variant = cls.choice(settings, "variant", VARIANTS)
        super().validate(settings)
        return {"variant": variant}

    @override
    def factor(self, tex: dict, n, L, c: dict):
        if self.settings["variant"] == "conty":
            return conty(n.z, L.z)
        return chiang(dr.dot(n, L), L.z, n.z)

    @classmethod
    @override
    def add_arguments(cls, parser) -> None:
        parser.add_argument(
            "--terminator-variant",
            choices=VARIANTS,
            default="conty",
            help="bump-terminator term: Conty Estevez et al. 2019, or Chiang et al. 2019 (default conty)",
        )

    @classmethod
    @override
    def settings_from_args(cls, args) -> dict:
        return {"variant": args.terminator_variant}

    @classmethod
    @override
    def tradeoff_variants(cls):

        return [Variant(f"{cls.label} ({v})", {"variant": v}, {"variant": v}) for v in VARIANTS]
