"""The approximation (hzval.techniques.horizon, issue 4) against answers known in advance.

Every expected value here is computed independently of the kernels: with
NumPy from the conventions (bilinear filtering between texel centres, the
weight cube map through hzval.core.cube.cube_lookup) or from geometry whose
horizon is known in closed form.
"""

import math

import drjit as dr
import numpy as np
import pytest

import hzval.bake as B
from hzval.core import conventions as cv
from hzval.core import cube as cube_layout
from hzval.core.errors import InputError
from hzval.materials import bricks as brick_wall
from hzval.scene import camera as hz_camera
from hzval.scene import spec as sc
from hzval.techniques.horizon import CUBE_SIZE, DEFAULT_FADE, Horizon
from tests.oracles.cube_reference import seamless_bilinear

K = 8.0
#: Every azimuth the issue names, the channel directions exactly, both ways
#: round, plus a few between channels (degrees).
AZIMUTHS = (0.0, 45.0, 90.0, 135.0, 180.0, 225.0, 270.0, 315.0, 360.0, -0.0, 7.5, -60.0, 100.0)
#: The issue's elevations, below the horizon first (sorted: monotonicity).
ELEVATIONS = (-30.0, -1.0, 0.0, 0.5, 1.0, 2.0, 45.0, 89.9, 90.0)
#: Float32 slack for comparing the two paths: each computes
#: s = sum of 8 products of numbers <= 1 and k (Lz - s) + 1, so each F
#: carries at most ~16 ulp(1) of rounding, times k, on either side.
F32_SLACK = 2 * K * 16 * 2.0**-23


# --------------------------------------------------------------------------
# NumPy references
# --------------------------------------------------------------------------


def light32(azimuth, elevation):
    """The light direction as the kernels get it (float32)."""
    return cv.light_direction(azimuth, elevation).astype(np.float32)


_CUBE = B.weight_cube(CUBE_SIZE).astype(np.float64) / 255.0


def gpu_weights(d):
    """The 8 channel weights that Listing 5.1 gets from the 8-bit cube map at ``d``.

    Bilinear and seamless across the faces, as OpenGL filters a cube map with
    GL_TEXTURE_CUBE_MAP_SEAMLESS (tests/oracles/cube_reference.py, built independently
    of hzval.techniques.cubemap), then f0 = clamp(2f - 1), f1 = clamp(1 - 2f).
    """
    d = np.asarray(d, np.float32).astype(np.float64)
    f = seamless_bilinear(_CUBE, d)
    return np.concatenate([np.clip(2 * f - 1, 0, 1), np.clip(1 - 2 * f, 0, 1)])


def exact_weights(d):
    d = np.asarray(d, np.float32).astype(np.float64)
    return cv.channel_weights(d[0], d[1])


def bilerp(tex, x, y, boundary):
    """Bilinear filtering between texel centres at tangent-space (x, y) (docs/ARCHITECTURE.md)."""
    rows, cols = tex.shape[:2]
    fx, fy = x.astype(np.float64) - 0.5, rows - y.astype(np.float64) - 0.5  # fy: row coordinate
    c0, r0 = np.floor(fx).astype(int), np.floor(fy).astype(int)
    ax, ay = fx - c0, fy - r0
    if tex.ndim == 3:
        ax, ay = ax[:, None], ay[:, None]

    def at(r, c):
        if boundary == "wrap":
            return tex[r % rows, c % cols]
        return tex[np.clip(r, 0, rows - 1), np.clip(c, 0, cols - 1)]

    return (1 - ay) * ((1 - ax) * at(r0, c0) + ax * at(r0, c0 + 1)) + ay * (
        (1 - ax) * at(r0 + 1, c0) + ax * at(r0 + 1, c0 + 1)
    )


def pixel_mean(values, scene, rows, cols):
    h, w = sc.image_shape(rows, cols, scene.camera)
    return values.reshape(h * w, scene.spp, *values.shape[1:]).mean(axis=1).reshape(h, w, *values.shape[1:])


def uniform_bake(horizon, normal=(0.0, 0.0, 1.0), rows=8, cols=8, boundary="wrap"):
    """A synthetic bake with the same horizon and normal in every texel."""
    n = np.asarray(normal, np.float64)
    n = n / np.linalg.norm(n)
    return B.Bake(
        B.BakeParams(boundary=boundary),
        np.broadcast_to(np.asarray(horizon, np.float32), (rows, cols, 8)).copy(),
        np.broadcast_to(n.astype(np.float32), (rows, cols, 3)).copy(),
        np.ones((rows, cols), np.float32),
        np.ones((rows, cols), np.float32),
    )


