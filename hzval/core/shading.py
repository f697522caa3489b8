"""Shading: the one place that defines how a surface point turns light into radiance.

The truth (:mod:`hzval.truth.plane`), every technique (:mod:`hzval.techniques.surface`,
:mod:`hzval.techniques.terrain`, :mod:`hzval.techniques.pom`) and the display exposure
(:mod:`hzval.metrics.compare`) use these formulas and constants, so that the two
sides of a comparison cannot drift apart: whatever differs between them is
the surface, never the shading (docs/ARCHITECTURE.md, "Shading").

The design in full: docs/internals.md, "hzval.core.shading".
"""

from __future__ import annotations

import math

import numpy as np

from hzval.core.backend import dr, mi  # Dr.Jit loads at first use, once the LLVM is chosen

__all__ = [
    "SPECULAR_KS",
    "SPECULAR_EXPONENT",
    "SKY_RADIANCE_PER_IRRADIANCE",
    "exposure",
    "max_radiance",
    "disk_sample_irradiance",
    "direct",
    "sky",
    "compose",
    "ipow",
]

#: Blinn-Phong specular colour ``ks`` (grey; a dielectric's normal-incidence
#: reflectance), FGED2 ch. 7's ``C_specular``.
SPECULAR_KS = 0.04
#: Blinn-Phong exponent ``alpha`` (FGED2 ch. 7).
SPECULAR_EXPONENT = 64
#: Radiance of the uniform sky of ``ambient`` per unit of the light's
#: irradiance E: ``1/pi`` gives an unoccluded horizontal plane an irradiance
#: E from the sky.
SKY_RADIANCE_PER_IRRADIANCE = 1.0 / math.pi


def max_radiance(scene) -> float:
    """Return the largest radiance a scene's declared direct and sky terms can produce, with a white albedo.

    ``E / pi`` (diffuse, facing the light) ``+ KS E`` (specular, at its peak ``n.h = 1``), or ``E`` (grey,
    neither declared), ``+ E * SKY_RADIANCE_PER_IRRADIANCE`` (ambient, the whole sky seen). Interreflection
    can add more; it is not counted.

    Parameters
    ----------
    scene : hzval.scene.spec.Scene
        Its light's irradiance ``E`` and its declared effects.

    Returns
    -------
    float
        Linear radiance.
    """
    E = float(scene.light.irradiance)
    diffuse, specular = scene.declares("diffuse"), scene.declares("specular")
    peak = E if not (diffuse or specular) else E / math.pi * diffuse + SPECULAR_KS * E * specular
    if scene.declares("ambient"):
        peak += E * SKY_RADIANCE_PER_IRRADIANCE
    return peak


def exposure(scene) -> float:
    """Return the scale from radiance to display values, so that :func:`max_radiance` shows as 1.

    Parameters
    ----------
    scene : hzval.scene.spec.Scene

    Returns
    -------
    float
        ``1 / max_radiance(scene)``.
    """
    return 1.0 / max_radiance(scene)


def disk_sample_irradiance(E: float, radius_deg: float) -> float:
    """Return the irradiance each sampled direction of a soft light carries (module docstring, "Soft light").

    A disk of angular radius ``rho`` sampled uniformly in solid angle delivers ``E (1 + cos rho) / 2`` to a
    surface facing its centre when each direction carries ``E``; scaling by ``2 / (1 + cos rho)`` makes it
    ``E``.

    Parameters
    ----------
    E : float
        The light's irradiance on a surface facing it.
    radius_deg : float
        ``rho``, the disk's angular radius in degrees.

    Returns
    -------
    float
        ``2 E / (1 + cos rho)``.

    Examples
    --------
    >>> disk_sample_irradiance(1.0, 0.0)
    1.0
    >>> round(disk_sample_irradiance(1.0, 90.0), 12)
    2.0
    """
    return 2.0 * float(E) / (1.0 + math.cos(math.radians(radius_deg)))


