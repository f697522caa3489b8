"""Sizes and formats: 1xN, Nx1, 2x2, prime and non-square maps; 8- and 16-bit PNG, EXR and .npy
inputs of the same data; ``wrap`` against ``open`` at every edge and corner.

Bakes are compared with the float64 reference of :mod:`tests.hard._ref` to within
float32 arithmetic on heights of at most ``hmax`` texels: each ``dh`` is a
float32 difference (exact, heights are float32) times a float32 ``1/r``,
each sine and mean a few roundings, so ``|s - s_ref| <= 2^-21 (hmax + 2)``.
"""

import math

import numpy as np
import pytest
from PIL import Image

import hzval.bake as B
from hzval.cli import main as cli
from hzval.core import conventions as cv
from hzval.io import codecs, heightmap
from hzval.techniques.horizon import Horizon

from ._ref import assert_bake_sane, assert_unit, channel_share, horizon_f64, make_scene, truth, uniform_bake

pytestmark = pytest.mark.hard


def f32_bound(h_tex):
    return 2.0**-21 * (float(np.abs(h_tex).max()) + 2.0)


def check_against_reference(h, params):
    r = B.bake(h, params)
    assert_bake_sane(r)
    h_tex = cv.heights_in_texels(h, params.depth)
    ref, mc, mc2 = horizon_f64(h_tex, params.radius, params.angles, params.boundary)
    bound = f32_bound(h_tex)
    assert np.abs(r.horizon.reshape(-1, 8) - ref).max() <= bound
    assert np.abs(r.mean_cos.ravel() - mc).max() <= bound and np.abs(r.mean_cos2.ravel() - mc2).max() <= bound
    return r


SHAPES = [(1, 16), (16, 1), (1, 2), (2, 1), (2, 2), (3, 3), (13, 13), (17, 31), (31, 7), (5, 97)]


@pytest.mark.parametrize("shape", SHAPES, ids=[f"{r}x{c}" for r, c in SHAPES])
@pytest.mark.parametrize("boundary", ["wrap", "open"])
def test_any_size_bakes_as_the_reference_does(variant, shape, boundary):
    h = np.random.default_rng(sum(shape)).random(shape).astype(np.float32)
    check_against_reference(h, B.BakeParams(depth=3.0 / max(shape[1], 1), boundary=boundary))