def scene(size=32, effects=("shadow",), spp=4, elevation=30.0, **kw):
    mat = sc.MaterialSpec(
        size=size,
        depth=kw.pop("depth", 0.1),
        boundary=kw.pop("boundary", "wrap"),
        albedo=kw.pop("albedo", 0.8),
    )
    light = sc.Light(elevation_deg=elevation, irradiance=kw.pop("irradiance", 1.0))
    return sc.Scene(material=mat, light=light, effects=tuple(effects), spp=spp, **kw).validate()


# --------------------------------------------------------------------------
# Fixtures: one bake, one object per path, every light of the grid rendered once
# --------------------------------------------------------------------------


@pytest.fixture(scope="module")
def bricks(variant):
    return B.bake(brick_wall.bricks(32), B.BakeParams(depth=0.1))


@pytest.fixture(scope="module")
def grid(bricks):
    """Frames of both paths for every (azimuth, elevation) of the grid."""
    scn = scene(effects=("shadow", "diffuse", "specular"))
    apps = {p: Horizon(scn, bricks, path=p) for p in ("exact", "gpu")}
    frames = {
        (p, az, el): a.render(az, elevation_deg=el)
        for p, a in apps.items()
        for az in AZIMUTHS
        for el in ELEVATIONS
    }
    return apps, frames


# --------------------------------------------------------------------------
# Effects and interface
# --------------------------------------------------------------------------


def test_simulated_lists_exactly_the_declared_effects(bricks):
    every = sc.EFFECTS
    a = Horizon(scene(effects=every), bricks)
    assert a.simulated == tuple(e for e in every if e != "interreflection")
    b = Horizon(scene(effects=("specular", "shadow")), bricks)
    assert b.simulated == ("shadow", "specular")
    assert set(b.render(10.0).layers) == {"factor"}
    c = Horizon(scene(effects=("ambient", "reflection_occlusion")), bricks)
    assert set(c.render(10.0).layers) == {"ambient", "reflection_occlusion"}


def test_bad_parameters_are_refused(bricks):
    scn = scene()
    for kw in ({"path": "cuda"}, {"ambient": "mean"}, {"k": 0.0}, {"k": float("nan")}, {"fade": -1.0}):
        with pytest.raises(InputError):
            Horizon(scn, bricks, **kw)


def test_frames_have_the_scene_shape(bricks):
    scn = scene(effects=("shadow", "diffuse"), camera=sc.Camera(supersampling=2), spp=1)
    f = Horizon(scn, bricks).render(15.0)
    assert f.image.shape == (64, 64, 3) and f.layers["factor"].shape == (64, 64)
    assert f.image.dtype == np.float32 and f.seconds > 0


# --------------------------------------------------------------------------
# Numerical stability over the light grid
# --------------------------------------------------------------------------


@pytest.mark.parametrize("path", ["exact", "gpu"])
def test_factor_is_finite_and_in_unit_range_everywhere(grid, path):
    _, frames = grid
    for az in AZIMUTHS:
        for el in ELEVATIONS:
            f = frames[path, az, el]
            F = f.layers["factor"]
            assert np.all(np.isfinite(F)) and np.all((F >= 0) & (F <= 1)), (az, el)
            assert np.all(np.isfinite(f.image)) and np.all(f.image >= 0), (az, el)


@pytest.mark.parametrize("path", ["exact", "gpu"])
def test_zenith_light_is_unshadowed(grid, bricks, path):
    assert bricks.horizon.max() < 0.9  # s <= max h < 1 = Lz: eq. 5.4 gives F >= 1
    for az in AZIMUTHS:
        assert np.all(grid[1][path, az, 90.0].layers["factor"] == 1.0), az


@pytest.mark.parametrize("path", ["exact", "gpu"])
def test_light_below_or_on_the_horizon_gives_no_light(grid, path):
    for az in AZIMUTHS:
        for el in (-30.0, -1.0, 0.0):
            assert np.all(grid[1][path, az, el].image == 0.0), (az, el)
        # Lz = -0.5 <= s - 1/k for every s >= 0: eq. 5.4 clamps to 0
        assert np.all(grid[1][path, az, -30.0].layers["factor"] == 0.0), az