def ipow(x, n: int):
    """``x ** n`` for a positive integer ``n`` by repeated squaring, without exp or log.

    The same rounding on every backend, and cheaper than ``dr.power`` in a kernel.

    Parameters
    ----------
    x : float, numpy.ndarray or Dr.Jit array
    n : int
        The exponent, at least 1.

    Returns
    -------
    The type of ``x``.

    Examples
    --------
    >>> ipow(2.0, 10), ipow(3, 1)
    (1024.0, 3)
    """
    result = None
    base = x
    while n:
        if n & 1:
            result = base if result is None else result * base
        n >>= 1
        if n:
            base = base * base
    return result


def direct(n, L, v, albedo, E, *, diffuse: bool, specular: bool, h=None):
    """Return the direct term ``D`` of the module docstring, per sample (Dr.Jit arrays in and out).

    Lambert (FGED2 ch. 7) ``albedo / pi * E * max(0, n.L)`` plus Blinn-Phong
    ``KS * E * max(0, n.h)^ALPHA * [n.L > 0]``, whichever are declared; ``E`` (grey) when neither is.

    Parameters
    ----------
    n, L, v : mitsuba.Vector3f
        Unit shading normal, direction toward the light and toward the viewer, tangent space.
    albedo : mitsuba.Color3f
        Linear albedo (read only with ``diffuse``).
    E : mitsuba.Float
        The light's irradiance (opaque in callers, so that kernels are shared).
    diffuse, specular : bool
        The declared terms.
    h : mitsuba.Vector3f, optional
        The half vector when the caller has it already (uniform over a frame for a hard light and a fixed
        view); else ``normalize(L + v)``.

    Returns
    -------
    mitsuba.Color3f
        Linear radiance.
    """
    if not (diffuse or specular):
        return mi.Color3f(E)
    nl = dr.dot(n, L)
    D = mi.Color3f(0.0)
    if diffuse:
        D += albedo * (E * dr.maximum(nl, 0.0) * (1.0 / math.pi))
    if specular:
        h = dr.normalize(L + v) if h is None else h
        nh = dr.maximum(dr.dot(n, h), 0.0)
        D += mi.Color3f(dr.select(nl > 0.0, SPECULAR_KS * E * ipow(nh, SPECULAR_EXPONENT), 0.0))
    return D


def sky(albedo, A, E):
    """Return the ambient term: ``albedo * A * E * SKY_RADIANCE_PER_IRRADIANCE``.

    Parameters
    ----------
    albedo : array
        Linear albedo (Dr.Jit or NumPy).
    A : array
        The unoccluded cosine-weighted fraction of the sky.
    E : float or array
        The light's irradiance.

    Returns
    -------
    array
        Linear radiance, the type of the operands.

    Examples
    --------
    >>> import math
    >>> math.isclose(sky(1.0, 1.0, math.pi), 1.0)
    True
    """
    return albedo * (A * E * SKY_RADIANCE_PER_IRRADIANCE)


def compose(
    direct_image: np.ndarray, factor: np.ndarray, ambient_image: np.ndarray | None = None
) -> np.ndarray:
    """Return a frame's image ``D * F + ambient`` per pixel.

    Techniques whose factor is computed per pixel (terrain, pom) shade with it here; the horizon map
    multiplies per sample in its kernel. The two differ only where the direct term varies inside a pixel
    that a shadow edge crosses (a covariance within one pixel).

    Parameters
    ----------
    direct_image : numpy.ndarray
        ``(H, W, 3)``: the unshadowed render's direct part ``D``, linear.
    factor : numpy.ndarray
        ``(H, W)``: the shadow factor ``F`` in [0, 1].
    ambient_image : numpy.ndarray, optional
        ``(H, W, 3)``: the ambient term, added unshadowed.

    Returns
    -------
    numpy.ndarray
        ``(H, W, 3)`` float32.

    Examples
    --------
    >>> import numpy as np
    >>> compose(np.ones((1, 1, 3)), np.full((1, 1), 0.5), np.full((1, 1, 3), 0.25)).tolist()
    [[[0.75, 0.75, 0.75]]]
    """
    # one new image, the sum made in it (each full-size temporary is pages new to the process)
    out = np.multiply(
        np.asarray(direct_image, np.float32), np.asarray(factor, np.float32)[..., None], dtype=np.float32
    )
    if ambient_image is not None:
        np.add(out, ambient_image, out=out)  # in float64 first if the ambient is, as before
    return out
