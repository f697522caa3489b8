"""Valve's self-shadowed bump maps: the ``ssbump`` technique.

Green 2007, "Efficient Self-Shadowed Radiosity Normal Mapping" (SIGGRAPH course; Source's
``$ssbump``). The bake (:func:`hzval.bake.occlusion.self_shadowed_bump`, ``ssbump.exr``; 8-bit as
Source stores it with ``--ssbump-storage u8``) stores per texel, for each vector ``b_c`` of Half-Life
2's radiosity basis, the light that reaches the texel from about ``b_c``:
``S_c = max(0, n . b_c) V_c``. Source shades a directional light by projecting ``L`` onto the basis,
``w_c = max(0, L . b_c)``, and sums ``S_c w_c``.

hzval scores the occlusion this adds to the normal map's shading:

    F = sum_c S_c w_c / sum_c max(0, n . b_c) w_c,

the ssbump's light over the same sum for an open texel (``V_c = 1``); 0 where no basis vector both
faces the normal and the light. The image is the normal map's direct term times ``F``: Source's own
``E sum_c S_c w_c`` differs from it by the radiosity basis's projection error, which is not a shadow
and which hzval leaves out of the score (docs/techniques.md).
"""

from __future__ import annotations

from typing_extensions import override

from hzval.bake.occlusion import HL2_BASIS
from hzval.core.backend import dr, mi
from hzval.techniques.perpixel import PerPixelFactor, Texture

__all__ = ["SSBump"]


class SSBump(PerPixelFactor):
    """Green's directional occlusion, as a factor on the normal map's shading (module docstring)."""

    name = "ssbump"
    label = "self-shadowed bump map"
    summary = "Valve's self-shadowed bump map (Green 2007): occlusion toward Half-Life 2's 3 basis vectors"
    file_stem = "ssbump"
    textures = ("ssbump",)
    square_symmetric = False  # Half-Life 2's basis: symmetric about x alone (HL2_BASIS)
    own_textures = {
        "ssbump": Texture(
            "ssbump",
            "ssbump_map",
            False,
            "the self-shadowed bump map (ssbump.exr)",
            storages=("float", "u8", "bc1", "bc7"),
        )
    }
    flags = {"ssbump-storage": "--ssbump-storage"}

    @override
    def factor(self, tex: dict, n, L, c: dict):
        S = tex["ssbump"]
        lit = open_ = 0.0
        for k, b in enumerate(HL2_BASIS):
            bv = mi.Vector3f(*(float(x) for x in b))
            w = dr.maximum(dr.dot(L, bv), 0.0)
            lit = lit + S[k] * w
            open_ = open_ + dr.maximum(dr.dot(n, bv), 0.0) * w
        return dr.select(open_ > 0.0, lit / dr.maximum(open_, 1e-12), 0.0)
