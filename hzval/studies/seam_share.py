"""How much of a technique's error lies within a few texels of a UV seam (docs/models.md).

A seam edge (:func:`hzval.geometry.model.seam_edge_ends`: two triangles meet at the same positions with
different UVs or tangents) is where a tangent-space technique reads two charts of the texture and
its frame jumps: a horizon map baked on the tile searches across the chart's border into texels
that lie elsewhere on the model. Per pixel, the distance from the base point under its truth hit
to the nearest seam edge, in texels of the world (``world_per_uv / cols`` world units a texel);
:func:`shares` says which part of the summed |F - V| and which part of the pixels lie within
:data:`SEAM_TEXELS` of one: an error share well above the pixel share is error the seams cause.
"""

from __future__ import annotations

import numpy as np

from hzval.geometry import model as hm

__all__ = ["SEAM_TEXELS", "seam_distance_texels", "shares"]

#: "Within a few texels": the bake's bilinear lookup reaches one texel across, its search farther.
SEAM_TEXELS = 3.0
#: Points sampled along each seam edge, per texel of its length (distances exact to 1/8 texel).
_STEPS_PER_TEXEL = 4


def seam_distance_texels(model, points: np.ndarray, texel_world: float) -> np.ndarray:
    """Return the distance of each world point to the nearest seam edge of ``model``, in texels.

    The result is ``(N,)``, a texel being ``texel_world`` world units; ``inf`` without seams, NaN where a
    point is NaN.
    """
    # SciPy: 0.3-0.4 s to import, paid only where it is used
    from scipy.spatial import cKDTree

    points = np.asarray(points, np.float64)
    out = np.full(len(points), np.inf)
    ends = hm.seam_edge_ends(model)
    if len(ends) == 0:
        out[~np.isfinite(points).all(axis=1)] = np.nan
        return out
    a, b = model.positions[ends[:, 0]], model.positions[ends[:, 1]]
    steps = np.maximum(1, np.ceil(np.linalg.norm(b - a, axis=1) / texel_world * _STEPS_PER_TEXEL)).astype(int)
    samples = np.concatenate(
        [a[i] + np.linspace(0.0, 1.0, k + 1)[:, None] * (b[i] - a[i]) for i, k in enumerate(steps)]
    )
    ok = np.isfinite(points).all(axis=1)
    out[~ok] = np.nan
    out[ok] = cKDTree(samples).query(points[ok])[0] / texel_world
    return out


def shares(error: np.ndarray, near: np.ndarray, keep: np.ndarray) -> dict:
    """Return the seams' share of the summed error and of the pixels, over the pixels ``keep``.

    ``error_share`` is the share of the summed ``error`` on the pixels ``near`` a seam and ``pixel_share`` the
    share of the pixels there; ``None`` where nothing is kept or no error.
    """
    e, n = np.asarray(error, np.float64)[keep], np.asarray(near, bool)[keep]
    total = float(e.sum())
    return {
        "error_share": float(e[n].sum() / total) if total > 0 else None,
        "pixel_share": float(n.mean()) if len(n) else None,
    }
