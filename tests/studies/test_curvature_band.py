"""The band measurement (hzval.studies.curvature_band): which pixels count, texel means, the pairing with the
flat patch and the trend's verdict on synthetic rows whose answer is known."""

import math

import numpy as np
import pytest

from hzval.core import conventions as cv
from hzval.studies import curvature_band


def test_the_band_holds_the_normals_that_see_the_light_at_its_elevation():
    L = cv.light_direction(0.0, 30.0)

    def tilt(deg):
        return np.array([math.sin(math.radians(deg)), 0.0, math.cos(math.radians(deg))])

    n = np.stack([tilt(0.0), tilt(2.9), tilt(-2.9), tilt(3.5), tilt(-10.0)])
    assert curvature_band.in_band(n, L, 30.0, 3.0).tolist() == [True, True, True, False, False]
    # turned about the light's azimuth's normal (across the light) the local elevation barely moves
    side = np.array([[0.0, math.sin(0.2), math.cos(0.2)]])
    assert curvature_band.in_band(side, L, 30.0, 1.0)[0]  # cos(0.2) lowers sin(elevation) by 2%: 0.65 degrees
    assert not curvature_band.in_band(side, L, 30.0, 0.5)[0]


def test_texel_means_average_the_pixels_of_each_texel():
    values = np.array([1.0, 3.0, 5.0, 7.0, 100.0])
    texel = np.array([0, 0, 2, 2, 1])
    keep = np.array([True, True, True, False, False])
    m = curvature_band.texel_means(values, texel, keep, 4)
    assert m[0] == 2.0 and m[2] == 5.0 and np.isnan(m[1]) and np.isnan(m[3])


def _maps(values):
    """``(frames, texels)`` maps with the same value on every texel of a frame."""
    return np.repeat(np.asarray(values, np.float64)[:, None], 6, axis=1)


def test_the_excess_is_the_case_minus_the_flat_patch_on_the_same_texels():
    flat = {
        "techniques": {"h": {"mae": _maps([0.1, 0.2, 0.3]), "floor": _maps([0, 0, 0])}},
        "texels": [6, 6, 6],
    }
    case_mae = _maps([0.15, 0.22, 0.33])
    case_mae[:, :3] = np.nan  # the band holds half the texels
    flat["techniques"]["h"]["mae"][:, 3] = 9.0  # a texel outside... inside the band, read on both
    case = {"techniques": {"h": {"mae": case_mae, "floor": _maps([0, 0, 0])}}, "texels": [3, 3, 3]}
    row = curvature_band.paired(case, flat)
    h = row["techniques"]["h"]
    ref = [(9.0 + 2 * v) / 3 for v in (0.1, 0.2, 0.3)]
    np.testing.assert_allclose(h["per_frame"], [0.15, 0.22, 0.33])
    np.testing.assert_allclose(h["per_frame_excess"], np.array([0.15, 0.22, 0.33]) - ref)
    assert h["mae"]["frames"] == 3 and h["mae"]["se"] > 0
    assert row["texels"] == 3


def _rows(means, spread=0.01, frames=16, seed=0):
    """Per-frame values about each mean: a shared per-light offset (which pairing cancels) plus noise."""
    rng = np.random.default_rng(seed)
    light = rng.normal(0.0, 0.05, frames)
    return [(k, list(m + light + rng.normal(0.0, spread, frames))) for k, m in means]


def test_trend_rises_monotonically():
    t = curvature_band.trend(_rows([(0.0, 0.10), (0.5, 0.12), (1.0, 0.15), (2.0, 0.20)], spread=0.001))
    assert t["verdict"] == "rises monotonically" and not t["falls"]
    assert t["overall"]["change"] == pytest.approx(0.10, abs=0.005) and t["overall"]["z"] > 10


def test_trend_order_does_not_matter():
    rows = _rows([(0.0, 0.10), (0.5, 0.12), (1.0, 0.15)], spread=0.001)
    assert curvature_band.trend(rows[::-1])["steps"] == curvature_band.trend(rows)["steps"]


def test_a_small_fall_is_noise_a_large_one_is_not():
    small = curvature_band.trend(_rows([(0.0, 0.10), (0.5, 0.1595), (1.0, 0.159), (2.0, 0.20)], spread=0.004))
    assert small["verdict"] == "rises within noise"
    assert len(small["falls"]) == 1 and -curvature_band.NOISE_Z < small["falls"][0]["z"] <= 0
    large = curvature_band.trend(_rows([(0.0, 0.10), (0.5, 0.16), (1.0, 0.12), (2.0, 0.20)], spread=0.004))
    assert large["verdict"] == "does not rise" and large["falls"][0]["z"] < -curvature_band.NOISE_Z


def test_flat_within_noise_does_not_rise():
    rows = [(0.0, [0.10, 0.12, 0.11, 0.13]), (0.5, [0.12, 0.11, 0.12, 0.12]), (1.0, [0.11, 0.13, 0.11, 0.13])]
    t = curvature_band.trend(rows)  # every step up, by less than its noise
    assert all(s["change"] > 0 for s in t["steps"]) and t["overall"]["z"] < curvature_band.NOISE_Z
    assert t["verdict"] == "does not rise"
    falling = curvature_band.trend(_rows([(0.0, 0.20), (1.0, 0.15), (2.0, 0.10)], spread=0.001))
    assert falling["verdict"] == "does not rise" and len(falling["falls"]) == 2
