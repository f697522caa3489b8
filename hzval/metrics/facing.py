"""What a frame's truth has to shadow, and the visibility metrics over the pixels that face the light.

Attached shadows (docs/ARCHITECTURE.md, "Metrics"): a pixel whose surface faces away
from the light (``N . L <= 0``) is black in the truth and in every technique's image, whatever its
``V`` and ``F``; on a rough photo about 30% of the pixels do at a low light, and ``|F - V|`` over
the whole image counts their differences, which no image shows. So every frame has, besides the
whole image's visibility metrics, the same metrics over the pixels that face the light
(``visibility_mae_facing``, ``leak_fraction_facing``, ``false_shadow_fraction_facing``), and the
truth's own statistics (``frames[i].truth``):

    ``shadowed_fraction``   pixels the truth shadows (``V < 0.5``,
    :data:`hzval.metrics.compare.LIT_THRESHOLD`)
    ``attached_fraction``   pixels facing away from the light
    ``cast_fraction``       pixels that face the light and are shadowed: what the facing metrics test
    ``visibility_se``       the standard error that the truth's Monte Carlo noise puts on a frame's
                            mean ``|F - V|``: ``sqrt(sum V (1 - V) / spp) / N`` (a binomial bound per
                            pixel; stratified samples make it an upper bound)
    ``partial_fraction``    pixels whose ``V`` is neither 0 nor 1 (penumbrae, noise): the ones whose
                            lit / shadowed count can change with the truth's noise

A pixel faces the light when the normal map's normal of its texel (the techniques' shading normal,
:func:`hzval.core.conventions.normal_map`, at the texel's centre) has ``N . L > 0``; with ``supersampling``
``s`` each texel's normal stands for its ``s x s`` pixels. Only the ``top`` view has pixels on the
texel grid; another view has no facing mask and no facing metrics.

:data:`FEW_SHADOWS`: a frame whose facing pixels are less than 1% shadowed tests next to nothing;
the sweep warns (``metrics.json``'s warnings) and the report says so.
"""

from __future__ import annotations

import numpy as np

from hzval.metrics import compare

__all__ = [
    "facing_mask",
    "truth_statistics",
    "facing_metrics",
    "few_shadows_warning",
    "FEW_SHADOWS",
    "FACING_KEYS",
]

#: Below this share of shadowed facing pixels a frame's visibility metrics test next to nothing.
FEW_SHADOWS = 0.01
#: The facing metrics of a technique's frame, after the whole image's of the same name.
FACING_KEYS = ("visibility_mae_facing", "leak_fraction_facing", "false_shadow_fraction_facing")


def facing_mask(normal: np.ndarray, L, supersampling: int = 1) -> np.ndarray:
    """Return the pixels whose texel faces the light.

    Parameters
    ----------
    normal : numpy.ndarray
        ``(rows, cols, 3)`` the normal map (tangent space, unit).
    L : array_like
        ``(3,)`` unit tangent-space vector toward the light (:func:`hzval.core.conventions.light_direction`).
    supersampling : int
        Pixels per texel along each axis (the top view's).

    Returns
    -------
    numpy.ndarray
        ``(rows * s, cols * s)`` bool: ``N . L > 0`` at the texel, in float32 as the map is stored,
        each texel repeated ``supersampling`` times along both axes.
    """
    # float32, as the normal map is stored: a 4096 map's normals in float64 would be 400 MB a frame
    mask = (np.asarray(normal, np.float32) @ np.asarray(L, np.float32)) > 0.0
    s = int(supersampling)
    return np.repeat(np.repeat(mask, s, axis=0), s, axis=1) if s > 1 else mask