@pytest.mark.parametrize("path", ["exact", "gpu"])
def test_factor_never_decreases_with_elevation(grid, path):
    # exact: s does not depend on the elevation, so F rises with Lz = sin e.
    # gpu: on the cube's side faces the weights depend on the azimuth only;
    # between the listed elevations Lz rises by more than the +z face changes
    # them. (Densely sampled, F_gpu does drop where L crosses onto the +z
    # face, at 35-45 degrees: see hzval.techniques.horizon.)
    for az in AZIMUTHS:
        F = np.stack([grid[1][path, az, el].layers["factor"] for el in ELEVATIONS])
        assert np.all(np.diff(F, axis=0) >= 0), az


def test_factor_never_decreases_with_elevation_densely_on_the_exact_path(bricks):
    a = Horizon(scene(spp=1), bricks)
    for az in (0.0, 22.5, 45.0, 200.0, 360.0, -0.0):
        F = np.stack([a.render(az, elevation_deg=e).layers["factor"] for e in np.arange(-10.0, 90.01, 1.25)])
        assert np.all(np.diff(F, axis=0) >= 0), az


def test_exact_and_gpu_paths_agree_within_the_8_bit_bound(grid, bricks):
    """|F_exact - F_gpu| <= k (|ds_quant| + |ds_weights|), derived per light.

    s_gpu - s_exact = sum_c w^_c (h^_c - h_c) + sum_c (w^_c - w_c) h_c, with
    h^ the 8-bit horizon (|h^ - h| <= 0.5/255 per texel, and so for their
    bilinear interpolants) and w^ the weights the 8-bit cube map gives after
    bilinear filtering (taken from the cube itself, gpu_weights). Hence
    |ds| <= 0.5/255 * sum(w^) + sum_c |w^_c - w_c| max(h_c), and clamping F
    only shrinks differences. Averaging over a pixel's samples keeps it.
    """
    _, frames = grid
    hmax = bricks.horizon.reshape(-1, 8).max(axis=0).astype(np.float64)
    worst = 0.0
    for az in AZIMUTHS:
        for el in ELEVATIONS:
            L = light32(az, el)
            w, wg = exact_weights(L), gpu_weights(L)
            bound = K * (0.5 / 255 * wg.sum() + np.abs(wg - w) @ hmax) + F32_SLACK
            diff = np.abs(
                frames["exact", az, el].layers["factor"].astype(np.float64)
                - frames["gpu", az, el].layers["factor"]
            )
            assert diff.max() <= bound, (az, el, diff.max(), bound)
            worst = max(worst, diff.max())
    print(f"largest |F_exact - F_gpu| over the grid: {worst:.5f}")


# --------------------------------------------------------------------------
# Channel weights, and the cube map's zero-weight leak, measured
# --------------------------------------------------------------------------


@pytest.fixture(scope="module")
def channel_blocks(variant):
    """4 x 32 map in 8 blocks of 4 columns; block c has h_c = 1, all else 0.

    At a texel centre of block c the horizon sine s equals the weight of
    channel c, so one probe reads the whole weight vector.
    """
    h = np.zeros((4, 32, 8), np.float32)
    for c in range(8):
        h[:, 4 * c : 4 * c + 4, c] = 1.0
    bake = B.Bake(
        B.BakeParams(),
        h,
        np.broadcast_to(np.float32([0, 0, 1]), (4, 32, 3)).copy(),
        np.ones((4, 32), np.float32),
        np.ones((4, 32), np.float32),
    )
    scn = scene(size=32)
    x = np.array([4 * c + 1.5 for c in range(8)])  # column 4c + 1, texel centre
    y = np.full(8, 4 - 1 - 0.5)  # row 1
    return {p: Horizon(scn, bake, path=p) for p in ("exact", "gpu")}, x, y


LIGHTS = [
    (az, el)
    for az in (*AZIMUTHS, 22.5, 67.4, 191.0, 300.0, -135.0)
    for el in (0.0, 10.0, 33.0, 50.0, 70.0, 89.9)
]


@pytest.mark.parametrize("path,reference", [("exact", exact_weights), ("gpu", gpu_weights)])
def test_horizon_sine_uses_the_paths_weights(channel_blocks, path, reference):
    apps, x, y = channel_blocks
    for az, el in LIGHTS:
        s = apps[path].sample(x, y, az, el)["horizon_sine"]
        assert s == pytest.approx(reference(light32(az, el)), abs=2e-6), (az, el)


