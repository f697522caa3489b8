"""Bent cones: the ``bent-cone`` technique (ambient aperture lighting applied to the sun).

The open directions of a texel are taken to be a cone about a bent normal ``B``. Two conventions
(``--bent-cone-variant``):

``jimenez`` (the default; Jimenez et al. 2016, "Practical Real-Time Strategies for Accurate Indirect
Occlusion", as HDRP): ``B`` the cosine-weighted mean open direction (``bent_normal.exr``) and a
cone whose cosine-weighted solid angle is the ambient occlusion ``AO`` (``mean_cos2``): a cone of
half-angle ``theta_v`` holds the cosine-weighted share ``sin^2 theta_v``, so
``cos theta_v = sqrt(1 - AO)``;
``oat-sander`` (Oat & Sander 2007, "Ambient Aperture Lighting"): ``B`` the plain (solid-angle)
average of the open directions and a cone whose solid angle is the uniformly counted open share
``V`` of the hemisphere, ``2 pi (1 - cos theta_v) = 2 pi V``, so ``cos theta_v = 1 - V``; both
from the bake's horizon sines (:func:`hzval.bake.occlusion.uniform_bent_normal`,
:func:`hzval.bake.occlusion.uniform_ao`). Either is stored as ``--bent-normal-storage`` and
``--ao-storage`` say (8-bit as a normal map with ``u8``).

``F`` is the share of the light's disc inside the cone:

- a hard light is the limit of a small disc: ``F = 1`` where ``B.L >= cos theta_v``, else 0;
- a soft light of angular radius ``r`` (:class:`hzval.scene.spec.Light`) takes the exact solid angle of
  the intersection of two spherical caps (:func:`cap_intersection`) over the disc's
  ``2 pi (1 - cos r)``, or with ``--bent-cone-intersection filament`` Filament's smooth approximation
  (``sphericalCapsIntersection``, after Oat & Sander 2007), which Filament and HDRP ship for
  specular occlusion.
"""

from __future__ import annotations

import math

from typing_extensions import override

from hzval.bake import occlusion
from hzval.core.backend import dr, mi
from hzval.techniques.perpixel import PerPixelFactor, through

__all__ = ["BentCone", "VARIANTS", "INTERSECTIONS", "cap_intersection", "cap_intersection_filament"]

#: The cone's convention (module docstring).
VARIANTS: tuple[str, ...] = ("jimenez", "oat-sander")
#: How a soft light's disc is intersected with the cone.
INTERSECTIONS: tuple[str, ...] = ("exact", "filament")
#: The planes the ``oat-sander`` variant derives from the horizon sines, by the texture they replace.
_UNIFORM = {
    "bent-normal": ("bent_normal_uniform", occlusion.uniform_bent_normal),
    "ao": ("ao_uniform", occlusion.uniform_ao),
}


def cap_intersection(r1, r2, d):
    """Return the solid angle of the intersection of two spherical caps.

    Tovchigrechko & Vakser 2001, "How common is the funnel-like energy landscape in protein-protein
    interactions?" (appendix), as Mazonka 2012, "Solid Angle of Conical Surfaces, Polyhedral Cones,
    and Intersecting Spherical Caps", eq. 35: for ``|r1 - r2| < d < r1 + r2``,
    ``2 (pi - acos((cos d - cos r1 cos r2) / (sin r1 sin r2)) - cos r1 acos((cos r2 - cos d cos r1) /
    (sin d sin r1)) - cos r2 acos((cos r1 - cos d cos r2) / (sin d sin r2)))``; the smaller cap's
    ``2 pi (1 - cos min(r1, r2))`` when one holds the other, 0 when they are apart.

    Parameters
    ----------
    r1, r2 : drjit.Float
        The caps' angular radii, radians, each in (0, pi / 2].
    d : drjit.Float
        The angle between their centres, radians.

    Returns
    -------
    drjit.Float
        Steradians.
    """
    c1, c2, cd = dr.cos(r1), dr.cos(r2), dr.cos(d)
    s1, s2, sd = dr.sin(r1), dr.sin(r2), dr.maximum(dr.sin(d), 1e-12)

    def acos(x):
        return dr.acos(dr.clip(x, -1.0, 1.0))

    lens = 2.0 * (
        math.pi
        - acos((cd - c1 * c2) / (s1 * s2))
        - c1 * acos((c2 - cd * c1) / (sd * s1))
        - c2 * acos((c1 - cd * c2) / (sd * s2))
    )
    whole = 2.0 * math.pi * (1.0 - dr.maximum(c1, c2))
    out = dr.select(d >= r1 + r2, 0.0, dr.clip(lens, 0.0, whole))
    return dr.select(d <= dr.abs(r1 - r2), whole, out)