def truth_statistics(
    V: np.ndarray, facing: np.ndarray | None, spp: int, seen: np.ndarray | None = None
) -> dict:
    """Measure what the truth has to shadow in one frame (``metrics.json``'s ``frames[i].truth``).

    Parameters
    ----------
    V : numpy.ndarray
        ``(H, W)`` the truth's visibility, the mean of ``spp`` 0/1 samples a pixel.
    facing : numpy.ndarray or None
        ``(H, W)`` bool, the pixels that face the light (:func:`facing_mask`); ``None``: not known
        (a view other than the top one).
    spp : int
        Samples per pixel, for the standard error.
    seen : numpy.ndarray, optional
        ``(H, W)`` bool, the pixels that see the surface; ``None``: all.

    Returns
    -------
    dict
        ``shadowed_fraction`` (``V`` under :data:`hzval.metrics.compare.LIT_THRESHOLD`),
        ``visibility_se`` (the standard error of the image's mean ``V``, from the per-pixel Bernoulli
        variance ``V (1 - V) / spp``), ``partial_fraction`` (0 < V < 1); with ``facing``, also
        ``attached_fraction`` (facing away) and ``cast_fraction`` (facing yet shadowed). Each a share of
        the seen pixels.
    """
    V = np.asarray(V, np.float32)
    seen = np.ones(V.shape, bool) if seen is None else np.asarray(seen, bool)
    n = max(int(seen.sum()), 1)
    shadowed = (V < compare.LIT_THRESHOLD) & seen
    spread = V * (1.0 - V)  # float32 per pixel, summed in float64
    spread[~seen] = 0.0
    out = {
        "shadowed_fraction": float(shadowed.sum()) / n,
        "visibility_se": float(np.sqrt(np.sum(spread, dtype=np.float64) / max(spp, 1))) / n,
        "partial_fraction": float(np.sum(seen & (V > 0.0) & (V < 1.0))) / n,
    }
    if facing is not None:
        out["attached_fraction"] = float(np.sum(seen & ~facing)) / n
        out["cast_fraction"] = float(np.sum(shadowed & facing)) / n
    return out


def facing_metrics(V: np.ndarray, F: np.ndarray, facing: np.ndarray, seen: np.ndarray | None = None) -> dict:
    """Return the visibility metrics over the pixels that face the light.

    Parameters
    ----------
    V, F : numpy.ndarray
        ``(H, W)`` truth visibility and technique factor.
    facing : numpy.ndarray
        ``(H, W)`` bool (:func:`facing_mask`).
    seen : numpy.ndarray, optional
        ``(H, W)`` bool, the pixels that see the surface; ``None``: all.

    Returns
    -------
    dict
        :data:`FACING_KEYS` to :func:`hzval.metrics.compare.visibility_metrics` over ``facing & seen``;
        ``None`` each where no pixel is counted.
    """
    mask = facing if seen is None else (facing & seen)
    if not mask.any():
        return dict.fromkeys(FACING_KEYS)
    return dict(zip(FACING_KEYS, (float(v) for v in compare.visibility_metrics(V, F, mask))))


def few_shadows_warning(frames: list[dict]) -> str | None:
    """One line when some frames have almost nothing to shadow.

    Parameters
    ----------
    frames : list of dict
        ``metrics.json``'s frames, each with its ``truth`` statistics (:func:`truth_statistics`).

    Returns
    -------
    str or None
        The warning, naming the frames whose cast (or, without facing, all) shadows cover less than
        :data:`FEW_SHADOWS` of the pixels, and what casts more; ``None`` when every frame has enough.
    """
    few = []
    for f in frames:
        t = f.get("truth") or {}
        share = t.get("cast_fraction", t.get("shadowed_fraction"))
        if share is not None and share < FEW_SHADOWS:
            few.append((f.get("name") or f"az{f['azimuth_deg']:+g}", share))
    if not few:
        return None
    listed = ", ".join(f"{a} {100 * s:.2f}%" for a, s in few[:6]) + (" ..." if len(few) > 6 else "")
    return (
        f"few shadows to test: under {100 * FEW_SHADOWS:g}% of the pixels that face the light are shadowed "
        "in "
        f"{len(few)} of {len(frames)} frames ({listed}); every visibility error is then near 0 "
        "(a larger --depth or a lower --elevation casts more)"
    )
