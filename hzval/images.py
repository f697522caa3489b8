"""The visualisations of a comparison: visibility-difference and FLIP maps, and their colours.

One module owns them, so that the sweep that paints them, the report that
explains them (legends, plot lines) and the check that shows its own
difference maps agree on every colour. Images out are 8-bit sRGB
``(H, W, 3)`` arrays ready for :func:`hzval.files.write_png`.
"""

from __future__ import annotations

import numpy as np

from hzval import files
from hzval.compare import LIT_THRESHOLD

__all__ = ["LEAK_RGB", "FALSE_SHADOW_RGB", "hex_colour", "visibility_diff_image", "magma", "flip_image"]

#: Where the technique lights what the truth shadows (a light leak), sRGB 8-bit.
LEAK_RGB = (255, 127, 14)
#: Where the technique shadows what the truth lights (a false shadow), sRGB 8-bit.
FALSE_SHADOW_RGB = (31, 119, 180)


def hex_colour(rgb) -> str:
    """``(255, 127, 14)`` -> ``"#ff7f0e"``."""
    return "#" + "".join(f"{int(c):02x}" for c in rgb)


def visibility_diff_image(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """8-bit RGB map of a factor ``F`` against the truth's visibility ``V`` (both ``(H, W)`` in [0, 1]).

    Grey where they agree (``0.25 + 0.5 V``: darker in shadow), :data:`LEAK_RGB`
    where ``F`` is lit and ``V`` is not, :data:`FALSE_SHADOW_RGB` the other way
    round; lit means at least :data:`hzval.compare.LIT_THRESHOLD`, as the
    metrics count them.
    """
    grey = files.unit_to_u8(0.25 + 0.5 * np.clip(V, 0, 1))
    img = np.repeat(grey[..., None], 3, axis=-1)
    lit_truth, lit_approx = V >= LIT_THRESHOLD, F >= LIT_THRESHOLD
    img[lit_approx & ~lit_truth] = LEAK_RGB
    img[~lit_approx & lit_truth] = FALSE_SHADOW_RGB
    return img


def magma(values: np.ndarray) -> np.ndarray:
    """Values in [0, 1] (clipped) as 8-bit RGB through matplotlib's magma, FLIP's own colour map."""
    from matplotlib import colormaps

    return (colormaps["magma"](np.clip(values, 0, 1))[..., :3] * 255 + 0.5).astype(np.uint8)


def flip_image(error: np.ndarray) -> np.ndarray:
    """A FLIP error map (``(H, W)`` in [0, 1]) as 8-bit RGB, as FLIP shows it."""
    return magma(error)
