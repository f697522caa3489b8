"""What a frame's truth has to shadow (hzval.metrics.facing), on analytic cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hzval.core import conventions as cv
from hzval.metrics import facing as hzfacing


def _tilted(rows=8, cols=12, degrees=40.0):
    """Normals of a surface whose left half slopes down to +x by ``degrees`` and right half to -x."""
    a = math.radians(degrees)
    n = np.zeros((rows, cols, 3))
    n[:, : cols // 2] = (math.sin(a), 0.0, math.cos(a))
    n[:, cols // 2 :] = (-math.sin(a), 0.0, math.cos(a))
    return n


def test_facing_mask_is_the_sign_of_n_dot_l():
    n = _tilted()
    L = cv.light_direction(180.0, 30.0)  # from -x, 30 degrees up: the half tilted 40 degrees to +x faces away
    mask = hzfacing.facing_mask(n, L)
    assert not mask[:, :6].any() and mask[:, 6:].all()
    mirrored = hzfacing.facing_mask(n[:, ::-1] * np.array([-1, 1, 1]), cv.light_direction(0.0, 30.0))
    np.testing.assert_array_equal(mirrored, mask[:, ::-1])  # mirror x: the same mask, mirrored
    assert hzfacing.facing_mask(
        n, cv.light_direction(180.0, 60.0)
    ).all()  # above the slope: everything faces it
    big = hzfacing.facing_mask(n, L, supersampling=3)
    assert big.shape == (24, 36) and np.array_equal(big[::3, ::3], mask)


def test_truth_statistics_and_facing_metrics():
    V = np.zeros((8, 12))
    V[:, 6:] = 1.0
    V[0, 6:9] = 0.0  # a cast shadow on the lit side: 3 pixels
    V[1, 6] = 0.5  # a penumbra pixel
    mask = hzfacing.facing_mask(_tilted(), cv.light_direction(180.0, 30.0))
    t = hzfacing.truth_statistics(V, mask, spp=4)
    assert t["attached_fraction"] == pytest.approx(0.5)
    assert t["shadowed_fraction"] == pytest.approx((48 + 3) / 96)
    assert t["cast_fraction"] == pytest.approx(3 / 96)
    assert t["partial_fraction"] == pytest.approx(1 / 96)
    assert t["visibility_se"] == pytest.approx(math.sqrt(0.25 / 4) / 96)
    # F lights every pixel: over the whole image its leaks count the attached half, over the facing pixels not
    F = np.ones_like(V)
    m = hzfacing.facing_metrics(V.astype(np.float32), F.astype(np.float32), mask)
    assert m["leak_fraction_facing"] == pytest.approx(3 / 48)
    assert m["visibility_mae_facing"] == pytest.approx((3 + 0.5) / 48)
    assert m["false_shadow_fraction_facing"] == 0
    assert hzfacing.facing_metrics(V, F, np.zeros_like(mask)) == dict.fromkeys(hzfacing.FACING_KEYS)


def test_few_shadows_are_said_once():
    frames = [
        {"azimuth_deg": a, "truth": {"cast_fraction": c}} for a, c in ((-30, 0.001), (0, 0.2), (30, 0.0))
    ]
    line = hzfacing.few_shadows_warning(frames)
    assert "2 of 3 frames" in line and "az-30 0.10%" in line and "az+30 0.00%" in line and "--depth" in line
    assert hzfacing.few_shadows_warning(frames[1:2]) is None
