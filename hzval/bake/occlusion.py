"""Directional occlusion from the horizon map: the bent normal and Valve's self-shadowed bump map.

Both come from the bake's horizon sines ``s_k = sin(alpha_k)`` toward the ``D`` azimuths
``phi_k = 360 k / D`` degrees (:func:`hzval.core.conventions.channel_azimuth_deg`), the same sweep
the ambient map comes from: a direction of elevation ``t`` toward ``phi_k`` is open when
``t > alpha_k``. Each azimuth stands for a wedge ``2 pi / D`` wide; the integrals over elevation
are exact. Horizons below the tangent plane count as the plane (``s`` clipped to [0, 1]), as the
ambient map's do.

``bent_normal``
    The cosine-weighted mean open direction (about the tangent plane's normal ``+z``, as the ambient
    map's ``mean_cos2``), normalised. Per azimuth, with ``theta_h = pi/2 - alpha`` the open polar
    angle: ``int_0^theta_h (sin theta cos phi, sin theta sin phi, cos theta) cos theta sin theta
    d theta = ((1 - s^2)^(3/2) (cos phi, sin phi), 1 - s^3) / 3``. An open texel gives ``+z``, and
    so does one closed on every side (no open direction: its AO is 0).
``ssbump``
    Valve's self-shadowed bump map (Green 2007, "Efficient Self-Shadowed Radiosity Normal
    Mapping", SIGGRAPH course; Source SDK 2013's ``height2ssbump``): per basis vector ``b_c`` of
    Half-Life 2's radiosity basis (:data:`HL2_BASIS`), ``max(0, n . b_c) * V_c``, ``n`` the normal
    map's normal and ``V_c`` the share of the light from the hemisphere about ``b_c`` (weighted by
    ``b_c . w``, upward directions ``w`` only) that reaches the texel. An open, flat texel stores
    ``1/sqrt(3)`` in each channel. Per azimuth the elevation integral is
    ``int max(0, b_c . w) cos t dt`` with ``b_c . w = p cos t + b_z sin t``, ``p`` ``b_c``'s
    component along ``phi``: ``G(t) = b_z sin^2(t) / 2 + p (t / 2 + sin(2 t) / 4)`` from
    ``max(alpha, -atan(p / b_z))`` to ``pi / 2``.

What had to be assumed (docs/techniques.md): Valve traces 250 random rays from the mesh's vertices
and uses a 3 x 3 averaged vertex normal; here the directions are the bake's ``D`` azimuths with
exact elevation integrals, and ``n`` is hzval's normal map, so that ssbump and the other
techniques read the same surface.
"""

from __future__ import annotations

import math

import numpy as np

from hzval.core import conventions as cv

__all__ = [
    "HL2_BASIS",
    "bent_normal",
    "uniform_ao",
    "uniform_bent_normal",
    "self_shadowed_bump",
]

#: Half-Life 2's radiosity normal-mapping basis in tangent space (Source SDK's ``g_localBumpBasis``;
#: McTaggart 2004, "Half-Life 2 / Valve Source Shading"), one unit vector per row, ``+y`` up the image.
#: It is symmetric about ``y = 0``: an engine whose ``y`` runs down the image swaps rows 1 and 2.
HL2_BASIS = np.array(
    [
        [math.sqrt(2.0 / 3.0), 0.0, 1.0 / math.sqrt(3.0)],
        [-1.0 / math.sqrt(6.0), 1.0 / math.sqrt(2.0), 1.0 / math.sqrt(3.0)],
        [-1.0 / math.sqrt(6.0), -1.0 / math.sqrt(2.0), 1.0 / math.sqrt(3.0)],
    ]
)


def _channel(sines: np.ndarray, k: int) -> np.ndarray:
    """Return channel ``k`` of the horizon sines, clipped to [0, 1].

    It takes one channel at a time: no copy of the whole map.
    """
    return np.clip(np.asarray(sines[..., k], np.float32), 0.0, 1.0)