def test_cube_weight_error_is_what_hzval_approx_documents():
    # The numbers quoted in hzval.techniques.horizon: over all directions the decoded
    # weights sum to at most 1 + 3/255 (three zero-weight leaks on layer 0);
    # on the side faces (elevation <= 45 deg) sum |w^ - w| <= 0.173, largest
    # at the channel azimuths, whose tent peak falls between cube texels.
    worst_sum, worst_err = 0.0, 0.0
    for az in np.arange(0.0, 360.0, 1.0):
        for el in (0.0, 15.0, 30.0, 45.0):
            L = light32(az, el)
            wg = gpu_weights(L)
            worst_sum = max(worst_sum, wg.sum())
            worst_err = max(worst_err, np.abs(wg - exact_weights(L)).sum())
    assert worst_sum == pytest.approx(1 + 3 / 255, abs=1e-9)
    # 0.169 below 45 degrees; at 45 the seamless filter blends in the +z face's texels: 0.173
    assert 0.16 < worst_err <= 0.173
    L = light32(0.0, 30.0)  # channel 0: 0.92 = 235/255 instead of 1
    assert gpu_weights(L)[0] == pytest.approx(235 / 255, abs=1e-9)


def test_zero_weight_leaks_one_255th_on_layer_0_only(channel_blocks):
    # Lengyel stores a weight w as round((w + 1) * 127.5): w = 0 is 127.5, not
    # storable; it rounds to 128 = 0x80, which Listing 5.1 decodes as
    # clamp(2 * 128/255 - 1) = 1/255 on layer 0 and clamp(1 - 2 * 128/255) = 0
    # on layer 1.
    assert int(cube_layout.encode_signed_weight(np.array(0.0))) == 128
    leak0, leak1 = max(2 * 128 / 255 - 1, 0), max(1 - 2 * 128 / 255, 0)
    assert (leak0, leak1) == (pytest.approx(1 / 255, abs=1e-15), 0)
    apps, x, y = channel_blocks
    for c in range(8):
        # perpendicular to channel c: its weight and its opposite's are 0
        az = 45.0 * (c + 2)
        for el in (0.0, 20.0):
            s_gpu = apps["gpu"].sample(x, y, az, el)["horizon_sine"]
            s_exact = apps["exact"].sample(x, y, az, el)["horizon_sine"]
            assert s_exact[c] == pytest.approx(0.0, abs=1e-6)
            expect = leak0 if c < 4 else leak1
            assert s_gpu[c] == pytest.approx(expect, abs=1e-7), (c, az, el)


# --------------------------------------------------------------------------
# Known geometry
# --------------------------------------------------------------------------


@pytest.mark.parametrize("path", ["exact", "gpu"])
def test_flat_plane_is_lambert_and_unshadowed(variant, path):
    flat = B.bake(np.full((16, 16), 0.3, np.float32), B.BakeParams(depth=0.1))
    scn = scene(size=16, effects=("shadow", "diffuse"), albedo=0.5, irradiance=2.0)
    a = Horizon(scn, flat, path=path)
    for az in (0.0, 45.0, 123.0, 360.0, -0.0):
        for el in ELEVATIONS:
            f = a.render(az, elevation_deg=el)
            lz = float(light32(az, el)[2])
            if lz >= 0:
                assert np.all(f.layers["factor"] == 1.0), (az, el)
            expect = 0.5 / math.pi * 2.0 * max(lz, 0.0) if lz > 0 else 0.0
            assert f.image == pytest.approx(np.full_like(f.image, expect), rel=1e-6, abs=1e-7), (az, el)


def test_shadow_only_scene_shades_grey_irradiance_times_factor(bricks):
    scn = scene(effects=("shadow",), irradiance=3.0, spp=1)
    f = Horizon(scn, bricks).render(30.0)
    assert np.array_equal(f.image[..., 0], f.image[..., 2])
    assert f.image[..., 1] == pytest.approx(3.0 * f.layers["factor"], rel=1e-6)


WALL_H, WALL_COL = 4.0, 20  # a wall 4 texels high (as in test_bake)


@pytest.fixture(scope="module")
def wall(variant):
    h = np.zeros((8, 32), np.float32)
    h[:, WALL_COL] = 1.0
    return B.bake(h, B.BakeParams(depth=WALL_H / 32, boundary="open"))


def wall_sine(d):
    return WALL_H / math.hypot(WALL_H, d)


