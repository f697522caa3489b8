"""Filament's AO micro-shadowing: the ``microshadow-filament`` technique.

Filament (``computeMicroShadowing``, shaders/src/common_lighting.fs) after Chan 2018, "Material
Advances in Call of Duty: WWII" (SIGGRAPH course): the ambient-occlusion map ``AO`` read as the
aperture of a cone of open directions, and

    F = saturate(N.L / sqrt(1 - AO))^2,

``N`` the normal map's normal, ``L`` the tangent-space light and ``AO`` the bake's cosine-weighted
open fraction (``ambient.exr``'s ``mean_cos2``), float, or 8-bit as engines store it with
``--ao-storage u8``. An open texel (``AO = 1``) would divide by zero: Filament clamps ``AO`` to
0.9999, which leaves ``F < 1`` below ``N.L = 0.01``; hzval takes the limit instead, ``F = 1``
wherever ``N.L > 0``, so that a flat texel is never shadowed. ``F = 0`` where ``N.L <= 0``, as
Filament's saturated ``N.L`` gives.
"""

from __future__ import annotations

from typing_extensions import override

from hzval.core.backend import dr
from hzval.techniques.perpixel import PerPixelFactor, through

__all__ = ["MicroshadowFilament", "micro_shadow"]


def micro_shadow(nl, ao, straight_through: bool = False):
    """Chan's micro-shadow factor (module docstring), Dr.Jit or NumPy-free scalars alike.

    Parameters
    ----------
    nl : drjit.Float
        ``N . L``.
    ao : drjit.Float
        The open fraction in [0, 1].
    straight_through : bool
        With the gradient of the unclamped ramp ``N.L / sqrt(1 - AO)`` (a fit's,
        :func:`hzval.techniques.perpixel.through`); the value is the same.

    Returns
    -------
    drjit.Float
        ``F`` in [0, 1].
    """
    closed = dr.maximum(1.0 - ao, 0.0)
    f = dr.clip(nl / dr.sqrt(dr.maximum(closed, 1e-30)), 0.0, 1.0)
    F = dr.select(closed > 0.0, f * f, dr.select(nl > 0.0, 1.0, 0.0))
    # the ramp's gradient, its closed share floored so that an open texel's stays finite
    return through(F, nl / dr.sqrt(dr.maximum(closed, 1e-4)), straight_through)


class MicroshadowFilament(PerPixelFactor):
    """``F = saturate(N.L / sqrt(1 - AO))^2`` (module docstring)."""

    name = "microshadow-filament"
    label = "micro-shadows (Filament)"
    summary = "Filament's AO micro-shadowing (Chan 2018): F = saturate(N.L / sqrt(1 - AO))^2"
    file_stem = "microshadow_filament"
    textures = ("ao",)
    flags = {"ao-storage": "--ao-storage"}

    @override
    def factor(self, tex: dict, n, L, c: dict):
        return micro_shadow(dr.dot(n, L), tex["ao"][0], self.straight_through)
