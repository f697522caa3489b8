"""The sRGB transfer functions and the luminance of its primaries, as colour-science gives them.

The standard is IEC 61966-2-1. Albedo images and previews are sRGB-encoded, renders linear.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from hzval.core import conventions as cv

__all__ = ["decode", "encode", "luminance_weights"]


def decode(values: np.ndarray) -> np.ndarray:
    """sRGB-encoded values to linear (IEC 61966-2-1, colour-science's ``cctf_decoding``).

    Parameters
    ----------
    values : array_like
        Encoded values in [0, 1].

    Returns
    -------
    numpy.ndarray
        float64 linear values.

    Examples
    --------
    >>> round(float(decode(0.5)), 6)
    0.214041
    """
    import colour  # 1.7 s to import: paid only where a conversion runs

    return np.asarray(colour.cctf_decoding(np.asarray(values, dtype=np.float64), function="sRGB"))


def encode(values: Any) -> Any:
    """Linear values to sRGB-encoded values (IEC 61966-2-1), negatives as 0.

    NumPy values go through colour-science's ``cctf_encoding(function="sRGB")``. A Dr.Jit array
    (``mi.Float64``: the comparison's display values, :func:`hzval.metrics.compare.display`) is encoded in a
    kernel by the formula colour-science evaluates, ``12.92 L`` at or below ``L = 0.0031308``, else
    ``1.055 L^(1/2.4) - 0.055``: within 4e-16 of it in float64 (Dr.Jit's ``pow`` is not NumPy's).

    Parameters
    ----------
    values : array_like or Dr.Jit array
        Linear values.

    Returns
    -------
    numpy.ndarray or Dr.Jit array
        Encoded values, the type of ``values``.

    Examples
    --------
    >>> round(float(encode(0.214041)), 4), float(encode(-1.0))
    (0.5, 0.0)
    """
    if cv.is_drjit(values):
        import drjit as dr  # only for a Dr.Jit array

        v = dr.maximum(values, 0.0)
        return dr.select(v <= 0.0031308, v * 12.92, 1.055 * dr.power(v, 1 / 2.4) - 0.055)
    import colour  # 1.7 s to import: paid only where a conversion runs

    v = np.clip(np.asarray(values, dtype=np.float64), 0.0, None)
    return np.asarray(colour.cctf_encoding(v, function="sRGB"))


def luminance_weights() -> np.ndarray:
    """Weights of R, G, B in the luminance Y of the sRGB / Rec. 709 primaries.

    Taken from colour-science's sRGB RGB-to-XYZ matrix (its Y row), so that RGB height maps are reduced as
    ``Y = w . rgb`` on their data values.

    Returns
    -------
    numpy.ndarray
        ``(3,)`` float64, summing to 1.

    Examples
    --------
    >>> w = luminance_weights()
    >>> round(float(w.sum()), 6), round(float(w[1]), 4)
    (1.0, 0.7152)
    """
    import colour  # 1.7 s to import: paid only where a conversion runs

    return np.asarray(colour.RGB_COLOURSPACES["sRGB"].matrix_RGB_to_XYZ[1], dtype=np.float64)
