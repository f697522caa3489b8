"""The visualisations of a comparison: visibility-difference and FLIP maps, and their colours.

One module owns them, so that the sweep that paints them, the report that
explains them (legends, plot lines) and the check that shows its own
difference maps agree on every colour. Images out are 8-bit sRGB
``(H, W, 3)`` arrays ready for :func:`hzval.io.codecs.write_png`, or the same
pixels as :class:`hzval.io.codecs.Indexed` palette images (``*_indexed``: the
sweep's frame files, a third of the bytes).
"""

from __future__ import annotations

import functools

import numpy as np

from hzval.io import codecs
from hzval.metrics.compare import LIT_THRESHOLD

__all__ = [
    "LEAK_RGB",
    "FALSE_SHADOW_RGB",
    "hex_colour",
    "visibility_diff_image",
    "visibility_diff_indexed",
    "VisibilityDiff",
    "magma",
    "magma_palette",
    "magma_index",
    "flip_image",
    "flip_indexed",
]

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
    round; lit means at least :data:`hzval.metrics.compare.LIT_THRESHOLD`, as the
    metrics count them.
    """
    return VisibilityDiff(V).image(F)


def visibility_diff_indexed(V: np.ndarray, F: np.ndarray) -> codecs.Indexed | np.ndarray:
    """Return :func:`visibility_diff_image` as a palette image, pixel for pixel, a third of the RGB bytes.

    The palette is its grey levels (at most 128 for ``V`` in [0, 1]) and the two colours. It is RGB in the
    case (non-finite ``V``) where more than 256 colours would be needed.
    """
    return VisibilityDiff(V).indexed(F)


class VisibilityDiff:
    """The truth's half of one frame's visibility-difference maps, made once for every technique's factor.

    The maps are :func:`visibility_diff_image`'s, each factor compared with it. It holds its grey levels,
    where it is lit, and how many pixels have each grey level.

    Parameters
    ----------
    V : numpy.ndarray
        ``(H, W)`` the truth's visibility, in [0, 1].

    Attributes
    ----------
    grey : numpy.ndarray
        ``(H, W)`` uint8, the map's grey where the technique agrees (``0.25 + 0.5 V``).
    lit : numpy.ndarray
        ``(H, W)`` bool, where the truth is lit (at least :data:`hzval.metrics.compare.LIT_THRESHOLD`).
    """

    def __init__(self, V: np.ndarray):
        V = np.asarray(V)
        self.grey = codecs.unit_to_u8(0.25 + 0.5 * np.clip(V, 0, 1))
        self.lit = V >= LIT_THRESHOLD
        self._counts = np.bincount(self.grey.ravel(), minlength=256)

    def _marks(self, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(leak mask, false-shadow mask)`` of the factor ``F``."""
        lit_test = np.asarray(F) >= LIT_THRESHOLD
        return lit_test & ~self.lit, ~lit_test & self.lit

    def image(self, F: np.ndarray) -> np.ndarray:
        """Return the map of a technique's factor ``F`` (``(H, W)`` in [0, 1]) as 8-bit RGB ``(H, W, 3)``."""
        leak, false_shadow = self._marks(F)
        img = np.repeat(self.grey[..., None], 3, axis=-1)
        img[leak] = LEAK_RGB
        img[false_shadow] = FALSE_SHADOW_RGB
        return img

    def indexed(self, F: np.ndarray) -> codecs.Indexed | np.ndarray:
        """Return the map of a technique's factor ``F`` as a palette image.

        ``F`` is ``(H, W)`` in [0, 1]; the image is :func:`visibility_diff_indexed`'s.
        """
        leak, false_shadow = self._marks(F)
        marked = leak | false_shadow
        # the grey levels left where neither colour is painted: every pixel's count less the
        # marked ones' (few), not a count over a copy of the unmarked pixels
        shown = self._counts - np.bincount(self.grey[marked], minlength=256)
        levels = np.flatnonzero(shown)
        if len(levels) > 254:
            return self.image(F)
        slot = np.zeros(256, np.uint8)
        slot[levels] = np.arange(len(levels))
        index = slot[self.grey]
        index[leak] = len(levels)
        index[false_shadow] = len(levels) + 1
        palette = np.concatenate([np.repeat(levels[:, None], 3, axis=1), [LEAK_RGB, FALSE_SHADOW_RGB]])
        return codecs.Indexed(index, palette.astype(np.uint8))


def magma(values: np.ndarray) -> np.ndarray:
    """Return values in [0, 1] (clipped) as 8-bit RGB through matplotlib's magma, FLIP's own colour map.

    NaN is black, as matplotlib's "bad" colour without its alpha.
    """
    values = _as_float(values)
    rgb = magma_palette()[magma_index(values)]
    rgb[np.isnan(values)] = 0
    return rgb


@functools.cache
def magma_palette() -> np.ndarray:
    """Matplotlib's magma as 256 8-bit sRGB colours ``(256, 3)``, rounded to nearest."""
    # matplotlib: 0.6 s to import, paid only where a figure is drawn
    from matplotlib import colormaps

    palette = (colormaps["magma"](np.arange(256))[..., :3] * 255 + 0.5).astype(np.uint8)
    palette.flags.writeable = False
    return palette


def magma_index(values: np.ndarray) -> np.ndarray:
    """Return the magma colour (:func:`magma_palette`) index, uint8, of values in [0, 1] (clipped).

    It is picked as matplotlib picks it: ``floor(256 x)``, 1 in the top colour; NaN gets 0 (:func:`magma`
    paints it black). ``256 x`` is exact in any binary float type, so the index is matplotlib's for each.
    """
    v = _as_float(values)
    x = np.empty_like(v)  # an array even for a scalar, so that the steps below work in place
    with np.errstate(over="ignore"):  # a value beyond max / 256 is 255 either way
        np.multiply(v, 256, out=x)
    np.fmax(x, 0, out=x)  # fmax, not maximum: NaN gives 0
    np.minimum(x, 255, out=x)
    return x.astype(np.uint8)


def _as_float(values) -> np.ndarray:
    """Return an array of a float type as it is (its own precision decides the index), others as float64."""
    values = np.asarray(values)
    return values if np.issubdtype(values.dtype, np.floating) else values.astype(np.float64)


def flip_image(error: np.ndarray) -> np.ndarray:
    """Return a FLIP error map (``(H, W)`` in [0, 1]) as 8-bit RGB, as FLIP shows it."""
    return magma(error)


def flip_indexed(error: np.ndarray) -> codecs.Indexed | np.ndarray:
    """Return :func:`flip_image` as a palette image of magma's 256 colours, pixel for pixel.

    The index is the colour map's, so nothing is lost, and it takes a third of the RGB bytes. It is RGB if
    ``error`` has a NaN (whose black is no magma colour).
    """
    error = _as_float(error)
    if np.isnan(error).any():
        return flip_image(error)
    return codecs.Indexed(magma_index(error), magma_palette())
