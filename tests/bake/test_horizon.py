"""The seed bake's two kernel forms (``hzval.bake.horizon.horizon_map(kernel=...)``) and its radius.

The unrolled kernel has one block of code per neighbour offset; the looped
one walks the offset table in a symbolic Dr.Jit loop. Both compute the same
float32 ``(h_n - h_0) * (1/r)`` for every offset and take exact maxima, so
they must agree **bit for bit**, at every radius, on both boundaries; the
seed peer (tests/bake/test_horizon_peer.py) pins the unrolled form. Maps are small;
the unrolled kernel's compile time still grows with the radius (radius 40:
~13 s with an empty kernel cache, so that case is marked slow).
"""

import math

import numpy as np
import pytest

from hzval.bake import horizon as bake_horizon
from hzval.bake import maps as bake
from hzval.core import conventions as cv

ANGLES = 32


def both(h, radius, boundary, **kw):
    unrolled = bake_horizon.horizon_map(h, radius, ANGLES, boundary, kernel="unrolled", **kw)
    loop = bake_horizon.horizon_map(h, radius, ANGLES, boundary, kernel="loop", **kw)
    return unrolled, loop


def assert_identical(a, b):
    """Bit for bit on the LLVM backend; on CUDA within 4 ulp, since its compiler may fuse a multiply
    and an add of the straight-line kernel differently from the loop's (3 ulp seen at radius 2)."""
    from hzval.core import backend

    cuda = backend.variant().startswith("cuda")
    for x, y in zip(a, b):
        assert x.shape == y.shape and x.dtype == y.dtype == np.float32
        if cuda:
            np.testing.assert_array_max_ulp(x, y, maxulp=4)
        else:
            assert x.tobytes() == y.tobytes(), float(np.max(np.abs(x.astype(np.float64) - y)))


# radius 40's unrolled kernel (4,992 offsets) takes ~13 s to compile with an
# empty kernel cache: slow-marked; 25 (1,940 offsets) is above the unroll bound
@pytest.mark.parametrize("radius", [2, 4, 9, 17, 25, pytest.param(40, marks=pytest.mark.slow)])
@pytest.mark.parametrize("boundary", ["wrap", "open"])
def test_loop_and_unrolled_agree_bit_for_bit(variant, radius, boundary):
    rng = np.random.default_rng(radius)
    # odd, non-square, smaller than 2 radius from r = 17: wrapped neighbours repeat
    h = cv.heights_in_texels(rng.random((13, 21)).astype(np.float32), 0.2)
    unrolled, loop = both(h, radius, boundary)
    assert_identical(unrolled, loop)
    assert np.any(unrolled[0] > 0)


def test_loop_agrees_with_16_directions_and_64_bins(variant):
    rng = np.random.default_rng(7)
    h = cv.heights_in_texels(rng.random((11, 10)).astype(np.float32), 0.3)
    a = bake_horizon.horizon_map(h, 6, 64, "wrap", kernel="unrolled", directions=16)
    b = bake_horizon.horizon_map(h, 6, 64, "wrap", kernel="loop", directions=16)
    assert a[0].shape == (11, 10, 16)
    assert_identical(a, b)


def occluder_map(radius, i, j, height=5.0):
    """A flat map (texel units) with one texel ``height`` high at tangent offset ``(i, j)`` from
    the centre texel ``(row, col)``; large enough that nothing wraps into the radius."""
    n = 2 * radius + 7
    h = np.zeros((n, n), np.float32)
    row, col = n // 2, n // 2
    drow, dcol = cv.tangent_to_pixel_offset(i, j)
    h[row + drow, col + dcol] = height
    return h, (row, col)


@pytest.mark.parametrize("kernel", ["unrolled", "loop"])
@pytest.mark.parametrize("boundary", ["wrap", "open"])
@pytest.mark.parametrize("radius", [10, 24])
def test_an_occluder_counts_just_inside_the_radius_and_not_at_it(variant, kernel, boundary, radius):
    """Neighbours count iff ``i^2 + j^2 < R^2``: at distance R - 1 along +x (channel 0) and at a
    diagonal offset just inside, the occluder's sine fills its bins; at exactly R (along +x, and
    (6, 8) for R = 10 or (0, 24) for R = 24 along +y, r^2 = R^2) it is not seen."""
    height = 5.0
    inside = [(radius - 1, 0), (7, 7) if radius == 10 else (16, 17)]
    outside = [(radius, 0), (6, 8) if radius == 10 else (0, 24)]
    for i, j in inside:
        assert i * i + j * j < radius * radius
        h, (row, col) = occluder_map(radius, i, j, height)
        hz = bake_horizon.horizon_map(h, radius, ANGLES, boundary, kernel=kernel)[0][row, col]
        sine = height / math.hypot(height, math.hypot(i, j))
        covered = next(g.bins for g in bake_horizon.horizon_table(radius, ANGLES) if (i, j) in g.offsets)
        for c in range(cv.CHANNEL_COUNT):
            centre = c * ANGLES // cv.CHANNEL_COUNT
            mine = {(centre + d) % ANGLES for d in range(-2, 3)}
            expect = sine * len(mine & set(covered)) / len(mine)
            assert hz[c] == pytest.approx(expect, rel=1e-5, abs=1e-7), (i, j, c)
        assert hz.max() > 0
    for i, j in outside:
        assert i * i + j * j >= radius * radius
        h, (row, col) = occluder_map(radius, i, j, height)
        hz = bake_horizon.horizon_map(h, radius, ANGLES, boundary, kernel=kernel)[0][row, col]
        assert np.all(hz == 0.0), (i, j)


def test_auto_unrolls_the_default_radius_and_loops_large_radii_on_small_maps():
    assert bake_horizon.choose_kernel(792, 1) == "unrolled"  # radius 16
    assert bake_horizon.choose_kernel(792, 4096 * 4126) == "unrolled"  # ... at every size
    assert bake_horizon.choose_kernel(bake_horizon.UNROLL_MAX_OFFSETS, 1) == "unrolled"
    r32, r64 = 3204, 12848
    assert bake_horizon.choose_kernel(r32, 512 * 574) == "loop"
    assert bake_horizon.choose_kernel(r64, 512 * 638) == "loop"
    # large maps: the loop's slower run outweighs the unrolled kernel's compile
    assert bake_horizon.choose_kernel(r32, 4096 * 4158) == "unrolled"


def test_the_default_bake_takes_the_unrolled_kernel(variant, monkeypatch):
    def fail(*args, **kwargs):
        raise AssertionError("the default radius must not take the loop")

    monkeypatch.setattr(bake_horizon, "_max_tan_loop", fail)
    bake.bake(np.zeros((8, 8), np.float32), bake.BakeParams())


def test_auto_takes_the_loop_for_a_large_radius_on_a_small_map(variant, monkeypatch):
    calls = []
    original = bake_horizon._max_tan_loop
    monkeypatch.setattr(bake_horizon, "_max_tan_loop", lambda *a, **k: calls.append(1) or original(*a, **k))
    rng = np.random.default_rng(3)
    h = cv.heights_in_texels(rng.random((12, 12)).astype(np.float32), 0.1)
    auto = bake_horizon.horizon_map(h, 40, ANGLES, "wrap")
    assert calls == [1]
    assert_identical(auto, bake_horizon.horizon_map(h, 40, ANGLES, "wrap", kernel="loop"))


def test_unknown_kernel_form_is_rejected():
    with pytest.raises(ValueError, match="kernel form"):
        bake_horizon.horizon_map(np.zeros((4, 4), np.float32), 4, ANGLES, "wrap", kernel="fast")