@pytest.mark.parametrize("path", ["exact", "gpu"])
def test_wall_casts_the_shadow_of_its_baked_sine(wall, path):
    # d = 1..3 texels left of the wall, the light at azimuth 0 (channel 0)
    # facing it: s is exactly sin(atan(h/d)) (test_bake), and F follows eq. 5.4.
    a = Horizon(scene(effects=("shadow",), boundary="open"), wall, path=path)
    for d in (1, 2, 3):
        s = wall_sine(d)
        assert wall.horizon[4, WALL_COL - d, 0] == pytest.approx(s, abs=1e-6)
        x, y = np.array([WALL_COL - d + 0.5]), np.array([8 - 4 - 0.5])
        for lz in (s - 0.3, s - 0.1, s - 0.05, s - 0.01, s, s + 0.05):
            el = math.degrees(math.asin(min(lz, 1.0)))
            L = light32(0.0, el)
            if path == "exact":
                s_path = s
            else:  # 8-bit horizon and the cube's weights at L
                s_path = float(gpu_weights(L) @ (np.rint(wall.horizon[4, WALL_COL - d] * 255) / 255))
            F = a.sample(x, y, 0.0, el)["factor"][0]
            assert F == pytest.approx(np.clip(K * (L[2] - s_path) + 1, 0, 1), abs=1e-5), (d, lz)


def test_wall_pixel_averages_its_samples(wall):
    # Pixel (4, 18) is d = 2 from the wall; its samples interpolate between
    # d = 3, 2, 1, whose sines are all known: the pixel is the mean of eq. 5.4
    # over its samples.
    scn = scene(effects=("shadow",), boundary="open", spp=16)
    a = Horizon(scn, wall)
    s_col = np.zeros(32)
    for d in (1, 2, 3):
        s_col[WALL_COL - d] = wall_sine(d)
    x, y = hz_camera.sample_positions(8, 32, scn.camera, scn.spp, scn.seed)
    p = 4 * 32 + 18
    xs = x[p * scn.spp : (p + 1) * scn.spp].astype(np.float64) - 0.5
    c0 = np.floor(xs).astype(int)
    s = (1 - (xs - c0)) * s_col[c0] + (xs - c0) * s_col[c0 + 1]
    for el in (40.0, 45.0, 50.0, 60.0):
        lz = float(light32(0.0, el)[2])
        expect = np.clip(K * (lz - s) + 1, 0, 1).mean()
        assert a.render(0.0, elevation_deg=el).layers["factor"][4, 18] == pytest.approx(expect, abs=1e-5)


def test_k_per_frame_is_eq_5_4s_k(wall):
    a = Horizon(scene(effects=("shadow",), boundary="open"), wall, k=8.0)
    x, y = np.array([WALL_COL - 2 + 0.5]), np.array([3.5])
    el = math.degrees(math.asin(wall_sine(2) - 0.05))
    for k in (2.0, 8.0, 30.0):
        F = a.sample(x, y, 0.0, el, k=k)["factor"][0]
        assert F == pytest.approx(np.clip(k * (light32(0.0, el)[2] - wall_sine(2)) + 1, 0, 1), abs=1e-5)
    with pytest.raises(InputError):
        a.render(0.0, k=-1.0)


# --------------------------------------------------------------------------
# Shading terms against NumPy
# --------------------------------------------------------------------------


@pytest.mark.parametrize("boundary", ["wrap", "open"])
def test_without_shadows_the_image_is_plain_lambert(variant, boundary):
    bake = B.bake(brick_wall.bricks(24), B.BakeParams(depth=0.1, boundary=boundary))
    scn = scene(size=24, effects=("shadow", "diffuse"), irradiance=1.5, boundary=boundary, spp=4)
    rng = np.random.default_rng(3)
    albedo = rng.uniform(0.1, 0.9, (24, 24, 3)).astype(np.float32)
    a = Horizon(scn, bake, albedo)
    x, y = hz_camera.sample_positions(24, 24, scn.camera, scn.spp, scn.seed)
    n = bilerp(bake.normal, x, y, boundary)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    alb = bilerp(albedo, x, y, boundary)
    for az, el in ((0.0, 30.0), (110.0, 12.0), (250.0, 60.0)):
        L = light32(az, el).astype(np.float64)
        expect = pixel_mean(alb / math.pi * 1.5 * np.maximum(n @ L, 0)[:, None], scn, 24, 24)
        f = a.render(az, shadows=False, elevation_deg=el)
        assert "factor" not in f.layers
        assert f.image == pytest.approx(expect, rel=1e-5, abs=1e-7)
        assert np.all(a.render(az, elevation_deg=el).image <= f.image + 1e-7)  # F <= 1


