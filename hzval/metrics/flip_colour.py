"""FLIP's constants and per-pixel colour steps in float32, on NumPy values or Dr.Jit arrays alike.

They are ``FLIP.h``'s ``FLIPConstants`` and ``color3`` conversions: sRGB to linear, XYZ, YCxCz and CIELAB, the
Hunt adjustment and the HyAB distance (docs/flip.md).
"""

from __future__ import annotations

import numpy as np

from hzval.core import conventions as cv
from hzval.core.backend import dr  # Dr.Jit loads at first use, once the LLVM is chosen

__all__ = [
    "f32",
    "QC",
    "PC",
    "PT",
    "W",
    "QF",
    "GAUSS_A1",
    "GAUSS_B1",
    "GAUSS_A2",
    "GAUSS_B2",
    "PI",
    "DEFAULT_PPD",
    "srgb_to_linear",
    "linear_rgb_to_xyz",
    "xyz_to_linear_rgb",
    "xyz_to_ycxcz",
    "ycxcz_to_xyz",
    "xyz_to_cielab",
    "hunt",
    "hyab",
    "max_distance",
    "k32",
    "powf",
    "clamp_unit",
]

f32 = np.float32

#: FLIP's constants (``FLIPConstants`` in FLIP.h): the colour-difference exponent ``qc``,
QC = f32(0.7)
#: the fraction ``pc`` of ``cmax`` below which colour differences are compressed,
PC = f32(0.4)
#: the error ``pt`` those differences map to at most,
PT = f32(0.95)
#: the feature filter's width ``w`` in degrees (its standard deviation is ``0.5 w ppd`` pixels),
W = f32(0.082)
#: and the feature-difference exponent ``qf``.
QF = f32(0.5)

#: The contrast sensitivity functions' Gaussians (``GaussianConstants`` in FLIP.h, the paper's
#: Table 1) for Y, Cx and Cz: ``a1 sqrt(pi / b1) exp(-pi^2 x^2 / b1) + a2 sqrt(pi / b2) exp(-pi^2 x^2 / b2)``.
GAUSS_A1 = (f32(1.0), f32(1.0), f32(34.1))
GAUSS_B1 = (f32(0.0047), f32(0.0053), f32(0.04))
GAUSS_A2 = (f32(0.0), f32(0.0), f32(13.5))
GAUSS_B2 = (f32(1.0e-5), f32(1.0e-5), f32(0.025))

#: FLIP's pi (``FLIP::PI``, as a float).
PI = f32(3.14159265358979)

#: FLIP's default viewing condition: 0.7 m from a 3840-pixel, 0.7 m wide monitor
#: (``calculatePPD(0.7, 3840, 0.7)`` = 67.02 pixels per degree).
DEFAULT_PPD = f32(0.7) * (f32(3840.0) / f32(0.7)) * (PI / f32(180.0))


def k32(v):
    """Return a float32 constant of FLIP's as the value both NumPy and Dr.Jit compute with.

    The value is a Python float, which is exact.
    """
    return float(f32(v))


_ILLUMINANT = (k32(0.950428545), 1.0, k32(1.088900371))  # DEFAULT_ILLUMINANT (D65)
_INV_ILLUMINANT = (
    k32(1.052156925),
    1.0,
    k32(0.918357670),
)  # INV_DEFAULT_ILLUMINANT

_RGB_TO_XYZ = (
    (
        k32(f32(10135552.0) / f32(24577794.0)),
        k32(f32(8788810.0) / f32(24577794.0)),
        k32(f32(4435075.0) / f32(24577794.0)),
    ),
    (
        k32(f32(2613072.0) / f32(12288897.0)),
        k32(f32(8788810.0) / f32(12288897.0)),
        k32(f32(887015.0) / f32(12288897.0)),
    ),
    (
        k32(f32(1425312.0) / f32(73733382.0)),
        k32(f32(8788810.0) / f32(73733382.0)),
        k32(f32(70074185.0) / f32(73733382.0)),
    ),
)
_XYZ_TO_RGB = (
    (k32(3.241003275), k32(-1.537398934), k32(-0.498615861)),
    (k32(-0.969224334), k32(1.875930071), k32(0.041554224)),
    (k32(0.055639423), k32(-0.204011202), k32(1.057148933)),
)

