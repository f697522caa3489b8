"""Each convention of docs/ARCHITECTURE.md, pinned by a case whose answer is known."""

import math

import numpy as np
import pytest

from hzval.core import conventions as cv
from hzval.core import cube as cube_layout
from hzval.core import srgb


def test_texel_centres_row_zero_is_top():
    x, y = cv.texel_centres(rows=4, cols=3)
    assert x[0, 0] == 0.5 and x[0, 2] == 2.5
    assert y[0, 0] == 3.5  # top row is highest y
    assert y[3, 0] == 0.5


def test_pixel_and_tangent_offsets_are_inverse():
    assert cv.tangent_to_pixel_offset(1, 0) == (0, 1)  # +x is one column right
    assert cv.tangent_to_pixel_offset(0, 1) == (-1, 0)  # +y is one row up
    for dx, dy in [(3, -2), (-1, 5), (0, 0)]:
        assert cv.pixel_to_tangent_offset(*cv.tangent_to_pixel_offset(dx, dy)) == (dx, dy)


def test_heights_in_texels_use_image_width():
    h = np.ones((10, 40), np.float32)
    assert cv.heights_in_texels(h, 0.25)[0, 0] == pytest.approx(10.0)  # 0.25 * 40 cols


@pytest.mark.parametrize("az,expect", [(0, (1, 0)), (90, (0, 1)), (180, (-1, 0)), (270, (0, -1))])
def test_light_direction_azimuth_counterclockwise_from_x(az, expect):
    L = cv.light_direction(az, 0.0)
    assert L[:2] == pytest.approx(expect, abs=1e-12)
    assert cv.light_direction(az, 90.0) == pytest.approx([0, 0, 1], abs=1e-12)


def test_light_elevation():
    L = cv.light_direction(30.0, 30.0)
    assert np.linalg.norm(L) == pytest.approx(1.0)
    assert L[2] == pytest.approx(0.5)


def test_channel_layout():
    assert cv.CHANNEL_AZIMUTHS_DEG == (0, 45, 90, 135, 180, 225, 270, 315)
    assert cv.channel_layer(0) == (0, 0) and cv.channel_layer(3) == (0, 3)
    assert cv.channel_layer(4) == (1, 0) and cv.channel_layer(7) == (1, 3)


@pytest.mark.parametrize("az", [0, 45, 90, 135, 180, 225, 270, 315, 360, -0.0, -45])
def test_channel_weights_on_a_channel_direction_pick_that_channel(az):
    L = cv.light_direction(az, 20)
    w = cv.channel_weights(L[0], L[1])
    k = int(round(az / 45)) % 8
    assert w[k] == pytest.approx(1.0, abs=1e-9)
    assert w.sum() == pytest.approx(1.0)


def test_channel_weights_interpolate_linearly_in_azimuth():
    L = cv.light_direction(100.0, 10)  # between channel 2 (90) and 3 (135)
    w = cv.channel_weights(L[0], L[1])
    assert w[2] == pytest.approx(35 / 45) and w[3] == pytest.approx(10 / 45)
    assert np.count_nonzero(w) == 2


def test_cube_lookup_inverts_texel_directions():
    d = cube_layout.cube_texel_directions(16)
    face, s, t = cube_layout.cube_lookup(d)
    assert (face == np.arange(6)[:, None, None]).all()
    centres = (np.arange(16) + 0.5) / 16
    assert np.allclose(s, centres[None, None, :]) and np.allclose(t, centres[None, :, None])


def test_cube_faces_follow_opengl():
    # OpenGL table 8.19: +z face, s grows with +x, t grows with -y
    face, s, t = cube_layout.cube_lookup(np.array([[0.5, 0.0, 1.0], [0.0, 0.5, 1.0]]))
    assert list(face) == [4, 4]
    assert s[0] > 0.5 and t[1] < 0.5


def test_signed_weight_encoding():
    enc = cube_layout.encode_signed_weight(np.array([-1.0, 0.0, 1.0]))
    assert list(enc) == [0, 128, 255]
    # decoding zero with the shader's max(2f - 1, 0) leaks exactly 1/255 onto layer 0
    assert 2 * int(enc[1]) / 255 - 1 == pytest.approx(1 / 255)


def test_height_gradient_signs():
    rows, cols = 6, 8
    ramp_x = np.tile(np.arange(cols, dtype=np.float32), (rows, 1))  # rises to the right
    gx, gy = cv.height_gradient(ramp_x, "open")
    assert np.allclose(gx, 1.0) and np.allclose(gy, 0.0)
    ramp_up = np.tile(np.arange(rows, 0, -1, dtype=np.float32)[:, None], (1, cols))  # rises up the image
    gx, gy = cv.height_gradient(ramp_up, "open")
    assert np.allclose(gy, 1.0) and np.allclose(gx, 0.0)


def test_height_gradient_wrap_sees_across_the_edge():
    h = np.zeros((3, 5), np.float32)
    h[:, 0] = 2.0
    gx, _ = cv.height_gradient(h, "wrap")
    assert gx[0, 4] == pytest.approx(1.0)  # right neighbour of the last column is column 0
    gx, _ = cv.height_gradient(h, "open")
    assert gx[0, 4] == 0.0


def test_pad_heights():
    h = np.arange(6, dtype=np.float32).reshape(2, 3)
    w = cv.pad_heights(h, 4, "wrap")
    assert (w[4:6, 4:7] == h).all() and w[0, 0] == h[0, 2]
    o = cv.pad_heights(h, 1, "open")
    assert np.isneginf(o[0]).all() and (o[1:3, 1:4] == h).all()


def test_tangent_to_uv_of_drjit_arrays_is_numpys_bit_for_bit(variant):
    import mitsuba as mi

    rng = np.random.default_rng(4)
    x, y = (rng.random(10_001) * 517).astype(np.float32), (rng.random(10_001) * 383).astype(np.float32)
    x[:3], y[:3] = (0.0, 516.5, 517.0), (383.0, 0.5, 0.0)
    want_u, want_v = cv.tangent_to_uv(x, y, 383, 517)
    got_u, got_v = cv.tangent_to_uv(mi.Float(x), mi.Float(y), 383, 517)
    assert np.array_equal(np.asarray(got_u).view(np.uint32), want_u.view(np.uint32))
    assert np.array_equal(np.asarray(got_v).view(np.uint32), want_v.view(np.uint32))


def test_srgb_round_trip_and_known_value():
    assert srgb.encode(np.array(0.0031308)) == pytest.approx(0.04045, abs=1e-5)
    x = np.linspace(0, 1, 11)
    assert np.allclose(srgb.decode(srgb.encode(x)), x)


def test_luminance_weights_are_rec709():
    w = srgb.luminance_weights()
    assert w.sum() == pytest.approx(1.0, abs=1e-4)
    assert w == pytest.approx([0.2126, 0.7152, 0.0722], abs=1e-4)


def test_azimuth_of_numpy():
    assert cv.azimuth_of(0.0, 1.0) == pytest.approx(math.pi / 2)