@pytest.mark.parametrize("shape", [(1, 16), (1, 23), (16, 1), (13, 13), (17, 31), (2, 2)])
def test_wrap_bake_is_translation_invariant_at_any_size(variant, shape):
    """Rolling a tiling map rolls its bake, exactly: every size tiles, not only powers of two
    (the seed's ``& (width - 1)`` would not)."""
    h = np.random.default_rng(3).random(shape).astype(np.float32)
    p = B.BakeParams(depth=2.0 / shape[1])
    a = B.bake(h, p)
    shift = (shape[0] // 3, shape[1] // 2 + 1)
    b = B.bake(np.roll(h, shift, axis=(0, 1)), p)
    for field in ("horizon", "normal", "mean_cos", "mean_cos2"):
        assert np.array_equal(getattr(b, field), np.roll(getattr(a, field), shift, axis=(0, 1))), field


def test_1xN_and_Nx1_wrap_are_their_rows_and_columns_repeated(variant):
    rng = np.random.default_rng(4)
    row = rng.random((1, 23)).astype(np.float32)
    p = B.BakeParams(depth=0.1)
    one = B.bake(row, p)
    many = B.bake(np.repeat(row, 5, axis=0), p)
    assert np.array_equal(many.horizon, np.repeat(one.horizon, 5, axis=0))
    assert np.array_equal(many.normal, np.repeat(one.normal, 5, axis=0))
    col = rng.random((19, 1)).astype(np.float32)
    p = B.BakeParams(depth=2.0)  # depth is per image width: 1 texel here
    one = B.bake(col, p)
    # the same heights in texels on a 19x4 map need a quarter of the depth
    many = B.bake(np.repeat(col, 4, axis=1), B.BakeParams(depth=0.5))
    assert np.allclose(many.horizon, np.repeat(one.horizon, 4, axis=1), atol=1e-6)


@pytest.mark.parametrize("shape", [(1, 16), (16, 1)])
@pytest.mark.parametrize("boundary", ["wrap", "open"])
def test_truth_and_approximation_take_1xN_and_Nx1(variant, shape, boundary):
    """A wall 2 texels high across a strip: its shadow at 30 degrees is 2 / tan 30 = 3.46 texels
    long, so the three texel centres behind it are dark and the fourth is lit."""
    rows, cols = shape
    h = np.zeros(shape, np.float32)
    h.flat[8] = 1.0
    depth = 2.0 / cols
    along = 0.0 if rows == 1 else 90.0  # the strip's direction; light from its + end
    centres = truth(h, depth, boundary, spp=1, positions=_centres(rows, cols))
    V = centres.render(along).layers["visibility"].ravel()
    # the wall is at index 8; the light from + puts its shadow at smaller x (row: larger index)
    behind = [7, 6, 5, 4] if rows == 1 else [9, 10, 11, 12]
    assert list(V[behind]) == [0.0, 0.0, 0.0, 1.0]
    b = B.bake(h, B.BakeParams(depth=depth, boundary=boundary))
    assert_bake_sane(b)
    a = Horizon(make_scene(shape, depth, boundary), b)
    f = a.render(along)
    assert_unit(f.layers["factor"])
    F = f.layers["factor"].ravel()
    assert F[behind[0]] < 0.5  # right behind the wall: s = sin(atan 2) = 0.89
    assert F[12 if rows == 1 else 4] == 1.0  # on the light's side: nothing toward it


def _centres(rows, cols):
    x, y = cv.texel_centres(rows, cols)
    return np.ascontiguousarray(x, np.float32).ravel(), np.ascontiguousarray(y, np.float32).ravel()


@pytest.mark.parametrize("boundary", ["wrap", "open"])
def test_2x2_map_renders_finite_on_both_sides(variant, boundary):
    h = np.float32([[1.0, 0.0], [0.0, 0.3]])
    b = check_against_reference(h, B.BakeParams(depth=1.0, boundary=boundary))
    t = truth(h, 1.0, boundary, elevation=20.0, spp=16)
    for path in ("exact", "gpu"):
        a = Horizon(make_scene((2, 2), 1.0, boundary, elevation=20.0), b, path=path)
        for az in (0.0, 45.0, 180.0, 300.0):
            assert_unit(a.render(az).layers["factor"])
    for az in (0.0, 45.0, 180.0, 300.0):
        f = t.render(az)
        assert_unit(f.layers["visibility"])
    if boundary == "wrap":
        # a lattice of peaks 2 texels apart, 2 high: the low texel (1, 0) sees the peak at (0, 0)
        # above it (r = 1, +y) and the one across the left edge... every channel is lit by one
        assert (b.horizon[1, 0] > 0).sum() >= 6


# --------------------------------------------------------------------------
# Formats: the same data as 8- and 16-bit PNG, EXR and .npy
# --------------------------------------------------------------------------


@pytest.fixture(scope="module")
def same_data(tmp_path_factory):
    """A 17x29 map whose values v/255 are exact in all four formats (16-bit: v * 257)."""
    d = tmp_path_factory.mktemp("formats")
    v = np.random.default_rng(9).integers(0, 256, (17, 29))
    Image.fromarray(v.astype(np.uint8)).save(d / "h8.png")
    codecs.write_png(d / "h16.png", (v * 257).astype(np.uint16))
    values = (v / 255.0).astype(np.float32)
    codecs.write_exr(d / "h.exr", {"Y": values})
    np.save(d / "h.npy", values)
    return d, values


def test_every_format_of_the_same_data_loads_the_same_heights(same_data):
    d, values = same_data
    for name in ("h8.png", "h16.png", "h.exr", "h.npy"):
        assert np.array_equal(heightmap.load_height(d / name).height, values), name


def test_every_format_of_the_same_data_bakes_the_same(variant, same_data, tmp_path):
    d, _ = same_data
    outs = {}
    for name in ("h8.png", "h16.png", "h.exr", "h.npy"):
        out = tmp_path / name.replace(".", "_")
        assert (
            cli.main(["bake", str(d / name), "--depth", "0.2", "--boundary", "open", "--out", str(out)]) == 0
        )
        outs[name] = {
            f: codecs.read_exr(out / f) for f in ("horizon0.exr", "horizon1.exr", "normal.exr", "ambient.exr")
        }
    first = outs["h8.png"]
    for name, got in outs.items():
        for f, channels in got.items():
            for ch, arr in channels.items():
                assert np.array_equal(arr, first[f][ch]), (name, f, ch)


# --------------------------------------------------------------------------
# wrap against open at every edge and corner
# --------------------------------------------------------------------------

CORNERS = {"top-left": (0, 0), "top-right": (0, -1), "bottom-left": (-1, 0), "bottom-right": (-1, -1)}


@pytest.mark.parametrize("corner", sorted(CORNERS))
def test_bake_sees_across_every_edge_and_corner_with_wrap_only(variant, corner):
    """A spike in one corner of a 20x20 map: with wrap the other three corners see it across an
    edge (r = 1) or across the corner (r = sqrt 2) with its exact sine and bin shares; with open
    they are 19 texels or more away, beyond the radius: no horizon at all."""
    n, height = 20, 3.0
    h = np.zeros((n, n), np.float32)
    sr, sc = (v % n for v in CORNERS[corner])
    h[sr, sc] = 1.0
    wrap = B.bake(h, B.BakeParams(depth=height / n, boundary="wrap"))
    open_ = B.bake(h, B.BakeParams(depth=height / n, boundary="open"))
    for other, (r, c) in CORNERS.items():
        r, c = r % n, c % n
        if (r, c) == (sr, sc):
            continue
        drow = ((sr - r + n // 2) % n) - n // 2  # the spike's nearest copy
        dcol = ((sc - c + n // 2) % n) - n // 2
        i, j = cv.pixel_to_tangent_offset(drow, dcol)
        s = height / math.hypot(height, math.hypot(i, j))
        expect = [channel_share(i, j, ch) * s for ch in range(8)]
        assert wrap.horizon[r, c] == pytest.approx(expect, abs=1e-6), (corner, other)
        assert np.all(open_.horizon[r, c] == 0.0), (corner, other)


@pytest.mark.parametrize("azimuth", [45.0, 135.0, 225.0, 315.0])
def test_truth_shadows_cross_every_edge_and_corner_with_wrap_only(variant, azimuth):
    """A 4x4 block, 3 texels high, in the middle of a 24x24 map casts a shadow 8.2 texels long at
    20 degrees. Rolled so that the block straddles the four corners, the wrap truth is the centred
    one rolled (its shadow crosses an edge pair and a corner, toward each diagonal in turn); the
    open truth of the rolled map loses what crosses: lit where the wrap truth is dark."""
    n, shift = 24, (12, 12)
    h = np.zeros((n, n), np.float32)
    h[10:14, 10:14] = 1.0
    depth = 3.0 / n
    # identical sample offsets in every pixel, so that rolling moves samples onto samples
    fx, fy = np.meshgrid([0.3, 0.8], [0.15, 0.65])  # on no line of mesh edges (x, y, x - y)
    row, col = np.divmod(np.arange(n * n), n)
    xs = (col[:, None] + fx.ravel()[None]).astype(np.float32).ravel()
    ys = ((n - row)[:, None] - fy.ravel()[None]).astype(np.float32).ravel()
    kw = dict(elevation=20.0, spp=4, positions=(xs, ys))
    centred = truth(h, depth, "wrap", **kw).render(azimuth).layers["visibility"]
    rolled = np.roll(h, shift, axis=(0, 1))
    wrap = truth(rolled, depth, "wrap", **kw).render(azimuth).layers["visibility"]
    open_ = truth(rolled, depth, "open", **kw).render(azimuth).layers["visibility"]
    assert truth(h, depth, "open", **kw).render(azimuth).layers["visibility"] == pytest.approx(centred)
    assert np.array_equal(wrap, np.roll(centred, shift, axis=(0, 1)))
    crossed = (wrap < 1.0) & (open_ == 1.0)
    assert crossed.sum() >= 8
    assert np.all(open_ >= wrap)
    # what wraps is the shadow of the block's pieces at the corner away from the light: it leaves
    # the tile there and comes back in at the corner toward the light
    rows, cols = np.nonzero(crossed)
    up, right = math.sin(math.radians(azimuth)) > 0, math.cos(math.radians(azimuth)) > 0
    assert np.all((rows < n // 2) == up) and np.all((cols >= n // 2) == right)


@pytest.mark.parametrize("boundary", ["wrap", "open"])
def test_approximation_filters_across_edges_with_wrap_and_clamps_with_open(variant, boundary):
    """Samples a tenth of a texel inside every edge and corner: bilinear filtering between
    texel centres takes the far edge's texels with wrap, and clamps to the near edge with open."""
    rows, cols = 5, 7
    rng = np.random.default_rng(8)
    hz = rng.uniform(0.0, 0.8, (rows, cols)).astype(np.float32)
    b = uniform_bake(np.zeros(8), rows=rows, cols=cols, boundary=boundary)
    b.horizon[..., 0] = hz  # channel 0: azimuth 0 reads it exactly
    a = Horizon(make_scene((rows, cols), 0.1, boundary), b)
    xs = np.array([0.1, cols / 2, cols - 0.1, 0.1, cols - 0.1, 0.1, cols / 2, cols - 0.1])
    ys = np.array([0.1, 0.1, 0.1, rows / 2, rows / 2, rows - 0.1, rows - 0.1, rows - 0.1])
    s = a.sample(xs, ys, 0.0, 10.0)["horizon_sine"]
    fx, fr = xs - 0.5, rows - ys - 0.5  # column and row coordinates of texel centres
    c0, r0 = np.floor(fx).astype(int), np.floor(fr).astype(int)
    ax, ay = fx - c0, fr - r0

    def at(r, c):
        if boundary == "wrap":
            return hz[r % rows, c % cols].astype(np.float64)
        return hz[np.clip(r, 0, rows - 1), np.clip(c, 0, cols - 1)].astype(np.float64)

    expect = (1 - ay) * ((1 - ax) * at(r0, c0) + ax * at(r0, c0 + 1)) + ay * (
        (1 - ax) * at(r0 + 1, c0) + ax * at(r0 + 1, c0 + 1)
    )
    assert s == pytest.approx(expect, abs=2e-6)