# -- FLIP.h's color3 conversions, on planes ------------------------------------------------------


def _numpy(v) -> bool:
    """Whether ``v`` is a NumPy value (the filters' constants) rather than a Dr.Jit array (the images)."""
    return not cv.is_drjit(v)


def _where(cond, a, b):
    if _numpy(cond):
        return np.where(cond, a, b)

    return dr.select(cond, a, b)


def powf(x, e):
    """``powf(x, e)`` for ``x >= 0`` (``powf(0, 0) = 1``, ``powf(0, e > 0) = 0``)."""
    if _numpy(x):
        return np.power(x, e)

    at_zero = (1.0 if e == 0 else 0.0) if _numpy(e) else dr.select(e == 0, 1.0, 0.0)
    return dr.select(x > 0, dr.power(dr.maximum(x, 1e-38), e), at_zero)


def _sqrt(x):
    if _numpy(x):
        return np.sqrt(x)

    return dr.sqrt(x)


def _abs(x):
    if _numpy(x):
        return np.abs(x)

    return dr.abs(x)


def clamp_unit(v):
    """``Min(Max(v, 0), 1)``: NaN becomes 0, as FLIP's macros make it."""
    if _numpy(v):
        return np.fmin(np.fmax(v, f32(0.0)), f32(1.0))

    return dr.select(v > 0.0, dr.minimum(v, 1.0), 0.0)  # NaN > 0 is false: 0


def srgb_to_linear(c):
    """Convert sRGB to linear in float32, as FLIP's ``color3::sRGBToLinearRGB`` does.

    This is the sRGB transfer function's inverse (IEC 61966-2-1): ``c / 12.92`` up to 0.04045, ``((c + 0.055)
    / 1.055) ^ 2.4`` above.

    Parameters
    ----------
    c : numpy.ndarray or drjit.Float
        sRGB-encoded values in [0, 1].

    Returns
    -------
    numpy.ndarray or drjit.Float
        Linear values.
    """
    with np.errstate(invalid="ignore"):
        return _where(
            c <= k32(0.04045),
            c / k32(12.92),
            powf((c + k32(0.055)) / k32(1.055), k32(2.4)),
        )


def _mat(m, x, y, z):
    return (
        m[0][0] * x + m[0][1] * y + m[0][2] * z,
        m[1][0] * x + m[1][1] * y + m[1][2] * z,
        m[2][0] * x + m[2][1] * y + m[2][2] * z,
    )


def linear_rgb_to_xyz(r, g, b):
    """FLIP's ``color3::LinearRGBToXYZ``: linear sRGB primaries to CIE XYZ, D65.

    Parameters
    ----------
    r, g, b : numpy.ndarray or drjit.Float
        Linear RGB, float32.

    Returns
    -------
    tuple
        ``(x, y, z)``.
    """
    return _mat(_RGB_TO_XYZ, r, g, b)


def xyz_to_linear_rgb(x, y, z):
    """FLIP's ``color3::XYZToLinearRGB``: CIE XYZ to linear sRGB primaries, D65.

    Parameters
    ----------
    x, y, z : numpy.ndarray or drjit.Float
        CIE XYZ (D65), float32.

    Returns
    -------
    tuple
        ``(r, g, b)``.
    """
    return _mat(_XYZ_TO_RGB, x, y, z)


def xyz_to_ycxcz(x, y, z):
    """Convert CIE XYZ to YCxCz, the opponent space FLIP filters in (FLIP's ``color3::XYZToYCxCz``).

    It computes ``Y = 116 y/yn - 16``, ``Cx = 500 (x/xn - y/yn)``, ``Cz = 200 (y/yn - z/zn)``.

    Parameters
    ----------
    x, y, z : numpy.ndarray or drjit.Float
        CIE XYZ (D65), float32.

    Returns
    -------
    tuple
        ``(Y, Cx, Cz)``.
    """
    x, y, z = x * _INV_ILLUMINANT[0], y * _INV_ILLUMINANT[1], z * _INV_ILLUMINANT[2]
    return 116.0 * y - 16.0, 500.0 * (x - y), 200.0 * (y - z)


