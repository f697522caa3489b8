"""What the plane's and the model's truths share, each formula written once.

That is the rays' lift above the surface, the random streams, the glossy lobe and its sampling, the reflection
estimate and the per-pixel mean and variance of 0/1 samples. :mod:`hzval.truth.plane` and
:mod:`hzval.truth.model` read it.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Protocol, runtime_checkable

import numpy as np

from hzval.core import backend
from hzval.core.backend import dr, mi  # Dr.Jit loads at first use, once the LLVM is chosen
from hzval.core.errors import InputError
from hzval.core.shading import SPECULAR_EXPONENT, SPECULAR_KS
from hzval.scene.spec import Frame, Scene, load_albedo

__all__ = [
    "relight",
    "LIFT_TEXELS",
    "LIFT_PER_HEIGHT",
    "AMBIENT_STREAM",
    "REFLECTION_STREAM",
    "lift_for",
    "specular_sampling_share",
    "sample_bsdf",
    "stream_rng",
    "lobe_sample",
    "reflection_estimate",
    "mean_and_variance",
]

#: Smallest lift of ray origins above the surface, in texels.
LIFT_TEXELS = 2.0**-13
#: Lift per texel of height magnitude: 32 float32 ulps of the heights.
LIFT_PER_HEIGHT = 2.0**-18
#: Random stream of the ambient directions; the path tracer's first bounce
#: reuses it, so that its cosine-weighted directions are the ambient layer's.
AMBIENT_STREAM = 0xA3B1
REFLECTION_STREAM = 0x5EF1


def lift_for(z_min: float, z_max: float) -> float:
    """Return the ray origins' lift above the surface, texels, for heights from ``z_min`` to ``z_max``.

    See the module docstring, "Self-intersection".
    """
    return max(LIFT_TEXELS, LIFT_PER_HEIGHT * max(abs(z_min), abs(z_max)))


def specular_sampling_share(scene: Scene) -> float:
    """Share of BSDF samples drawn from the specular lobe (the rest cosine-weighted)."""
    if not scene.declares("specular"):
        return 0.0
    return 1.0 if not scene.declares("diffuse") else 0.25


def sample_bsdf(scene: Scene, n, v, albedo, p_spec: float, u_lobe, u):
    """Sample the truth's BSDF about normal ``n`` seen from ``v``: ``(wo, f cos / pdf)``.

    The BSDF is the one :meth:`hzval.truth.plane.Truth._direct` evaluates: Lambert
    ``albedo / pi`` and, with ``specular``, FGED2's Blinn-Phong written as a
    BSDF, ``f cos = ks (n.h)^alpha [n.wo > 0]``. Directions come from a
    mixture of the cosine-weighted hemisphere and the lobe's half-vector
    distribution ``pdf(h) = (alpha + 1) / (2 pi) (n.h)^alpha``, ``pdf(wo) =
    pdf(h) / (4 wo.h)`` (Walter et al. 2007), so the weight stays bounded.
    """
    wo_d = mi.Frame3f(n).to_world(mi.warp.square_to_cosine_hemisphere(u))
    if p_spec > 0.0:
        wo_s, _ = _lobe_direction(n, v, u)
        wo = dr.select(u_lobe < p_spec, wo_s, wo_d) if p_spec < 1.0 else wo_s
    else:
        wo = wo_d
    cos_o = dr.dot(n, wo)
    f_cos = mi.Color3f(0.0)
    pdf = mi.Float(0.0)
    if scene.declares("diffuse"):
        f_cos += albedo * (dr.maximum(cos_o, 0.0) * (1.0 / math.pi))
    if p_spec < 1.0:
        pdf += (1.0 - p_spec) * dr.maximum(cos_o, 0.0) * (1.0 / math.pi)
    if scene.declares("specular"):
        hv = dr.normalize(wo + v)
        nh = dr.maximum(dr.dot(n, hv), 0.0)
        lobe = dr.power(nh, SPECULAR_EXPONENT)
        f_cos += mi.Color3f(dr.select(cos_o > 0.0, SPECULAR_KS * lobe, 0.0))
        pdf_h = (SPECULAR_EXPONENT + 1.0) * (0.5 / math.pi) * lobe
        pdf += p_spec * pdf_h / dr.maximum(4.0 * dr.abs(dr.dot(wo, hv)), 1e-12)
    ok = (cos_o > 0.0) & (pdf > 0.0)
    return wo, dr.select(ok, f_cos / dr.maximum(pdf, 1e-30), 0.0)


def stream_rng(seed: int, stream: int, start: int, count: int):
    """Return a PCG32 per sample ``start <= k < start + count`` of the image.

    Each is seeded by the scene's ``seed`` and a ``stream`` tag: deterministic, and the same in a band as in
    one piece (the plane's truth in bands, a model's in one piece, :mod:`hzval.truth.model`).
    """
    state = (int(seed) * 0x9E3779B97F4A7C15 + stream) & 0xFFFFFFFFFFFFFFFF
    # Dr.Jit's PCG32(size, initstate, initseq) adds each lane's index to both (drjit/random.h):
    # sample k of one piece starts from initstate + k with the sequence 2k, so lane j of a
    # band starting at sample s takes initstate + s and initseq j + 2 s
    return mi.PCG32(
        size=count,
        initstate=(state + start) & 0xFFFFFFFFFFFFFFFF,
        initseq=dr.arange(mi.UInt64, count) + 2 * start,
    )


def lobe_sample(ns, v, u):
    """Return ``(wo, w)``: a direction of the glossy lobe about ``ns`` and its weight in ``R``'s estimate.

    ``ns`` is the shading normal, seen from ``v`` (toward the camera, unit); the direction comes from ``u`` in
    [0, 1)^2 (:func:`_lobe_direction`); ``R`` is the ``reflection_occlusion`` layer (module docstring).

    Drawn from the lobe's half-vector distribution, each direction carries the
    estimator's weight ``f cos / pdf = ks 8 pi (wo.h) / (alpha + 1)``
    (Walter et al. 2007; ``f cos = ks (n.h)^alpha [n.wo > 0]``, ``pdf =
    (alpha + 1) / (2 pi) (n.h)^alpha / (4 wo.h)``); the constant cancels in
    the ratio, so ``w = wo.h`` where ``ns.wo > 0``, else 0.
    """
    wo, h = _lobe_direction(ns, v, u)
    return wo, dr.select(dr.dot(ns, wo) > 0.0, dr.maximum(dr.dot(wo, h), 0.0), 0.0)


def reflection_estimate(w, V, spp: int) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(R, variance)`` per pixel (flat float32) from per-sample weights and escapes.

    The weights are ``w`` (:func:`lobe_sample`) and the escapes ``V`` (0/1), of ``spp`` consecutive samples a
    pixel: ``R = sum w V / sum w`` (0 where ``sum w = 0``) and the ratio estimator's variance ``sum w^2 (V -
    R)^2 / (sum w)^2`` (NaN for one sample a pixel, which has none).
    """
    sums = [dr.block_sum(x, spp) for x in (w * V, w, w * w * V, w * w)]
    dr.eval(sums)
    backend.sync()
    wv, ws, w2v, w2 = (np.asarray(x, np.float64) for x in sums)
    R = np.divide(wv, ws, out=np.zeros_like(ws), where=ws > 0)
    var = np.divide(w2v * (1.0 - 2.0 * R) + R * R * w2, ws * ws, out=np.zeros_like(ws), where=ws > 0)
    if spp < 2:
        var[:] = np.nan
    return R.astype(np.float32), np.maximum(var, 0.0).astype(np.float32)


