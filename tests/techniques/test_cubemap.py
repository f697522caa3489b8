"""hzval.techniques.cubemap (issue 31): OpenGL's seamless cube-map filtering in Dr.Jit, against a NumPy
reference built another way (tests/oracles/cube_reference.py)."""

import math

import numpy as np
import pytest

from hzval.bake.maps import CUBE_SIZE, weight_cube
from hzval.core import cube as cube_layout
from tests.oracles.cube_reference import seamless_bilinear

CUBE = weight_cube(CUBE_SIZE).astype(np.float64) / 255.0


def directions() -> np.ndarray:
    """Random directions, every cube edge and corner, and points just either side of them."""
    rng = np.random.default_rng(3)
    d = [rng.normal(size=3) for _ in range(200)]
    for sx in (-1, 1):
        for sy in (-1, 1):
            for sz in (-1, 1):
                d.append(np.array([sx, sy, sz], float))  # corners
                for eps in (0.0, 1e-3, -1e-3, 0.03, -0.03):
                    d += [
                        np.array([sx, sy, sz * (0.3 + eps)]),
                        np.array([sx * (0.6 + eps), sy, sz]),
                        np.array([sx, sy * (1 + eps), sz * (1 - eps)]),
                    ]  # edges and near them
    return np.array(d, np.float32)


def evaluate(d: np.ndarray, seamless: bool = True) -> np.ndarray:
    import drjit as dr
    import mitsuba as mi

    from hzval.techniques import cubemap

    cube = mi.Float(CUBE.astype(np.float32).ravel())
    v = mi.Vector3f(*(mi.Float(np.ascontiguousarray(d[:, i])) for i in range(3)))
    f = cubemap.bilinear(cube, CUBE_SIZE, v, seamless)
    dr.eval(f)
    return np.stack([np.asarray(f[i], np.float64) for i in range(4)], axis=-1)


def test_it_is_the_reference_everywhere_edges_and_corners_included(variant):
    d = directions()
    got = evaluate(d)
    want = np.array([seamless_bilinear(CUBE, x) for x in d])
    assert np.abs(got - want).max() <= 1e-5


def test_the_filter_is_continuous_across_every_seam(variant):
    # directions 1e-4 either side of an edge: a seamless filter gives nearly the same texel
    rng = np.random.default_rng(5)
    worst = 0.0
    for _ in range(50):
        a = rng.uniform(-0.9, 0.9)
        for base in ([1, 1, a], [1, a, 1], [a, 1, 1], [-1, 1, a], [1, -1, a], [a, -1, -1]):
            b = np.array(base, float)
            i = [k for k in range(3) if abs(b[k]) == 1][0]
            lo, hi = b.copy(), b.copy()
            lo[i] *= 1 - 1e-4
            hi[i] *= 1 + 1e-4
            f = evaluate(np.array([lo, hi], np.float32))
            worst = max(worst, np.abs(f[0] - f[1]).max())
    assert worst < 2e-3
    # the clamped (non-seamless) filter jumps there: the test can fail
    d = np.array([[1, 1 - 1e-4, 0.3], [1 - 1e-4, 1, 0.3]], np.float32)
    f = evaluate(d, seamless=False)
    assert np.abs(f[0] - f[1]).max() > 0.015  # 5/255: 0.039 in a factor, 0.3 in F at k = 8


def test_inside_a_face_it_is_plain_bilinear(variant):
    # at a texel centre it returns that texel; midway between two it is their mean
    n = CUBE_SIZE
    d = cube_layout.cube_texel_directions(n)
    got = evaluate(d.reshape(-1, 3).astype(np.float32))
    assert np.abs(got - CUBE.reshape(-1, 4)).max() <= 1e-6
    mid = (d[4, 3, 5] + d[4, 3, 6]) / 2
    assert evaluate(mid[None].astype(np.float32))[0] == pytest.approx(
        (CUBE[4, 3, 5] + CUBE[4, 3, 6]) / 2, abs=1e-6
    )


def test_a_corner_is_the_mean_of_its_three_texels(variant):
    # toward the (+1, +1, +1) corner the four taps are the three corner texels and their mean
    got = evaluate(np.array([[1, 1, 1]], np.float32) / math.sqrt(3))[0]
    want = (CUBE[0, 0, 0] + CUBE[2, -1, -1] + CUBE[4, 0, -1]) / 3
    assert got == pytest.approx(want, abs=1e-6)
