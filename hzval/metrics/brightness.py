"""Why an engine's frame is off the truth's brightness as a whole: a factor of pi, a gamma of 2.2, sRGB twice.

A frame ``pi`` times too bright scores a large FLIP against the truth with no hint why.
:func:`diagnose` tries the usual slips on the truth ``T`` (linear radiance; ``x = clip(exposure T)``
its display-scaled value, ``exposure`` from ``frames.json``) and names the one that explains the
engine's frame ``E`` (as :func:`hzval.commands.score.read_frame` decoded it) far better than ``T`` itself:

    ``pi``          ``E = pi T``: the Lambert BRDF's ``1 / pi`` left out (radiance = albedo / pi * E cos)
    ``1/pi``        ``E = T / pi``: ``1 / pi`` applied twice
    ``gamma``       ``E = x^(1/2.2) / exposure``: display values (gamma 2.2) where radiance is expected
    ``degamma``     ``E = x^2.2 / exposure``: a gamma of 2.2 applied to linear values once more
    ``srgb``        ``E = srgb_encode(x) / exposure``: sRGB-encoded twice (a PNG), or display values in
                    an EXR, which is read as linear radiance
    ``linear``      ``E = srgb_decode(x) / exposure``: linear values in a PNG, not sRGB-encoded

A slip is named when its mean ``|E - c(T)|`` (display-scaled, ``1`` = white) is at most
:data:`BETTER` of the frame's own ``|E - T|`` and that is at least :data:`NOTICEABLE`: a frame
whose only difference is its shadows is explained by no slip.
"""

from __future__ import annotations

import numpy as np

from hzval.core import srgb

__all__ = ["diagnose", "SLIPS", "BETTER", "NOTICEABLE"]

#: A slip must explain the frame this much better than the truth does (its error at most this share).
BETTER = 0.5
#: The frame's own mean |E - T| (display-scaled) below which nothing is diagnosed.
NOTICEABLE = 0.02


def _slips(x: np.ndarray) -> dict:
    """Each slip's ``exposure * E`` from the display-scaled truth ``x`` in [0, 1]."""
    return {
        "pi": np.pi * x,
        "1/pi": x / np.pi,
        "gamma": x ** (1 / 2.2),
        "degamma": x**2.2,
        "srgb": srgb.encode(x),
        "linear": srgb.decode(x),
    }


#: What each slip says, the likely cause (``{png}``: whether the frame was a PNG).
SLIPS = {
    "pi": "about pi times too bright: is the Lambert BRDF's 1/pi missing (radiance = albedo / pi * E * N.L)?",
    "1/pi": "about pi times too dark: is 1/pi applied twice (or the irradiance divided by pi)?",
    "gamma": "brighter in the darks as a gamma of 1/2.2 makes it: "
    "display values where linear radiance is expected?",
    "degamma": "darker in the darks as a gamma of 2.2 makes it: a gamma applied to linear values?",
    "srgb": "brighter in the darks as sRGB encoding makes it: {srgb}",
    "linear": "darker in the darks as sRGB decoding makes it: {linear}",
}


def diagnose(engine: np.ndarray, truth: np.ndarray, exposure: float, png: bool = False) -> dict | None:
    """Which brightness slip of :data:`SLIPS` explains an engine's frame, if one does.

    The engine's and the truth's exposed values are compared as they are and with each slip applied
    to the truth; a slip is named when it explains the frame at least 1 / :data:`BETTER` times better
    than no slip, and the frame differs noticeably (:data:`NOTICEABLE`).

    Parameters
    ----------
    engine, truth : numpy.ndarray
        ``(H, W, 3)`` linear radiance of one light.
    exposure : float
        The sweep's exposure (:func:`hzval.core.shading.exposure`).
    png : bool
        Whether the engine's frame was read from a PNG (the sRGB slips then say so).

    Returns
    -------
    dict or None
        ``{slip, line, error, own_error, ratio}``: the slip, its one-line diagnosis, the mean absolute
        error with it and without, and their ratio; ``None`` when no slip explains the frame.
    """
    e = np.clip(np.asarray(engine, np.float64) * exposure, 0.0, None)
    x = np.clip(np.asarray(truth, np.float64) * exposure, 0.0, 1.0)
    own = float(np.mean(np.abs(e - x)))
    if own < NOTICEABLE:
        return None
    errors = {k: float(np.mean(np.abs(e - v))) for k, v in _slips(x).items()}
    slip = min(errors, key=errors.get)
    if errors[slip] > BETTER * own:
        return None
    srgb = (
        "the PNG sRGB-encoded twice?"
        if png
        else "display (sRGB) values in an EXR, which hzval reads as linear radiance "
        "(frames.json exposure_meaning)?"
    )
    linear = (
        "linear values written to the PNG without sRGB encoding (frames.json exposure_meaning)?"
        if png
        else "sRGB decoding applied to linear radiance?"
    )
    ratio = float(e.mean() / max(x.mean(), 1e-12))
    return {
        "slip": slip,
        "line": SLIPS[slip].format(srgb=srgb, linear=linear),
        "error": errors[slip],
        "own_error": own,
        "ratio": ratio,
    }
