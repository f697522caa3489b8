"""hzval.metrics.brightness: a frame's brightness slips (a factor pi, sRGB twice or not at all) named,
on images made from a known one."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hzval.core import srgb
from hzval.metrics import brightness


@pytest.fixture(scope="module")
def truth_image():
    rng = np.random.default_rng(3)
    T = rng.uniform(0.05, 0.3, (24, 24, 3))
    T[:8] = 0.0  # shadows
    return T


@pytest.mark.parametrize(
    "slip, make, png",
    [
        ("pi", lambda T, e: np.pi * T, False),
        ("1/pi", lambda T, e: T / np.pi, False),
        ("srgb", lambda T, e: srgb.encode(np.clip(T * e, 0, 1)) / e, False),
        ("linear", lambda T, e: srgb.decode(np.clip(T * e, 0, 1)) / e, True),
        ("degamma", lambda T, e: np.clip(T * e, 0, 1) ** 2.2 / e, False),
    ],
)
def test_brightness_slips_are_named(truth_image, slip, make, png):
    e = math.pi
    found = brightness.diagnose(make(truth_image, e), truth_image, e, png=png)
    assert found is not None and found["slip"] == slip, found
    if slip == "pi":
        assert found["ratio"] == pytest.approx(math.pi, rel=1e-6) and "1/pi" in found["line"]
    if slip == "linear":
        assert "PNG" in found["line"]


def test_a_frame_that_differs_in_its_shadows_only_is_no_slip(truth_image):
    other = truth_image.copy()
    other[:8] = 0.2  # leaks everywhere the truth is shadowed
    assert brightness.diagnose(other, truth_image, math.pi) is None
    assert brightness.diagnose(truth_image, truth_image, math.pi) is None