def bent_normal(sines: np.ndarray) -> np.ndarray:
    """Return the bent normal of each texel (module docstring).

    Parameters
    ----------
    sines : numpy.ndarray
        ``(rows, cols, D)`` horizon sines, channel ``k`` toward ``360 k / D`` degrees.

    Returns
    -------
    numpy.ndarray
        ``(rows, cols, 3)`` float32 unit vectors in tangent space.

    Examples
    --------
    >>> import numpy as np
    >>> bent_normal(np.zeros((1, 1, 8)))[0, 0].round(6).tolist()
    [0.0, 0.0, 1.0]
    >>> b = bent_normal(np.array([[[1.0, 0, 0, 0, 0, 0, 0, 0]]]))[0, 0]
    >>> bool(b[0] < 0 and abs(b[1]) < 1e-6)
    True
    >>> bent_normal(np.ones((1, 1, 8)))[0, 0].tolist()
    [0.0, 0.0, 1.0]
    """
    return _mean_direction(sines, lambda s: np.maximum(1.0 - s * s, 0.0) ** 1.5, lambda s: 1.0 - s * s * s)


def uniform_ao(sines: np.ndarray) -> np.ndarray:
    """Return the open share of the hemisphere's solid angle, counted uniformly.

    This is Oat & Sander 2007's visibility, not the cosine-weighted AO: per azimuth wedge ``int_alpha^(pi/2)
    cos t dt = 1 - s``, so ``mean_k (1 - s_k)``; ``(rows, cols)`` float32 in [0, 1].

    Examples
    --------
    >>> import numpy as np
    >>> float(uniform_ao(np.full((1, 1, 8), 0.25))[0, 0])
    0.75
    """
    sines = np.asarray(sines)
    D = sines.shape[-1]
    out = np.zeros(sines.shape[:-1], np.float32)
    for k in range(D):
        out += 1.0 - _channel(sines, k)
    return out / np.float32(D)


def uniform_bent_normal(sines: np.ndarray) -> np.ndarray:
    """Return the plain (solid-angle) average of the open directions, normalised.

    This is Oat & Sander 2007's bent normal: per azimuth ``phi``, with ``alpha = asin s``, ``int_alpha^(pi/2)
    (cos t cos phi, cos t sin phi, sin t) cos t dt = ((pi/4 - alpha/2 - sin(2 alpha)/4) (cos phi, sin phi), (1
    - s^2) / 2)``; ``(rows, cols, 3)`` float32, ``+z`` where nothing is open.

    Examples
    --------
    >>> import numpy as np
    >>> uniform_bent_normal(np.zeros((1, 1, 8)))[0, 0].round(6).tolist()
    [0.0, 0.0, 1.0]
    """

    def side(sk):
        alpha = np.arcsin(sk)
        return np.float32(math.pi / 4) - alpha / 2 - np.sin(2 * alpha) / 4

    # arcsin(1) in float32 leaves a closed texel's sum a rounding above 0
    return _mean_direction(sines, side, lambda sk: (1.0 - sk * sk) / 2, closed_below=1e-12)


def _mean_direction(sines: np.ndarray, side, up, closed_below: float = 0.0) -> np.ndarray:
    """Return the sum of the ``side`` and ``up`` terms over the ``D`` azimuths, normalised.

    The sum is ``sum_k (side(s_k) (cos phi_k, sin phi_k), up(s_k))``; the result is ``+z`` where its length is
    at most ``closed_below`` (a texel closed on every side: its AO is 0, and a cone about any axis is empty).
    ``(rows, cols, 3)`` float32.
    """
    sines = np.asarray(sines)
    D = sines.shape[-1]
    out = np.zeros((*sines.shape[:-1], 3), np.float32)
    for k in range(D):
        phi = math.radians(cv.channel_azimuth_deg(k, D))
        sk = _channel(sines, k)
        horizontal = side(sk)
        out[..., 0] += horizontal * np.float32(math.cos(phi))
        out[..., 1] += horizontal * np.float32(math.sin(phi))
        out[..., 2] += up(sk)
    norm = np.linalg.norm(out, axis=-1, keepdims=True)
    closed = norm[..., 0] <= closed_below
    out[closed] = (0.0, 0.0, 1.0)
    norm[closed] = 1.0
    out /= norm
    return out