def ycxcz_to_xyz(yy, cx, cz):
    """FLIP's ``color3::YCxCzToXYZ``, the inverse of :func:`xyz_to_ycxcz`.

    Parameters
    ----------
    yy, cx, cz : numpy.ndarray or drjit.Float
        YCxCz values, float32.

    Returns
    -------
    tuple
        ``(x, y, z)``, D65.
    """
    y = (yy + 16.0) / 116.0
    cx, cz = cx / 500.0, cz / 200.0
    return (y + cx) * _ILLUMINANT[0], y * _ILLUMINANT[1], (y - cz) * _ILLUMINANT[2]


_DELTA = f32(6.0) / f32(29.0)
_DELTA_CUBE = k32(_DELTA * (_DELTA * _DELTA))
_LAB_FACTOR = k32(f32(1.0) / (f32(3.0) * (_DELTA * _DELTA)))
_LAB_TERM = k32(f32(4.0) / f32(29.0))
_THIRD = k32(f32(1.0) / f32(3.0))


def _lab_f(t):
    return _where(t > _DELTA_CUBE, powf(t, _THIRD), _LAB_FACTOR * t + _LAB_TERM)


def xyz_to_cielab(x, y, z):
    """FLIP's ``color3::XYZToCIELab`` (D65), with ``powf(t, 1/3)`` as FLIP has it, not ``cbrtf``.

    Parameters
    ----------
    x, y, z : numpy.ndarray or drjit.Float
        CIE XYZ (D65), float32.

    Returns
    -------
    tuple
        ``(L*, a*, b*)``.
    """
    fx, fy, fz = (
        _lab_f(x * _INV_ILLUMINANT[0]),
        _lab_f(y * _INV_ILLUMINANT[1]),
        _lab_f(z * _INV_ILLUMINANT[2]),
    )
    return 116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)


def hunt(luminance, chrominance):
    """FLIP's ``color3::Hunt``: the Hunt effect's adjustment of a chrominance, ``0.01 L C``.

    Parameters
    ----------
    luminance, chrominance : numpy.ndarray or drjit.Float
        ``L*`` and ``a*`` (or ``b*``).

    Returns
    -------
    numpy.ndarray or drjit.Float
        The adjusted chrominance.
    """
    return k32(0.01) * luminance * chrominance


def hyab(l1, a1, b1, l2, a2, b2):
    """Return FLIP's ``color3::HyAB`` distance: city-block in L, Euclidean in (a, b).

    The distance is ``|L1 - L2| + sqrt((a1 - a2)^2 + (b1 - b2)^2)``.

    Parameters
    ----------
    l1, a1, b1, l2, a2, b2 : numpy.ndarray or drjit.Float
        Two Hunt-adjusted Lab colours.

    Returns
    -------
    numpy.ndarray or drjit.Float
        The distance.
    """
    da, db = a1 - a2, b1 - b2
    return _abs(l1 - l2) + _sqrt(da * da + db * db)


def max_distance() -> np.float32:
    """``color3::computeMaxDistance(qc)``: the Hunt-adjusted HyAB of green against blue, to the ``QC``."""
    green = xyz_to_cielab(*linear_rgb_to_xyz(f32(0.0), f32(1.0), f32(0.0)))
    blue = xyz_to_cielab(*linear_rgb_to_xyz(f32(0.0), f32(0.0), f32(1.0)))
    g = (green[0], hunt(green[0], green[1]), hunt(green[0], green[2]))
    b = (blue[0], hunt(blue[0], blue[1]), hunt(blue[0], blue[2]))
    return f32(np.power(f32(hyab(*g, *b)), QC))


# -- the filters -----------------------------------------------------------------------------------