def test_with_one_sample_the_image_is_direct_light_times_factor(bricks):
    a = Horizon(scene(effects=("shadow", "diffuse", "specular"), spp=1), bricks)
    on, off = a.render(70.0), a.render(70.0, shadows=False)
    assert on.image == pytest.approx(off.image * on.layers["factor"][..., None], rel=1e-6, abs=1e-8)


def test_specular_is_blinn_phong(variant):
    from hzval.core.shading import SPECULAR_EXPONENT, SPECULAR_KS

    n = np.array([0.2, -0.1, 1.0])
    bake = uniform_bake(np.zeros(8), n)
    a = Horizon(scene(size=8, effects=("specular",), irradiance=2.0), bake)
    n = n / np.linalg.norm(n)
    for az, el in ((300.0, 70.0), (10.0, 80.0), (180.0, 5.0)):
        L = light32(az, el).astype(np.float64)
        h = (L + [0, 0, 1]) / np.linalg.norm(L + [0, 0, 1])
        expect = SPECULAR_KS * 2.0 * max(n @ h, 0) ** SPECULAR_EXPONENT * (n @ L > 0)
        assert a.render(az, elevation_deg=el).image == pytest.approx(
            np.full((8, 8, 3), expect), rel=1e-4, abs=1e-9
        )


@pytest.mark.parametrize("term", ["mean_cos2", "mean_cos"])
def test_ambient_map_is_sampled_and_added(bricks, term):
    scn = scene(effects=("ambient",), irradiance=2.0, albedo=0.6)
    f = Horizon(scn, bricks, ambient=term).render(0.0, elevation_deg=-5.0)  # no direct light
    x, y = hz_camera.sample_positions(32, 32, scn.camera, scn.spp, scn.seed)
    A = pixel_mean(bilerp(getattr(bricks, term), x, y, "wrap"), scn, 32, 32)
    assert f.layers["ambient"] == pytest.approx(A, rel=1e-5)
    assert f.image == pytest.approx(np.repeat(0.6 * A[..., None] * 2.0 / math.pi, 3, -1), rel=1e-5)


@pytest.mark.parametrize("path", ["exact", "gpu"])
@pytest.mark.parametrize("normal", [(0, 0, 1), (0.4, 0, 1), (1, 0, 1.2), (1, 0, 0.5), (-0.3, 0.8, 1)])
def test_reflection_occlusion_is_toolbags_fade_against_the_horizon(variant, path, normal):
    horizon = np.float32([0.3, 0.1, 0.1, 0.1, 0.2, 0.1, 0.1, 0.1])
    bake = uniform_bake(horizon, normal)
    a = Horizon(scene(size=8, effects=("reflection_occlusion",)), bake, path=path)
    n = np.asarray(normal, np.float64) / np.linalg.norm(normal)
    r = 2 * n[2] * n - [0, 0, 1]
    if path == "exact":
        s = exact_weights(r) @ horizon
    else:
        s = gpu_weights(r) @ (np.rint(horizon * 255) / 255)
    expect = np.clip(1 + DEFAULT_FADE * (r[2] - s), 0, 1) ** 2
    o = a.render(0.0).layers["reflection_occlusion"]
    assert o == pytest.approx(np.full((8, 8), expect), abs=2e-6)


# --------------------------------------------------------------------------
# Speed: no recompilation per light
# --------------------------------------------------------------------------


@pytest.mark.parametrize("path", ["exact", "gpu"])
@pytest.mark.parametrize("spp", [1, 4])
def test_a_new_light_compiles_no_kernel(bricks, path, spp):
    """Once a horizon map has rendered, a light at another azimuth, elevation or ``k`` reuses its
    kernels. Two frames warm them: on CUDA an object's first frame traces its uniforms kernel with
    one dead literal fewer than its later frames (PTX keeps a literal as an instruction, LLVM IR
    inlines it), so a second kernel is compiled once, at its second frame (seen on an H200)."""
    a = Horizon(scene(effects=sc.EFFECTS, spp=spp), bricks, path=path, k=5.0)
    a.render(10.0)
    a.render(20.0)
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
        dr.kernel_history()
        a.render(77.3, elevation_deg=12.5)
        a.render(-140.0, k=3.5)
        hist = [h for h in dr.kernel_history() if h["type"] == dr.KernelType.JIT]
    assert hist and all(h["cache_hit"] for h in hist)