def cap_intersection_filament(r1, r2, d):
    """Return Filament's smooth approximation of :func:`cap_intersection`.

    It is ``sphericalCapsIntersection``, after Oat & Sander 2007: the smaller cap's solid angle times
    ``smoothstep`` of where ``d`` lies between ``|r1 - r2|`` and ``r1 + r2``. Parameters and result as
    :func:`cap_intersection`.
    """
    whole = 2.0 * math.pi * (1.0 - dr.maximum(dr.cos(r1), dr.cos(r2)))
    delta = dr.abs(r1 - r2)
    x = 1.0 - dr.clip((d - delta) / dr.maximum(r1 + r2 - delta, 1e-4), 0.0, 1.0)
    area = x * x * (3.0 - 2.0 * x)
    return dr.select(d <= delta, whole, dr.select(d >= r1 + r2, 0.0, area * whole))


class BentCone(PerPixelFactor):
    """The share of the light inside the bent cone (module docstring)."""

    name = "bent-cone"
    label = "bent cone"
    summary = (
        "bent normal + visibility cone cos = sqrt(1 - AO) (Jimenez 2016) or 1 - V (Oat & Sander 2007), "
        "intersected with the light"
    )
    file_stem = "bent_cone"
    textures = ("bent-normal", "ao")
    reads_normal = False
    flags = {
        "bent-normal-storage": "--bent-normal-storage",
        "ao-storage": "--ao-storage",
        "variant": "--bent-cone-variant",
        "intersection": "--bent-cone-intersection",
    }

    @classmethod
    @override
    def validate(cls, settings: dict) -> dict:
        variant = cls.choice(settings, "variant", VARIANTS)
        intersection = cls.choice(settings, "intersection", INTERSECTIONS)
        super().validate(settings)
        return {"variant": variant, "intersection": intersection}

    @override
    def plane(self, name: str):
        if self.settings["variant"] != "oat-sander" or self.bake.horizon is None:
            return super().plane(name)
        if not hasattr(self, "_uniform"):
            self._uniform = {}
        if name not in self._uniform:
            self._uniform[name] = _UNIFORM[name][1](self.bake.horizon)
        return self._uniform[name]

    @override
    def plane_name(self, name: str) -> str:
        if self.settings["variant"] != "oat-sander":
            return super().plane_name(name)
        return _UNIFORM[name][0]

    @override
    def constants(self) -> dict:
        light = self.scene.light
        r = math.radians(light.radius_deg) if light.kind == "soft" else 0.0
        return {"r": r}

    @override
    def factor(self, tex: dict, n, L, c: dict):
        B = dr.normalize(mi.Vector3f(*tex["bent-normal"]))
        if self.settings["variant"] == "oat-sander":  # the cone holds the open solid angle
            cos_v = 1.0 - tex["ao"][0]
        else:  # the cone holds the cosine-weighted open share
            closed = dr.maximum(1.0 - tex["ao"][0], 0.0)
            cos_v = through(dr.sqrt(closed), dr.sqrt(dr.maximum(closed, 1e-4)), self.straight_through)
        cos_d = dr.dot(B, L)
        r = c["r"]
        if r == 0.0:  # a hard light: the disc's limit
            F = dr.select(cos_d >= cos_v, 1.0, 0.0)
        else:
            theta_v = dr.maximum(dr.acos(dr.clip(cos_v, -1.0, 1.0)), 1e-6)
            d = dr.acos(dr.clip(cos_d, -1.0, 1.0))
            meet = cap_intersection if self.settings["intersection"] == "exact" else cap_intersection_filament
            F = meet(theta_v, r, d) / (2.0 * math.pi * (1.0 - math.cos(r)))
        # a fit's gradient: how far the light is inside the cone (a step's own is 0)
        return through(F, cos_d - cos_v, self.straight_through)

    @classmethod
    @override
    def add_arguments(cls, parser) -> None:
        super().add_arguments(parser)
        parser.add_argument(
            "--bent-cone-variant",
            choices=VARIANTS,
            default="jimenez",
            help="bent cones: the cosine-weighted bent normal and cos = sqrt(1 - AO) (Jimenez 2016, "
            "HDRP), or the plain average and cos = 1 - V of the open solid angle (Oat & Sander 2007) "
            "(default jimenez)",
        )
        parser.add_argument(
            "--bent-cone-intersection",
            choices=INTERSECTIONS,
            default="exact",
            help="bent cones: a soft light's disc meets the cone exactly, or by Filament's smooth "
            "approximation (default exact; a hard light is the same in both)",
        )

    @classmethod
    @override
    def settings_from_args(cls, args) -> dict:
        return {
            **super().settings_from_args(args),
            "variant": args.bent_cone_variant,
            "intersection": args.bent_cone_intersection,
        }
