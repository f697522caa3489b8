"""Precision: 8-bit horizon storage near the horizon and the 8-bit cube map's zero weight on the
GPU path; float32 accumulation in the bake of wide maps (a 4096-wide strip by default, and the
whole 4096 x 4096 map).
"""

import math
import time

import numpy as np
import pytest

import hzval.bake as B
from hzval.techniques.horizon import Horizon

from ._ref import assert_bake_sane, exact_weights, gpu_weights, horizon_f64, light32, make_scene, uniform_bake

pytestmark = pytest.mark.hard
K = 8.0


# --------------------------------------------------------------------------
# 8-bit storage near the horizon
# --------------------------------------------------------------------------

#: horizon angles near 0, in degrees: below, at and above half an 8-bit step (asin(0.5/255) = 0.1123)
SMALL_ANGLES = (0.05, 0.11, 0.12, 0.3, 0.5, 1.0, 2.0, 3.0)


@pytest.mark.parametrize("angle", SMALL_ANGLES)
def test_8_bit_horizon_near_the_horizon_is_rounded_to_the_nearest_255th(variant, angle):
    """The GPU path stores sin(alpha) as round(255 sin(alpha)) / 255: the horizon angle moves by at
    most asin(0.5/255) = 0.112 degrees, horizons under that vanish, and F moves by at most
    k (0.5/255 sum(w^) + sum |w^ - w| h) against the exact path (the cube's weights w^)."""
    s = math.sin(math.radians(angle))
    stored = round(255 * s) / 255
    assert abs(math.degrees(math.asin(stored)) - angle) <= math.degrees(math.asin(0.5 / 255)) + 1e-9
    if angle < math.degrees(math.asin(0.5 / 255)):
        assert stored == 0.0
    b = uniform_bake([s] * 8, rows=4, cols=4)
    sc = make_scene((4, 4), 0.1, "wrap")
    gpu, exact = Horizon(sc, b, path="gpu"), Horizon(sc, b, path="exact")
    x, y = np.array([1.5]), np.array([2.5])
    for az in (0.0, 22.5, 45.0, 100.0, 359.0):
        for el in (0.0, 0.05, 0.1, 0.5, 1.0, 2.0, 5.0):
            L = light32(az, el)
            g, e = gpu.sample(x, y, az, el), exact.sample(x, y, az, el)
            wg, w = gpu_weights(L), exact_weights(L)
            assert g["horizon_sine"][0] == pytest.approx(wg.sum() * stored, abs=2e-6), (az, el)
            assert e["horizon_sine"][0] == pytest.approx(s, abs=2e-7)
            bound = K * (0.5 / 255 * wg.sum() + np.abs(wg - w).sum() * s) + 1e-5
            assert abs(g["factor"][0] - e["factor"][0]) <= bound, (az, el)
            assert 0.0 <= g["factor"][0] <= 1.0


def test_8_bit_horizon_near_the_horizon_on_a_bake(variant):
    """A ramp rising 0.3 degrees toward +x (open): every horizon sine is at most sin 0.3 = 0.0052,
    stored as 1/255 or 0; at a light elevation of 0.5 degrees the exact path is fully lit
    (F = 1: Lz >= s) and the GPU path within the bound above."""
    cols = 48
    h = np.tile(np.arange(cols, dtype=np.float32) / (cols - 1), (6, 1))
    depth = math.tan(math.radians(0.3)) * (cols - 1) / cols
    b = B.bake(h, B.BakeParams(depth=depth, boundary="open"))
    assert b.horizon.max() <= math.sin(math.radians(0.3)) + 1e-6
    assert set(np.unique(np.rint(b.horizon * 255))) <= {0.0, 1.0}
    sc = make_scene(h.shape, depth, "open", spp=4)
    for az in (0.0, 30.0, 180.0):
        F_exact = Horizon(sc, b).render(az, elevation_deg=0.5).layers["factor"]
        F_gpu = Horizon(sc, b, path="gpu").render(az, elevation_deg=0.5).layers["factor"]
        assert np.all(F_exact == 1.0)
        L = light32(az, 0.5)
        wg = gpu_weights(L)
        bound = (
            K
            * (
                0.5 / 255 * wg.sum()
                + np.abs(wg - exact_weights(L)).sum() * b.horizon.max()
                + (wg.sum() - 1) * b.horizon.max()
            )
            + 1e-5
        )
        assert np.abs(F_gpu - F_exact).max() <= bound, az


# --------------------------------------------------------------------------
# The cube map's zero weight: 127.5 cannot be stored
# --------------------------------------------------------------------------


def test_cube_zero_weight_leaks_exactly_one_255th_on_layer_0(variant):
    """Measured: for every channel whose weight is 0 over the whole bilinear footprint (more than
    6 degrees from its tent), the GPU path's factor is 128/255 -> clamp(2f - 1) = 1/255 on layer 0
    (channels 0-3) and clamp(1 - 2f) = 0 on layer 1 (channels 4-7). So at most three channels leak
    (the other layer-0 components carry a weight or a negative one), 3/255 in all; measured over
    the azimuths in 2.5-degree steps: 2/255 at most."""
    leak0 = 2 * 128 / 255 - 1
    worst_total = 0.0
    for az in np.arange(0.0, 360.0, 2.5):
        for el in (0.0, 20.0, 44.0):
            L = light32(az, el)
            w, wg = exact_weights(L), gpu_weights(L)
            far = np.array(
                [
                    min(abs((az - 45 * c + 180) % 360 - 180), abs((az - 45 * c) % 360 - 180)) > 45 + 6
                    for c in range(8)
                ]
            )
            # a channel is 'far' when neither it nor its opposite is within 51 degrees
            for c in range(8):
                if far[c] and far[(c + 4) % 8]:
                    assert w[c] == 0.0
                    assert wg[c] == pytest.approx(leak0 if c < 4 else 0.0, abs=1e-12), (az, el, c)
            zero = np.array([far[c] and far[(c + 4) % 8] for c in range(8)])
            worst_total = max(worst_total, float(wg[zero].sum()))
    assert leak0 == pytest.approx(1 / 255, abs=1e-15)
    assert worst_total <= 3 / 255 + 1e-12
    print(
        f"zero-weight leak per layer-0 channel 1/255 = {leak0:.5f}; worst total {worst_total * 255:.2f}/255"
    )


