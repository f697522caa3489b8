"""The horizon map's stored sines corrected for the surface's normal curvature.

The module holds the derivation, the correction for a constant curvature and the ``horizon-curved`` technique
that renders it (item 2; measured in studies/curved_horizon.py, docs/models.md).

Derivation. Let a point ``p`` of the base surface have the tangent plane ``z = 0``, heights ``h`` in
texels, and the surface's normal curvature along the azimuth ``phi`` be ``kappa`` (texels^-1, + convex:
the surface bends away from its normal). The base surface at geodesic distance ``d`` along ``phi``
lies ``R (1 - cos(d/R)) = kappa d^2 / 2 + O(d^4 kappa^3)`` below the tangent plane, at horizontal
distance ``R sin(d/R) = d (1 + O((kappa d)^2))``. A bump of height ``Delta h = h(q) - h(p)`` there is
seen from ``p`` at

    tan(angle) = (Delta h - kappa d^2 / 2) / d = Delta h / d - kappa d / 2

to first order in ``kappa d`` (the relief's own tilt by ``kappa d`` moves it by ``h kappa d``, second
order in the small relief ``h / d``). The flat bake stores, per bin of azimuths, the largest
``Delta h / d`` over ``0 < d <= radius``; on the curved surface the horizon is

    t_kappa = max_d (Delta h(d) / d - kappa d / 2)

which for small ``kappa`` is ``t_0 - kappa d* / 2`` (envelope theorem), ``d*`` the distance of the
flat horizon's occluder: the bake does not store it, and the first-order form cannot raise a horizon
that the flat search found empty (a bowl's rim). :func:`sine_change` therefore searches again with
the curvature (the same bins, radius and channel means as :func:`hzval.bake.horizon.horizon_map`'s seed
bake) and returns the change of each channel's sine, ``s_kappa - s_0``, which a shader adds to the
stored sine. A convex surface (``kappa > 0``) lowers every horizon (``change <= 0``), a concave one
raises it; ``kappa = 0`` changes nothing, bit for bit.

What it gains is measured in studies/curved_horizon.py (docs/models.md): the band's |F - V| with
the corrected sines against the baked ones, and, as a control, the same correction on the flat
patch, where it is wrong: a gain there too is the flat bake's own bias (its horizons too high for
this ``k``), not curvature.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from typing_extensions import override

from hzval.core import conventions as cv
from hzval.core.errors import InputError
from hzval.scene.spec import Scene
from hzval.techniques.horizon import Horizon
from hzval.techniques.registry import Context

__all__ = ["sine_change", "bin_tangents", "CurvedHorizon"]


def bin_tangents(h_texels: np.ndarray, kappa: float, radius: int, angles: int, boundary: str) -> np.ndarray:
    """Return the largest horizon slope of each bin on a curved surface.

    Per bin (azimuth ``360 b / angles`` degrees) and texel, the largest ``Delta h / d - kappa d / 2``
    over the steps ``d = 1 .. radius`` texels along the bin's direction (bilinear heights): the
    height above the tangent plane of a surface of normal curvature ``kappa`` falls by
    ``kappa d^2 / 2``. 0 (the tangent plane) where every step is below it.

    Parameters
    ----------
    h_texels : numpy.ndarray
        ``(rows, cols)`` heights in texels.
    kappa : float
        Normal curvature, texels^-1, + convex.
    radius, angles : int
        Steps and bins, as the seed bake's.
    boundary : {"wrap", "open"}

    Returns
    -------
    numpy.ndarray
        ``(angles, rows, cols)`` tangents.
    """
    h = np.asarray(h_texels, np.float64)
    rows, cols = h.shape
    xc, yc = cv.texel_centres(rows, cols)
    x, y = xc.ravel(), yc.ravel()
    h0 = h.ravel()  # row-major, as texel_centres lays them out
    out = np.zeros((angles, rows * cols))
    for b in range(angles):
        a = 2.0 * np.pi * b / angles
        dx, dy = np.cos(a), np.sin(a)
        best = np.zeros(rows * cols)
        for d in range(1, int(radius) + 1):
            t = (cv.bilinear_at(h, x + d * dx, y + d * dy, boundary) - h0) / d - 0.5 * kappa * d
            np.maximum(best, t, out=best)
        out[b] = best
    return out.reshape(angles, rows, cols)


def sine_change(
    h_texels: np.ndarray,
    kappa: float,
    *,
    radius: int = 16,
    angles: int = 32,
    directions: int = cv.CHANNEL_COUNT,
    boundary: str = "wrap",
) -> np.ndarray:
    """Each channel's horizon sine on a curved surface minus the flat one's.

    Both by :func:`bin_tangents` and the seed bake's channel means (``angles / directions + 1`` bins
    centred on the channel's azimuth).

    Parameters
    ----------
    h_texels : numpy.ndarray
        ``(rows, cols)`` heights in texels.
    kappa : float
        Normal curvature, texels^-1, + convex, the same along every azimuth.
    radius, angles, directions : int
        As the seed bake's.
    boundary : {"wrap", "open"}

    Returns
    -------
    numpy.ndarray
        ``(rows, cols, directions)``; 0 everywhere when ``kappa == 0``.
    """
    if kappa == 0.0:
        rows, cols = np.shape(h_texels)
        return np.zeros((rows, cols, directions), np.float32)

    def sine(t):
        return t / np.sqrt(1.0 + t * t)

    flat, curved = (sine(bin_tangents(h_texels, k, radius, angles, boundary)) for k in (0.0, kappa))
    diff = curved - flat
    half = angles // (2 * directions)
    chans = []
    for k in range(directions):
        centre = k * angles // directions
        idx = [(centre + d) % angles for d in range(-half, half + 1)]
        chans.append(diff[idx].mean(axis=0))
    return np.stack(chans, -1).astype(np.float32)


class CurvedHorizon(Horizon):
    """The ``horizon-curved`` technique: the bake's sines plus :func:`sine_change` for a curvature.

    It is a :class:`hzval.techniques.horizon.Horizon` rendering them for the model's normal curvature
    ``curvature`` (``--horizon-curvature``, texture widths^-1, + convex: ``world_per_uv / R`` for a sphere of
    radius ``R``), the same along every direction. ``curvature = 0`` renders the bake itself, bit for bit as
    ``horizon``. It is opt-in (``--techniques horizon,horizon-curved``): one number per model is what it knows
    of the shape; a per-vertex curvature (the shape operator of the base mesh's normals along each light) is
    not built (docs/models.md).
    """

    name = "horizon-curved"
    label = "curvature-corrected horizon map"
    summary = (
        "the horizon map's sines corrected for the model's normal curvature 1/R "
        "(--horizon-curvature): tan drops by kappa d / 2 at occluder distance d, re-searched"
    )
    file_stem = "horizon_curved"
    needs = ("shadow",)
    by_default = False
    input_flags = ()  # it starts from the bake, never from --horizon-map
    flags = {"k": "--horizon-k", "storage": "--horizon-storage", "curvature": "--horizon-curvature"}

    @classmethod
    def bake_needs(cls, scene: Scene) -> frozenset[str]:
        """Return the horizon map it corrects, and the height map the correction searches again."""
        return super().bake_needs(scene) | {"height"}

    @classmethod
    @override
    def build(cls, ctx: Context, *, curvature: float = 0.0, **settings) -> "CurvedHorizon":
        curvature = float(curvature)
        if not math.isfinite(curvature):
            raise InputError("--horizon-curvature", f"must be a finite number, got {curvature}")
        bake = ctx.bake
        # a constant curvature models the surface over the bake's search: it must bend less than a
        # radian there (a radius of curvature at least the search radius), or every horizon drops
        search = bake.params.radius or max(ctx.height.shape)  # the exact bake searches the whole map
        reach = search / ctx.height.shape[1]  # texture widths
        if abs(curvature) * reach > 1.0:
            raise InputError(
                "--horizon-curvature",
                f"{curvature:g} bends the surface {abs(curvature) * reach:.3g} radians over the bake's "
                f"search radius ({search} texels of {ctx.height.shape[1]}); at most "
                f"{1.0 / reach:g} in magnitude",
            )
        if curvature != 0.0:
            h = cv.heights_in_texels(ctx.height, ctx.scene.material.depth)
            p = bake.params
            ds = sine_change(
                h,
                curvature / h.shape[1],
                radius=p.radius,
                angles=p.angles,
                directions=int(bake.horizon.shape[-1]),
                boundary=ctx.scene.material.boundary,
            )
            # the bake stores no horizon below the tangent plane (its tangents start at 0)
            bake = dataclasses.replace(bake, horizon=np.clip(bake.horizon + ds, 0.0, 1.0).astype(np.float32))
        own = cls(ctx.scene, bake, ctx.albedo, samples=ctx.samples(), **settings)
        own.curvature = curvature
        return own

    @classmethod
    @override
    def add_arguments(cls, parser) -> None:
        parser.add_argument(
            "--horizon-curvature",
            type=float,
            default=0.0,
            metavar="K",
            help="curvature-corrected horizon map: the model's normal curvature 1/R in texture "
            "widths^-1, + convex, - concave (default 0: the bake itself; measured to help on "
            "convex surfaces, to cost on concave ones for three of six materials: "
            "docs/models.md)",
        )

    @classmethod
    @override
    def settings_from_args(cls, args) -> dict:
        return {
            "k": args.horizon_k,
            "curvature": args.horizon_curvature,
            **({"storage": args.horizon_storage} if args.horizon_storage else {}),
        }

    @classmethod
    @override
    def check_variants(cls) -> list:
        return []  # the regression check guards the bake's technique

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
            "curvature": self.curvature,
            "correction": "sines + hzval.techniques.horizon_curved.sine_change(1/R per texel)",
        }