def _G(p: float, bz: float, t):
    """``int (p cos t + bz sin t) cos t dt`` (module docstring)."""
    return bz * np.sin(t) ** 2 / 2.0 + p * (t / 2.0 + np.sin(2.0 * t) / 4.0)


def _shares(p: float, bz: float, alpha) -> tuple[float, np.ndarray]:
    """Return one azimuth's weighted share of upward directions about ``b`` and the part below the horizon.

    The result is ``(whole, lost)``: ``whole`` is the weighted share of one azimuth's upward directions about
    ``b`` (where ``p cos t + bz sin t > 0``), ``lost`` the part of it below the horizon ``alpha``; ``lost`` is
    exactly 0 where nothing is, so an open texel's share is exactly whole.
    """
    start = max(0.0, -math.atan2(p, bz))  # where the weight turns positive
    whole = max(float(_G(p, bz, math.pi / 2.0) - _G(p, bz, start)), 0.0)
    top = np.maximum(alpha, np.float32(start))
    return whole, np.maximum(_G(p, bz, top) - np.float32(_G(p, bz, start)), 0.0)


def self_shadowed_bump(sines: np.ndarray, normal: np.ndarray, pool=None) -> np.ndarray:
    """Valve's self-shadowed bump map of each texel (module docstring).

    Parameters
    ----------
    sines : numpy.ndarray
        ``(rows, cols, D)`` horizon sines.
    normal : numpy.ndarray
        ``(rows, cols, 3)`` unit tangent-space normals (the normal map).
    pool : concurrent.futures.Executor, optional
        Where to make the three channels, each on its own (NumPy releases the GIL); ``None``: in
        turn. The values are the same either way.

    Returns
    -------
    numpy.ndarray
        ``(rows, cols, 3)`` float32 in [0, 1], channel ``c`` for :data:`HL2_BASIS` row ``c``.

    Examples
    --------
    >>> import numpy as np
    >>> flat = self_shadowed_bump(np.zeros((1, 1, 8)), np.array([[[0.0, 0.0, 1.0]]]))[0, 0]
    >>> bool(np.allclose(flat, 1 / np.sqrt(3)))
    True
    """
    sines = np.asarray(sines)
    n = np.asarray(normal, np.float32)
    out = np.zeros((*sines.shape[:-1], 3), np.float32)

    def channel(c: int) -> None:
        out[..., c] = _ssbump_channel(sines, n, HL2_BASIS[c])

    if pool is None:
        for c in range(3):
            channel(c)
    else:
        for done in [pool.submit(channel, c) for c in range(3)]:
            done.result()
    return out


def _ssbump_channel(sines: np.ndarray, n: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Return one channel of :func:`self_shadowed_bump`, the basis vector ``b``'s.

    It is ``max(0, n . b)`` times the share of its weighted hemisphere that the horizons leave open, ``(rows,
    cols)`` float32.
    """
    D = sines.shape[-1]
    lost = np.zeros(sines.shape[:-1], np.float32)
    whole = 0.0
    for k in range(D):
        phi = math.radians(cv.channel_azimuth_deg(k, D))
        w, part = _shares(b[0] * math.cos(phi) + b[1] * math.sin(phi), b[2], np.arcsin(_channel(sines, k)))
        whole += w
        lost += part
    facing = np.maximum(n @ b.astype(np.float32), 0.0)
    return facing * (1.0 - lost * np.float32(1.0 / whole))
