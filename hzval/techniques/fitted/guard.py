"""The fit's guard: keep the baked map where the fitted one is worse on some training light nearby.

The optimiser (:mod:`hzval.techniques.fitted.fit`) minimises the *mean* error over the training lights, so
it may
trade: raise a texel's sine toward a direction to win at one elevation and lose at another. On
the training lights the trade pays; on a light between the training elevations it may not, and on
a frame where the bake is nearly exact (little shadow toward that azimuth) every such trade is a
loss, which makes a held-out frame worse than the bake's (``horizon-fit`` must never
be worse than ``horizon`` on a frame).

The guard undoes the trades texel by texel. A texel's *regression* at a light is the sum, over
the pixels whose samples read it (its 3 x 3 neighbourhood at one pixel a texel: a pixel's samples
span it and the bilinear filter reaches one texel further), of ``|F - V|`` of the current map minus
that of the baked map. A texel whose worst regression over the training lights exceeds
``tolerance`` (pixels' worth of ``|F - V|``) gets its baked sines back (all eight channels;
with a block format, the whole 4 x 4 block, which is encoded as one); this is repeated, since a
texel's regression may be its neighbour's doing, until no kept texel regresses or ``rounds`` have
passed (``verified`` says which). What is left is, on every training light and every neighbourhood,
at most ``tolerance`` worse than the bake: a texel is fitted only where the fit wins without trading.

Opt-in (``hzval fit --guard TOL``; :func:`hzval.techniques.fitted.fit.fit`'s ``guard``). Measured on the one
photo
whose frames got worse (docs/fit.md, colour-science's CVG_Background, 256, depth 0.05, wrap; trained
on 8 elevations 12.5..60, 4 spp): it did not help. The fit's gains there sit in few texels (the wrap
seam's cliff), whose trades the guard undoes: tolerance 0.25 reverted 1.2 % of the texels and took
the fitted/baked ratio at 25 degrees from 0.725 to 0.835 (0.5: 0.789, 1: 0.731), while the two
30-degree frames that got worse (|F - V| 3e-4 and 0 with the bake) stayed worse at every
tolerance: their losses come from texels that regress on no training light, at elevations between
the training ones.
"""

from __future__ import annotations

from typing import Callable, Iterable

import numpy as np

__all__ = ["TOLERANCE", "ROUNDS", "neighbourhood_sum", "guard"]

#: A texel is reverted when its neighbourhood's |F - V| at some training light exceeds the bake's by
#: more than this (in pixels' worth of |F - V|: 0.05 is one pixel 5 % off, or five 1 % off).
TOLERANCE = 0.05
#: Passes over the training lights at most; the last one that reverts nothing verifies the map.
ROUNDS = 8


def neighbourhood_sum(x: np.ndarray, boundary: str, radius: int = 1) -> np.ndarray:
    """Return the sum of ``x`` over each texel's ``(2 radius + 1)^2`` neighbourhood.

    Parameters
    ----------
    x : numpy.ndarray
        ``(rows, cols)`` values.
    boundary : {"wrap", "open"}
        ``wrap`` wraps around; ``open`` cuts at the edges (nothing outside the image).
    radius : int
        Texels on each side.

    Returns
    -------
    numpy.ndarray
        ``(rows, cols)`` sums.
    """
    rows, cols = x.shape
    pad = np.pad(x, radius, mode="wrap" if boundary == "wrap" else "constant")
    out = np.zeros_like(x)
    for dr in range(2 * radius + 1):
        for dc in range(2 * radius + 1):
            out += pad[dr : dr + rows, dc : dc + cols]
    return out


def _cells(mask: np.ndarray, cell: int) -> np.ndarray:
    """``mask`` (rows, cols) widened to whole ``cell x cell`` blocks: a block is set if any texel is."""
    if cell == 1:
        return mask
    rows, cols = mask.shape
    R, C = -(-rows // cell), -(-cols // cell)
    padded = np.zeros((R * cell, C * cell), bool)
    padded[:rows, :cols] = mask
    blocks = padded.reshape(R, cell, C, cell).any(axis=(1, 3))
    return np.repeat(np.repeat(blocks, cell, 0), cell, 1)[:rows, :cols]


def guard(
    baked: np.ndarray,
    fitted: np.ndarray,
    errors: Callable[[np.ndarray, bool], Iterable[np.ndarray]],
    boundary: str,
    *,
    cell: int = 1,
    tolerance: float = TOLERANCE,
    rounds: int = ROUNDS,
    finish: Callable[[np.ndarray], np.ndarray] | None = None,
) -> tuple[np.ndarray, dict]:
    """Revert the fitted texels whose neighbourhood regresses against the baked map (module docstring).

    Parameters
    ----------
    baked, fitted : numpy.ndarray
        ``(rows, cols, D)`` sines.
    errors : callable
        ``errors(sines, baked)`` yields ``|F - V|`` ``(rows, cols)`` per training light of ``sines`` as
        stored (``baked``: whether they are the baked map, rendered with its own ``k``).
    boundary : {"wrap", "open"}
        The map's boundary.
    cell : int
        The storage's block side (4 for block formats, else 1).
    tolerance : float
        The regression, in pixels' ``|F - V|``, a neighbourhood may show.
    rounds : int
        The most passes.
    finish : callable, optional
        Makes a mixed map storable (a block format's round trip), after each round.

    Returns
    -------
    sines : numpy.ndarray
        ``fitted`` with the regressing texels reverted to ``baked``.
    record : dict
        The share of texels kept fitted, the passes, whether the last found nothing to revert
        (``verified``) and the worst regression left (``None`` unverified).
    """
    base = [np.asarray(e, np.float32) for e in errors(baked, True)]
    keep = np.ones(fitted.shape[:2], bool)
    current, verified, done = fitted, False, 0
    worst = np.zeros(keep.shape, np.float32)
    for done in range(1, rounds + 1):  # noqa: B007 - the count is reported after the loop
        worst = np.full(keep.shape, -np.inf, np.float32)
        for e, b in zip(errors(current, False), base):
            np.maximum(worst, neighbourhood_sum(np.asarray(e, np.float32) - b, boundary), out=worst)
        revert = _cells(keep & (worst > tolerance), cell) & keep
        if not revert.any():
            verified = True
            break
        keep &= ~revert
        current = np.where(keep[..., None], fitted, baked).astype(np.float32)
        if finish is not None:
            current = finish(current)
    left = float(worst[keep].max()) if verified and keep.any() else None
    return current, {
        "tolerance": tolerance,
        "rounds": done,
        "verified": verified,
        "kept_fitted": float(keep.mean()),
        "worst_regression_kept": left,
    }