def _lobe_direction(n, v, u):
    """Return a direction of the Blinn-Phong lobe about normal ``n`` seen from ``v``, from ``u`` in [0, 1)^2.

    The half vector ``h`` has ``pdf(h) = (alpha + 1) / (2 pi) (n.h)^alpha``
    (``alpha`` = :data:`hzval.core.shading.SPECULAR_EXPONENT`) and the direction is
    ``v`` reflected about it (Walter et al. 2007); with ``h = n`` it is the
    mirror direction. It may point below the surface. Returns ``(wo, h)``.
    """
    cos_h = dr.power(u.x, 1.0 / (SPECULAR_EXPONENT + 1.0))
    sin_h = dr.safe_sqrt(1.0 - cos_h * cos_h)
    phi = 2.0 * math.pi * u.y
    h = mi.Frame3f(n).to_world(mi.Vector3f(sin_h * dr.cos(phi), sin_h * dr.sin(phi), cos_h))
    return 2.0 * dr.dot(v, h) * h - v, h


def mean_and_variance(s1, ss, spp):
    """Return pixel means and variances of the mean from per-pixel sums of x and of (x - mean)^2.

    Float64 Dr.Jit arrays go in, float32 arrays come out (rounded once, from float64).

    ``spp``: the samples of every pixel (an ``int``), or an array of each pixel's (those that see the
    surface; a pixel of none has mean 0). The variance of the mean is the sample variance (``n - 1``
    in the denominator) over ``n``: NaN for one sample, which has none.
    """
    if isinstance(spp, int):
        mean = s1 / spp
        var = (
            dr.full(mi.Float64, math.nan, dr.width(mean))
            if spp < 2
            else dr.maximum(ss, 0.0) / (spp - 1) / spp
        )
        return mi.Float(mean), mi.Float(var)
    n = mi.Float64(spp)
    mean = s1 / dr.maximum(n, 1.0)
    var = dr.select(n >= 2, dr.maximum(ss, 0.0) / dr.maximum(n - 1, 1.0) / dr.maximum(n, 1.0), math.nan)
    return mi.Float(mean), mi.Float(var)