def test_cube_leak_darkens_a_grazing_light_by_k_times_the_leak(variant):
    """Horizon 0.9 toward 0-135 degrees (layer 0) and 0 toward 180-315: a light at azimuth 202.5
    (between channels 4 and 5) sees no horizon (exact F = 1 for any Lz > 0). On the GPU path
    components 0 and 1 carry channels 4's and 5's weights (negative: no layer-0 weight), while
    components 2 and 3 hold zero weights (channels 2, 3, 6, 7 are 67.5 degrees or more away):
    128/255 each, a leak of 1/255 from channels 2 and 3. So s = 2 * 0.9/255 and near the horizon
    F drops to 1 + k (Lz - 1.8/255) < 1. Bound over all lights: k * 3/255 * max h = 0.0847."""
    b = uniform_bake([0.9] * 4 + [0.0] * 4)
    sc = make_scene((4, 4), 0.1, "wrap")
    gpu, exact = Horizon(sc, b, path="gpu"), Horizon(sc, b, path="exact")
    h8 = round(0.9 * 255) / 255
    az = 202.5
    for el in (0.1, 0.5, 1.0):
        assert gpu_weights(light32(az, el))[:4] == pytest.approx([0, 0, 1 / 255, 1 / 255], abs=1e-12)
        lz = float(light32(az, el)[2])
        g = gpu.sample([1.5], [1.5], az, el)
        assert g["horizon_sine"][0] == pytest.approx(2 * h8 / 255, abs=1e-6)
        assert g["factor"][0] == pytest.approx(min(1.0, 1 + K * (lz - 2 * h8 / 255)), abs=1e-5)
        assert exact.sample([1.5], [1.5], az, el)["factor"][0] == 1.0
        assert 1.0 - g["factor"][0] <= K * 3 / 255 * 0.9 + 1e-6
    assert gpu.sample([1.5], [1.5], az, 0.1)["factor"][0] < 0.96  # the leak is visible there: 0.957


# --------------------------------------------------------------------------
# float32 accumulation on wide maps
# --------------------------------------------------------------------------


def f32_bound(h_tex):
    """|s_f32 - s_f64| for heights of at most hmax texels: the float32 heights are rounded by
    2^-24 hmax each, so dh = h' - h0 by 2^-23 hmax (r >= 1 keeps tan within that); the float32
    difference, 1/r, product, sqrt and mean add a few ulps of their results (<= 1 each after
    the sine): 2^-22 (hmax + 2) in all."""
    return 2.0**-22 * (float(np.abs(h_tex).max()) + 2.0)


def _compare_with_f64(h, depth, points=None):
    r = B.bake(h, B.BakeParams(depth=depth))
    exact_heights = h.astype(np.float64) * depth * h.shape[1]  # float64, never rounded to float32
    ref, mc, mc2 = horizon_f64(exact_heights, points=points)
    got = r.horizon.reshape(-1, 8) if points is None else r.horizon[points[0], points[1]]
    err = np.abs(got - ref).max()
    return r, err, f32_bound(exact_heights)


def test_float32_bake_of_a_4096_wide_strip_matches_float64(variant):
    """A 16 x 4096 strip at depth 0.05: heights up to 204.8 texels, as on a 4096 x 4096 map (the
    height scale is per image width); smooth large-scale relief plus texel noise, so dh is a small
    difference of large heights. Error bound 2^-22 (hmax + 2) = 4.9e-5."""
    rng = np.random.default_rng(12)
    x = np.arange(4096) / 4096
    h = (0.5 + 0.45 * np.sin(2 * np.pi * x)[None, :] + 0.01 * rng.random((16, 4096))).astype(np.float32)
    r, err, bound = _compare_with_f64(h, 0.05)
    assert_bake_sane(r)
    print(f"4096-wide strip: max |s_f32 - s_f64| = {err:.2e} (bound {bound:.2e})")
    assert err <= bound


@pytest.mark.slow(
    reason="bakes a whole 4096 x 4096 map (2.7 GB at peak); the 4096-wide strip keeps its heights fast"
)
def test_float32_bake_of_a_4096_square_map_matches_float64(variant):
    """The whole 4096 x 4096 map, checked at 4096 texels against float64."""
    rng = np.random.default_rng(13)
    n = 4096
    x = np.arange(n) / n
    h = (
        0.5
        + 0.2 * np.sin(2 * np.pi * x)[None, :] * np.cos(2 * np.pi * x)[:, None]
        + 0.01 * rng.random((n, n), dtype=np.float32)
    ).astype(np.float32)
    t0 = time.perf_counter()
    points = (rng.integers(0, n, 4096), rng.integers(0, n, 4096))
    r, err, bound = _compare_with_f64(h, 0.05, points)
    assert_bake_sane(r)
    print(
        f"4096 x 4096: max |s_f32 - s_f64| = {err:.2e} (bound {bound:.2e}), {time.perf_counter() - t0:.1f} s"
    )
    assert err <= bound