@runtime_checkable
class TruthLike(Protocol):
    """What a sweep asks of a truth, the plane's and a model's alike.

    The plane's is :class:`hzval.truth.plane.Truth`, a model's :class:`hzval.truth.model.ModelTruth`.

    Attributes
    ----------
    scene : hzval.scene.spec.Scene
        The scene it traces, validated.
    shape : tuple of int
        ``(H, W)``, the image's pixels.
    simulated : tuple of str
        The declared effects it simulates, in :data:`hzval.scene.spec.EFFECTS`'s order.
    seen : numpy.ndarray or None
        ``(H, W)`` bool, the pixels that see the surface (``None``: all of them).
    timings : dict
        Seconds of each stage of its set-up.
    """

    scene: Scene
    shape: tuple[int, int]
    simulated: tuple[str, ...]
    seen: np.ndarray | None
    timings: dict

    def render(self, azimuth_deg: float) -> Frame:
        """Render the frame of the light at ``azimuth_deg``: its layers (``V``, the image, ...) per pixel."""
        ...

    def light_at(self, elevation_deg: float) -> None:
        """Light the frames that follow from ``elevation_deg``, at least the one it was built for."""
        ...


#: Declared effects that read the material's albedo.
NEEDS_ALBEDO = ("diffuse", "ambient", "interreflection")


def albedo_texels(scene: Scene, rows: int, cols: int, albedo=None):
    """Return the linear albedo texels of ``scene``'s material as one flat ``mi.Float`` array.

    The array is row-major ``(rows, cols, 3)``, or ``None`` when no declared effect reads it
    (:data:`NEEDS_ALBEDO`).

    ``albedo``: the texels themselves, ``(rows, cols, 3)`` linear; default the material's
    (:func:`hzval.scene.spec.load_albedo`).
    """
    if not any(scene.declares(e) for e in NEEDS_ALBEDO):
        return None
    a = load_albedo(scene.material, rows, cols) if albedo is None else np.asarray(albedo, np.float32)
    if a.shape != (rows, cols, 3):
        raise InputError("albedo", f"expected shape {(rows, cols, 3)}, got {a.shape}")
    return mi.Float(np.ascontiguousarray(a, np.float32).ravel())


def albedo_at(texels, rows, cols, x, y, active=True):
    """Return the linear albedo of the texel that holds the texel-unit point ``(x, y)``.

    It is the nearest, as the techniques read it (column ``floor(x)``, row ``rows - ceil(y)``: exact in
    float32, where ``rows - y`` itself would round).

    ``rows`` and ``cols``: the map's size as opaque ``mi.Float`` values (``dr.opaque``), so that one
    kernel serves every map size.
    """
    n_cols, n_rows = mi.Int32(cols), mi.Int32(rows)
    col = dr.clip(mi.Int32(dr.floor(x)), 0, n_cols - 1)
    row = dr.clip(mi.Int32(rows - dr.ceil(y)), 0, n_rows - 1)
    return dr.gather(mi.Color3f, texels, mi.UInt32(row * n_cols + col), active)


def relight(truth, elevation_deg: float) -> bool:
    """Point ``truth``'s light (``truth.scene``) at ``elevation_deg``; return whether the light changed.

    ``elevation_deg`` is on a sweep's elevation axis (:meth:`hzval.scene.spec.Light.elevations`): at least the
    elevation it was built for (``truth.built_elevation_deg``), whose margins and bands hold the longest
    shadow rays, and so every higher light's. A changed light is what a truth that traced its lights ahead
    must trace again.

    Raises
    ------
    ValueError
        For an elevation below the one it was built for.
    """
    e = float(elevation_deg)
    if e < truth.built_elevation_deg:
        raise ValueError(f"a truth built for {truth.built_elevation_deg:g} degrees cannot light from {e:g}")
    if e == float(truth.scene.light.elevation_deg):
        return False
    truth.scene = dataclasses.replace(truth.scene, light=truth.scene.light.at(e))
    return True
