"""The ground truth against answers known in advance (docs/ARCHITECTURE.md "Effects", issue 3).

Every number hzval reports is measured against :mod:`hzval.truth.plane`, so these
tests pin it to geometry and radiometry that can be worked out by hand:
flat ground, straight walls (whose shadow along the light's azimuth is
``h / tan(e)`` long, which pins the handedness of the whole pipeline),
disk-light penumbrae, Lambert and Blinn-Phong on planes, the cosine-weighted
sky of a periodic grating, and a white furnace. Maps are tiny; ``Truth``
objects that several tests share are module fixtures, and kernels compile
once (light directions are opaque).
"""

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from hzval.core.errors import InputError
from hzval.scene import camera as hz_camera
from hzval.scene import files as scene_files
from hzval.scene import spec as sc
from tests.helpers import WALL_AT, WALL_H, column_wall, make_scene, row_wall, wall_shadow_extents

SCENES = Path(__file__).resolve().parents[2] / "scenes"


def truth(h, depth, boundary="open", **kw):
    from hzval.truth.plane import Truth

    positions = kw.pop("positions", None)
    albedo = kw.pop("albedo_map", None)
    return Truth(
        make_scene(np.shape(h), depth, boundary, **kw),
        np.asarray(h, np.float32),
        positions=positions,
        albedo=albedo,
    )


def on_mesh_edges(rows, cols):
    """Four samples per pixel, every one on a mesh vertex or edge (spp = 4).

    The texel centre (a vertex), the pixel's top-right corner (the middle of
    a quad's diagonal edge), the middle of its right side (a horizontal
    edge) and of its top side (a vertical edge).
    """
    row, col = np.divmod(np.arange(rows * cols), cols)
    top = (rows - row).astype(np.float64)
    xs = np.stack([col + 0.5, col + 1.0, col + 1.0, col + 0.5], axis=1)
    ys = np.stack([top - 0.5, top, top - 0.5, top], axis=1)
    return xs.astype(np.float32).ravel(), ys.astype(np.float32).ravel()


# --------------------------------------------------------------------------
# Declared effects
# --------------------------------------------------------------------------


@pytest.mark.parametrize(
    "effects",
    [
        ("shadow",),
        ("diffuse",),
        ("shadow", "diffuse"),
        ("shadow", "specular", "ambient"),
        ("shadow", "diffuse", "specular", "ambient", "reflection_occlusion"),
        ("shadow", "diffuse", "interreflection"),
    ],
)
def test_simulated_lists_exactly_the_declared_effects(variant, effects):
    t = truth(np.zeros((4, 5)), 0.1, effects=effects, spp=1)
    assert t.simulated == tuple(e for e in sc.EFFECTS if e in effects)
    f = t.render(0.0)
    assert set(f.layers) == ({"visibility"} if "shadow" in effects else set()) | (
        {"ambient"} if "ambient" in effects else set()
    ) | ({"reflection_occlusion"} if "reflection_occlusion" in effects else set())
    assert set(f.variance) == set(f.layers) | {"image"}
    assert f.image.shape == (4, 5, 3) and f.image.dtype == np.float32
    assert "ambient_s" in t.timings if "ambient" in effects else "ambient_s" not in t.timings


def test_interreflection_without_a_reflecting_surface_is_refused(variant):
    with pytest.raises(InputError, match="interreflection needs"):
        truth(np.zeros((4, 4)), 0.1, effects=("shadow", "interreflection"), spp=1)


# --------------------------------------------------------------------------
# Flat ground, walls: the geometry of shadows
# --------------------------------------------------------------------------


@pytest.mark.parametrize("boundary", ["wrap", "open"])
@pytest.mark.parametrize("elevation", [0.5, 10.0, 45.0, 89.9, 90.0])
def test_flat_map_is_fully_lit_by_any_light_above_the_horizon(variant, boundary, elevation):
    t = truth(np.full((12, 16), 0.3), 0.1, boundary, elevation=elevation, irradiance=2.0, spp=4)
    for azimuth in (0.0, 77.0, 200.0, -45.0):
        f = t.render(azimuth)
        assert np.all(f.layers["visibility"] == 1.0)
        assert np.all(f.variance["visibility"] == 0.0)
        assert np.all(f.image == 2.0)


@pytest.mark.parametrize("elevation", [-5.0, 0.0])
def test_light_below_the_horizon_lights_nothing(variant, elevation):
    for boundary in ("wrap", "open"):
        t = truth(np.full((8, 8), 0.3), 0.1, boundary, elevation=elevation, spp=4)
        assert np.all(t.render(30.0).layers["visibility"] == 0.0)


@pytest.fixture(scope="module")
def walls(variant):
    """Truths of a column wall and a row wall (40x40, open), per elevation."""
    out = {}
    for e in (30.0, 50.0):
        out["col", e] = truth(column_wall(40, 40, WALL_AT), WALL_H / 40, elevation=e)
        out["row", e] = truth(row_wall(40, 40, WALL_AT), WALL_H / 40, elevation=e)
    return out


@pytest.mark.parametrize("elevation", [30.0, 50.0])
@pytest.mark.parametrize("azimuth", [0.0, 45.0, 90.0, 180.0])
def test_wall_casts_a_shadow_h_over_tan_e_long_away_from_the_light(walls, azimuth, elevation):
    """Measured along the light's azimuth, the shadow is h / tan(e) long.

    The wall is a one-texel ridge with its top at the texel centre; its
    shadow on the ground is the band from the top to ``h |cos phi| / tan e``
    texels across (the far face of the ridge included), so the sum of
    ``1 - V`` across the wall, divided by ``|cos phi|``, is the length along
    the azimuth. A column wall measures the x extent, a row wall the y
    extent; which side the shadow falls on pins +x right and +y up.
    """
    expected = WALL_H / math.tan(math.radians(elevation))
    for across, c in wall_shadow_extents(
        lambda: walls["col", elevation].render(azimuth).layers["visibility"],
        lambda: walls["row", elevation].render(azimuth).layers["visibility"],
        azimuth,
    ):
        assert across / c == pytest.approx(expected, abs=0.2)


def test_the_shipped_wall_scene_casts_its_documented_shadow(variant):
    from hzval.truth.plane import Truth

    scn = scene_files.load_scene(SCENES / "wall.toml")
    t = Truth(scn, sc.load_material_height(scn.material).height)
    e = math.radians(scn.light.elevation_deg)
    for azimuth in (0.0, 180.0):
        V = t.render(azimuth).layers["visibility"]
        assert (1.0 - V[8:-8]).sum(axis=1).mean() == pytest.approx(8.0 / math.tan(e), abs=0.2)


# --------------------------------------------------------------------------
# Soft light
# --------------------------------------------------------------------------


def _disk_visible_fraction(t):
    """Fraction of a uniform disk above a straight edge ``t`` radii above its centre."""
    t = np.clip(t, -1.0, 1.0)
    return (np.arccos(t) - t * np.sqrt(1.0 - t * t)) / np.pi


@pytest.fixture(scope="module")
def soft_wall(variant):
    from hzval.truth.plane import Truth

    scn = scene_files.load_scene(SCENES / "wall-soft.toml")
    height = sc.load_material_height(scn.material).height
    return scn, height, Truth(scn, height)


def test_soft_penumbra_has_the_width_the_geometry_predicts(soft_wall):
    """Behind a wall of height h, the penumbra runs from h/tan(e+rho) to h/tan(e-rho).

    In between, a point sees the part of the light's disk above the wall's
    top, at elevation ``atan(h / d)``: the visible fraction of a disk cut by
    a straight edge. Rows are alike (the wall spans the map), so their mean
    is compared with that fraction averaged over each pixel.
    """
    scn, _, t = soft_wall
    h, e, rho = 8.0, math.radians(scn.light.elevation_deg), math.radians(scn.light.radius_deg)
    top = 40.5
    V = t.render(0.0).layers["visibility"][8:-8].mean(axis=0)
    d_lo, d_hi = h / math.tan(e + rho), h / math.tan(e - rho)  # 11.43, 17.16
    x = np.arange(64)
    d_near, d_far = top - (x + 1), top - x  # a pixel's distances to the top
    umbra, lit = (d_far < d_lo - 0.05) & (x < 40), (d_near > d_hi + 0.05) & (x < 40)
    penumbra = (d_near > d_lo + 0.05) & (d_far < d_hi - 0.05)
    assert np.all(V[umbra] == 0.0) and np.all(V[lit] == 1.0)
    assert np.all((V[penumbra] > 0.0) & (V[penumbra] < 1.0))
    partial = np.flatnonzero((V > 0) & (V < 1) & (x < 40))
    assert top - (partial.max() + 1) == pytest.approx(d_lo, abs=1.0)  # its near end
    assert top - partial.min() == pytest.approx(d_hi, abs=1.0)  # its far end
    # and the profile itself, pixel by pixel
    u = (np.arange(64) + 0.5) / 64
    for col in np.flatnonzero(penumbra):
        d = top - (col + u)
        predicted = _disk_visible_fraction((np.arctan(h / d) - e) / rho).mean()
        assert V[col] == pytest.approx(predicted, abs=0.05)


def test_soft_light_variance_image_is_the_binomial_one_and_matches_the_spread(soft_wall):
    scn, _, t = soft_wall
    f = t.render(0.0)
    V, var, spp = f.layers["visibility"], f.variance["visibility"], scn.spp
    # shadow rays give 0 or 1, so the sample variance of the mean is V (1 - V) / (spp - 1)
    np.testing.assert_allclose(var, V * (1.0 - V) / (spp - 1), atol=1e-7)
    # rows 8..55 are exchangeable: their spread per column is the variance of one pixel mean
    # (ground columns only: the wall's own pixel is half in shadow by geometry, not by chance)
    mean = V[8:-8, :39].mean(axis=0)
    cols = np.flatnonzero((mean > 0.15) & (mean < 0.85))
    assert len(cols) >= 3
    observed = V[8:-8, cols].var(axis=0, ddof=1).sum()
    reported = var[8:-8, cols].mean(axis=0).sum()
    assert 0.6 < observed / reported < 1.4
    assert np.all(var[V == 1.0] == 0.0)


def test_soft_light_of_vanishing_radius_converges_to_the_hard_light(variant):
    h = column_wall(24, 32, 22)
    hard = truth(h, 4.0 / 32, elevation=30.0).render(0.0).layers["visibility"]
    soft = truth(h, 4.0 / 32, elevation=30.0, kind="soft", radius=0.01).render(0.0).layers["visibility"]
    assert np.abs(soft - hard).mean() < 1e-3
    assert np.abs(soft - hard).max() <= 2.0 / 16


def test_fixed_seed_is_deterministic_and_another_seed_differs(soft_wall):
    from hzval.truth.plane import Truth

    scn, height, t = soft_wall
    a = t.render(45.0)
    b = t.render(45.0)
    c = Truth(scn, height).render(45.0)
    assert np.array_equal(a.layers["visibility"], b.layers["visibility"])
    assert np.array_equal(a.layers["visibility"], c.layers["visibility"])
    assert np.array_equal(a.image, c.image)
    d = Truth(dataclasses.replace(scn, seed=1), height).render(45.0)
    assert not np.array_equal(a.layers["visibility"], d.layers["visibility"])
    assert abs(a.layers["visibility"].mean() - d.layers["visibility"].mean()) < 0.01


def test_a_new_azimuth_reuses_the_compiled_kernels(soft_wall, walls):
    import drjit as dr

    for t in (walls["col", 30.0], soft_wall[2]):
        t.render(10.0)
        dr.set_flag(dr.JitFlag.KernelHistory, True)
        try:
            dr.kernel_history()
            t.render(-35.0)
            t.render(123.0)
            history = dr.kernel_history()
        finally:
            dr.set_flag(dr.JitFlag.KernelHistory, False)
        jit = [k for k in history if str(k["type"]).endswith("JIT")]
        assert jit and all(k["cache_hit"] for k in jit)


# --------------------------------------------------------------------------
# Shading
# --------------------------------------------------------------------------


@pytest.mark.parametrize("effects", [("diffuse",), ("shadow", "diffuse")])
def test_lambertian_flat_plane_gives_albedo_over_pi_E_cos_theta(variant, effects):
    rows, cols, ss = 6, 7, 2
    albedo = np.random.default_rng(4).random((rows, cols, 3)).astype(np.float32)
    E, e = 2.5, 35.0
    t = truth(
        np.full((rows, cols), 0.5),
        0.1,
        effects=effects,
        elevation=e,
        irradiance=E,
        spp=4,
        supersampling=ss,
        albedo_map=albedo,
    )
    f = t.render(123.0)
    # supersampled pixel (r, c) shows texel (r // ss, c // ss)
    expected = np.repeat(np.repeat(albedo, ss, 0), ss, 1) / np.pi * E * math.cos(math.radians(90.0 - e))
    assert f.image.shape == (rows * ss, cols * ss, 3)
    np.testing.assert_allclose(f.image, expected, rtol=2e-6)
    assert np.all(f.variance["image"] <= 1e-12)  # only float rounding of the filtered normal


def ramp(rows, cols, slope_deg):
    """Heights rising toward +x by ``tan(slope)`` texels per texel, and the depth for them."""
    h = np.tile(np.arange(cols, dtype=np.float32) / (cols - 1), (rows, 1))
    return h, math.tan(math.radians(slope_deg)) * (cols - 1) / cols


@pytest.mark.parametrize("azimuth", [0.0, 90.0, 180.0])
def test_lambert_on_a_ramp_uses_the_normal_of_the_displaced_surface(variant, azimuth):
    h, depth = ramp(6, 16, 20.0)
    E, a, e = 1.5, 0.6, 40.0
    f = truth(h, depth, effects=("shadow", "diffuse"), elevation=e, irradiance=E, albedo=a, spp=4).render(
        azimuth
    )
    b, el, phi = math.radians(20.0), math.radians(e), math.radians(azimuth)
    n = np.array([-math.sin(b), 0.0, math.cos(b)])  # the ramp faces -x
    L = np.array([math.cos(el) * math.cos(phi), math.cos(el) * math.sin(phi), math.sin(el)])
    expected = a / math.pi * E * max(0.0, float(n @ L))
    np.testing.assert_allclose(f.image[:, 1:-1], expected, rtol=1e-5)  # the border half-texels are flat


def test_blinn_phong_specular_on_a_flat_plane(variant):
    from hzval.core.shading import SPECULAR_EXPONENT, SPECULAR_KS

    E, e, a = 1.2, 70.0, 0.3
    flat = np.full((4, 4), 0.2)
    spec = truth(flat, 0.1, effects=("specular",), elevation=e, irradiance=E, spp=4).render(10.0).image
    # h = normalize(L + z) lies halfway between the zenith and the light
    expected = SPECULAR_KS * E * math.cos(math.radians((90.0 - e) / 2)) ** SPECULAR_EXPONENT
    np.testing.assert_allclose(spec, expected, rtol=1e-5)
    both = (
        truth(flat, 0.1, effects=("diffuse", "specular"), elevation=e, irradiance=E, albedo=a, spp=4)
        .render(10.0)
        .image
    )
    np.testing.assert_allclose(both, expected + a / math.pi * E * math.sin(math.radians(e)), rtol=1e-5)


@pytest.mark.parametrize("shading", sc.SHADINGS)
def test_diffuse_is_mitsubas_own_diffuse_bsdf_on_the_displaced_mesh(variant, bumps, shading):
    """The truth shades with its own Lambert (module docstring); it must equal
    Mitsuba's ``diffuse`` plugin evaluated at the same surface interactions: with
    Mitsuba's own shading frame from the mesh's vertex normals (smooth), or with
    the facet's normal (faceted)."""
    import drjit as dr
    import mitsuba as mi

    h, depth = bumps
    E, a, az, e = 1.7, 0.45, 30.0, 35.0
    t = truth(
        h, depth, "wrap", effects=("diffuse",), elevation=e, irradiance=E, albedo=a, spp=4, shading=shading
    )
    image = t.render(az).image
    xs, ys = hz_camera.sample_positions(*h.shape, t.scene.camera, t.spp, t.scene.seed)
    si = t.mi_scene.ray_intersect(
        mi.Ray3f(mi.Point3f(mi.Float(xs), mi.Float(ys), 100.0), mi.Vector3f(0.0, 0.0, -1.0))
    )
    assert bool(dr.all(si.is_valid()))
    # the truth's shading frame: the facet's own normal, or the vertex normals' bilinear interpolation
    si.sh_frame = mi.Frame3f(si.n if shading == "faceted" else t._surface_at(mi.Float(xs), mi.Float(ys))[2])
    si.wi = si.to_local(mi.Vector3f(0.0, 0.0, 1.0))
    bsdf = mi.load_dict({"type": "diffuse", "reflectance": {"type": "rgb", "value": [a, a, a]}})
    L = mi.Vector3f(*(float(c) for c in t.scene.light.direction(az)))
    f_cos = bsdf.eval(mi.BSDFContext(), si, si.to_local(L))  # f * cos(theta_o)
    per_sample = np.asarray(f_cos.x, np.float64) * E
    expected = per_sample.reshape(-1, t.spp).mean(axis=1).reshape(h.shape)
    assert expected.std() > 0.01  # the bumps do vary the shading
    np.testing.assert_allclose(image[..., 0], expected, rtol=1e-4, atol=1e-6)


# --------------------------------------------------------------------------
# Boundaries
# --------------------------------------------------------------------------


@pytest.mark.parametrize("azimuth", [0.0, 270.0])
def test_wrap_carries_a_shadow_across_the_tile_edge_and_open_does_not(variant, azimuth):
    # a wall 2 texels from the edge that the light's shadow runs toward:
    # light from +x (0 deg) shadows toward -x, across the left edge; light
    # from -y (270 deg, below) shadows toward +y, across the top edge
    rows = cols = 32
    h = column_wall(rows, cols, 2) if azimuth == 0.0 else row_wall(rows, cols, 2)
    L = WALL_H / math.tan(math.radians(30.0))  # 6.93 texels
    wrap = truth(h, WALL_H / cols, "wrap").render(azimuth).layers["visibility"]
    open_ = truth(h, WALL_H / cols, "open").render(azimuth).layers["visibility"]
    if azimuth == 270.0:  # make rows the x axis
        wrap, open_ = wrap.T, open_.T
    far = slice(cols - 4, cols)  # 4.4 texels of it wrap around
    assert np.all(wrap[:, far] == 0.0)
    assert np.all(open_[:, far] == 1.0)
    assert (1.0 - wrap).sum(axis=1).mean() == pytest.approx(L, abs=0.2)
    assert (1.0 - open_).sum(axis=1).mean() == pytest.approx(2.5, abs=0.2)  # cut at the edge


def test_a_low_soft_light_sees_past_endless_walls_traced_in_hops(variant):
    """Walls every 16 texels, endless in y (wrap), a disk light low over the horizon.

    The light (1.5 degrees up, 2 degrees radius, from azimuth 80) grazes along
    the walls: a ray may cross hundreds of texels in y, far beyond the wrap
    margin, before it clears or meets one. In the x-z plane each ray must
    clear the next wall top, ``h`` high at ``d`` texels, so it escapes iff
    ``L.z / |L.x| > h / d``; the reference is that rule applied to the very
    samples and light directions the truth draws. Directions under 0.25
    degrees count as occluded (``MIN_TRACED_ELEVATION_DEG``).
    """
    from hzval.truth.rays import MIN_TRACED_ELEVATION_DEG
    from hzval.truth.samples import off_edge_lines as _off_edge_lines

    rows, cols, wall, h = 8, 16, 8, 2.0
    t = truth(column_wall(rows, cols, wall), h / cols, "wrap", kind="soft", elevation=1.5, radius=2.0, spp=16)
    assert t.margin < 40  # sized for 10 degrees: the rays need hops
    azimuth = 80.0
    V = t.render(azimuth).layers["visibility"]
    xs, ys = hz_camera.sample_positions(rows, cols, t.scene.camera, 16, 0)
    xs, ys, _ = _off_edge_lines(xs, ys, rows, cols)
    L = sc.light_samples(t.scene.light, azimuth, xs.size, 0).astype(np.float64)
    top = wall + 0.5
    d = np.where(L[:, 0] > 0, (top - xs) % cols, (xs - top) % cols)
    clears = L[:, 2] > np.abs(L[:, 0]) * h / np.where(d == 0, cols, d)
    lit = clears & (L[:, 2] > math.sin(math.radians(MIN_TRACED_ELEVATION_DEG)))
    expected = lit.reshape(rows * cols, 16).mean(axis=1).reshape(rows, cols)
    ground = [c for c in range(cols) if abs(c + 0.5 - top) >= 1.5]
    assert 0.05 < expected[:, ground].mean() < 0.95
    np.testing.assert_array_equal(V[:, ground], expected[:, ground])


# --------------------------------------------------------------------------
# Self-intersection (shadow acne)
# --------------------------------------------------------------------------

NOISE = 64


@pytest.fixture(scope="module")
def noise(variant):
    """A 64x64 uniform-noise map with 4 texels of relief: slopes up to 4:1."""
    return np.random.default_rng(7).random((NOISE, NOISE)).astype(np.float32), 4.0 / NOISE


def test_no_false_shadows_on_vertices_and_edges_with_the_light_at_the_zenith(noise):
    """Nothing can occlude the zenith, so V == 1 everywhere, on vertices too.

    Rays from the exact vertices (texel centres) and edge midpoints, lifted
    vertically as the truth lifts them, report no hit; rays spawned the
    usual way (Mitsuba's ``spawn_ray``, offset along the triangle's normal)
    from the same points do: the pitfall is real on this map. Renders with
    samples placed on the edges (the truth moves them a few ulps off the
    edge lines) and with the default jittered samples are fully lit.
    """
    import drjit as dr
    import mitsuba as mi

    h, depth = noise
    xs, ys = on_mesh_edges(NOISE, NOISE)
    for boundary in ("wrap", "open"):
        t = truth(h, depth, boundary, elevation=90.0, spp=4, positions=(xs, ys))
        assert t.moved_off_edges == xs.size
        assert np.all(t.render(0.0).layers["visibility"] == 1.0)
        # the lift alone, from the exact vertices and edge points
        o, n, _, valid = t._surface_at(mi.Float(xs), mi.Float(ys))
        up = mi.Vector3f(0.0, 0.0, 1.0)
        assert dr.all(valid) and dr.none(t._occluded(o, up, 1))
        # Mitsuba's own offset, from the same hits
        si = t.mi_scene.ray_intersect(
            mi.Ray3f(mi.Point3f(mi.Float(xs), mi.Float(ys), 10.0), mi.Vector3f(0.0, 0.0, -1.0))
        )
        naive = np.asarray(t.mi_scene.ray_test(si.spawn_ray(up)), dtype=bool).reshape(-1, 4)
        assert naive[:, 0].mean() > 0.1  # from vertices: about 30%
    jittered = truth(h, depth, "wrap", elevation=90.0, spp=16)
    assert np.all(jittered.render(0.0).layers["visibility"] == 1.0)


@pytest.mark.parametrize("slope, lit", [(2.5, True), (7.5, False)])
def test_grazing_light_on_a_smooth_ramp_has_no_false_shadows(variant, slope, lit):
    """A plane rising toward a light at 5 degrees: lit if it is less steep, else self-shadowed."""
    h, depth = ramp(8, 48, slope)
    for positions, spp in ((on_mesh_edges(8, 48), 4), (None, 16)):
        t = truth(h, depth, elevation=5.0, spp=spp, positions=positions)
        for azimuth in (0.0, 30.0, -30.0):
            V = t.render(azimuth).layers["visibility"]
            if lit:
                assert np.all(V == 1.0)
            else:
                # the border rows and columns see past the tile's edge (open): nothing is there
                assert np.all(V[1:-1, 1:-1] == 0.0)
        if lit:
            assert np.all(t.render(180.0).layers["visibility"] == 1.0)  # from behind, at 5 + slope


# --------------------------------------------------------------------------
# Ambient: the cosine-weighted sky
# --------------------------------------------------------------------------


def test_ambient_of_a_flat_plane_is_one_and_adds_the_sky(variant):
    # with neither diffuse nor specular declared the direct term is E (grey), as for shadow-only scenes
    E, a, e = 2.0, 0.7, 40.0
    for boundary in ("wrap", "open"):
        f = truth(
            np.full((6, 6), 0.4),
            0.1,
            boundary,
            effects=("ambient",),
            elevation=e,
            irradiance=E,
            albedo=a,
            spp=4,
        ).render(0.0)
        assert np.all(f.layers["ambient"] == 1.0)
        np.testing.assert_allclose(f.image, E + a * E / math.pi, rtol=1e-6)
        f = truth(
            np.full((6, 6), 0.4),
            0.1,
            boundary,
            effects=("diffuse", "ambient"),
            elevation=e,
            irradiance=E,
            albedo=a,
            spp=4,
        ).render(0.0)
        np.testing.assert_allclose(f.image, a / math.pi * E * (math.sin(math.radians(e)) + 1.0), rtol=1e-6)


def test_ambient_of_a_periodic_grating_matches_the_cosine_weighted_horizon(variant):
    """Walls every 24 texels, endless in y (wrap): a 2-D horizon on each side.

    From flat ground a distance ``d`` from a wall top of height ``h``, the
    cosine-weighted directions that clear it on that side are
    ``1 / (2 sqrt(1 + (h/d)^2))`` of all; the map is 8 rows high, so rays
    near the wall's direction cross many tiles and are traced in hops.
    """
    rows, cols, wall, h = 8, 24, 12, 3.0
    t = truth(column_wall(rows, cols, wall), h / cols, "wrap", effects=("shadow", "ambient"), spp=16)
    f = t.render(0.0)
    A, var = f.layers["ambient"], f.variance["ambient"]
    top = wall + 0.5
    u = (np.arange(32) + 0.5) / 32
    checked = 0
    for col in range(cols):
        x = col + u
        if np.any(np.abs(x - top) < 1.0) or np.any(np.abs(x + cols - top) < 1.0):
            continue  # on the wall's faces
        d_right = (top - x) % cols
        d_left = cols - d_right
        predicted = (0.5 / np.sqrt(1 + (h / d_right) ** 2) + 0.5 / np.sqrt(1 + (h / d_left) ** 2)).mean()
        sd = math.sqrt(var[:, col].mean() / rows)
        assert A[:, col].mean() == pytest.approx(predicted, abs=4.5 * sd + 1e-3)
        checked += 1
    assert checked == cols - 3
    assert t.timings["ambient_s"] > 0


# --------------------------------------------------------------------------
# Reflection occlusion: the glossy lobe about the mirror direction
# --------------------------------------------------------------------------


def sawtooth(rows, cols, period, slope_deg):
    """V-grooves along y: heights falling then rising at ``slope`` (texels per texel), period in texels."""
    x = np.arange(cols)
    tri = np.abs((x % period) - period / 2) / (period / 2)  # 1 at the ridges, 0 in the valleys
    depth = math.tan(math.radians(slope_deg)) * (period / 2) / cols
    return np.tile(tri.astype(np.float32), (rows, 1)), depth


def test_reflection_of_a_flat_plane_escapes_and_leaves_the_image_alone(variant):
    for boundary in ("wrap", "open"):
        t = truth(np.full((6, 6), 0.3), 0.1, boundary, effects=("diffuse", "reflection_occlusion"), spp=4)
        f = t.render(0.0)
        assert np.all(f.layers["reflection_occlusion"] == 1.0)
        assert np.all(f.variance["reflection_occlusion"] == 0.0)
        plain = truth(np.full((6, 6), 0.3), 0.1, boundary, effects=("diffuse",), spp=4).render(0.0)
        np.testing.assert_array_equal(f.image, plain.image)
        assert t.timings["reflection_s"] > 0


@pytest.mark.parametrize(
    "slope, lo, hi",
    [
        (10.0, 0.99, 1.0),  # the mirror ray leaves at 70 degrees, far above the 10-degree facing facet
        (50.0, 0.0, 0.02),  # it leaves at -10 degrees: below the horizontal, into the groove
    ],
)
def test_reflection_in_v_grooves_escapes_shallow_facets_and_not_steep_ones(variant, slope, lo, hi):
    h, depth = sawtooth(4, 32, 16, slope)
    R = (
        truth(h, depth, "wrap", effects=("reflection_occlusion",), spp=16, shading="faceted")
        .render(0.0)
        .layers["reflection_occlusion"]
    )
    # the ridge and valley columns sit on a crease: leave them out, and the lobe's upper
    # edge clears the facing ridge from the top quarter of a steep facet: leave that out too
    facets = np.r_[3:8, 9:14, 19:24, 25:30]
    assert lo <= R[:, facets].mean() <= hi


def _grooves_reflection_reference(cols, period, slope_deg, n=4000, seed=1):
    """Per column, the escaping share of the Blinn-Phong lobe on the V-grooves of
    :func:`sawtooth` (faceted), by an independent 2-D calculation: the grooves run along y,
    so a direction is blocked iff its run across x rises slower than the profile ahead of
    it. Half vectors drawn from ``pdf(h)`` weigh ``f cos / pdf``, proportional to ``wo.h``
    (``= h_z`` seen from ``v = +z``), where the lobe is above the facet."""
    from hzval.core.shading import SPECULAR_EXPONENT

    rng = np.random.default_rng(seed)
    b = math.radians(slope_deg)
    half = period / 2

    def profile(x):  # mesh vertices at texel centres: x = col + 0.5
        return np.abs(((x - 0.5) % period) - half) * math.tan(b)

    out = np.empty(cols)
    for c in range(cols):
        x0 = c + rng.random(n)
        z0 = profile(x0)
        falling = ((x0 - 0.5) % period) < half  # the profile falls toward +x here
        nx = np.where(falling, 1.0, -1.0) * math.sin(b)  # n = normalize(-dh/dx, 0, 1)
        nz = math.cos(b)
        cos_h = rng.random(n) ** (1.0 / (SPECULAR_EXPONENT + 1))
        sin_h, phi = np.sqrt(1 - cos_h**2), 2 * math.pi * rng.random(n)
        # frame about n: t1 in the xz plane, t2 = +y
        hx = sin_h * np.cos(phi) * nz + cos_h * nx
        sin_h * np.sin(phi)
        hz = -sin_h * np.cos(phi) * nx + cos_h * nz
        wx, wz = 2 * hz * hx, 2 * hz * hz - 1  # v = +z reflected about h
        ok = (nx * wx + nz * wz > 0) & (wz > 0)
        run = np.abs(wx) + 1e-12
        # march one period across x: a rising ray that clears the first ridge it meets clears all
        s = np.linspace(0.0, period, 400)[None, :]
        z = z0[:, None] + s * (wz / run)[:, None]
        blocked = np.any(profile(x0[:, None] + np.sign(wx)[:, None] * s) > z + 1e-6, axis=1)
        w = np.where(nx * wx + nz * wz > 0, hz, 0.0)
        out[c] = np.sum(w * (ok & ~blocked)) / np.sum(w)
    return out


def test_reflection_in_v_grooves_matches_an_independent_2d_calculation(variant):
    """35-degree grooves, where the mirror ray leaves at 20 degrees toward the facing facet:
    low on a facet it is blocked, high on it it clears the facing ridge."""
    P, slope = 16, 35.0
    h, depth = sawtooth(4, P, P, slope)
    R = truth(h, depth, "wrap", effects=("reflection_occlusion",), spp=256, shading="faceted").render(0.0)
    r = R.layers["reflection_occlusion"].mean(axis=0)
    ref = _grooves_reflection_reference(P, P, slope)
    assert ref.max() - ref.min() > 0.5  # the case does discriminate
    # per column: 4 rows x 256 samples, standard error <= 0.016; the reference's <= 0.008
    np.testing.assert_allclose(r, ref, atol=0.06)


# --------------------------------------------------------------------------
# Interreflection
# --------------------------------------------------------------------------


@pytest.fixture(scope="module")
def bumps(variant):
    from scipy.ndimage import gaussian_filter

    rng = np.random.default_rng(3)
    h = gaussian_filter(rng.random((20, 20)), 2.0, mode="wrap")
    return ((h - h.min()) / (h.max() - h.min())).astype(np.float32), 3.0 / 20


def test_path_tracer_to_depth_2_is_the_direct_render(bumps):
    h, depth = bumps
    kw = dict(elevation=20.0, albedo=0.6, spp=4)
    direct = truth(h, depth, "wrap", effects=("shadow", "diffuse"), **kw).render(30.0)
    path = truth(h, depth, "wrap", effects=("shadow", "diffuse", "interreflection"), depth_ir=2, **kw).render(
        30.0
    )
    np.testing.assert_array_equal(path.image, direct.image)
    more = truth(h, depth, "wrap", effects=("shadow", "diffuse", "interreflection"), depth_ir=4, **kw).render(
        30.0
    )
    assert more.image.mean() > direct.image.mean() * 1.005  # light bounces between bumps


def test_white_furnace_a_white_surface_under_a_uniform_sky_is_as_bright_as_the_sky(bumps):
    """Albedo 1, sky only (light below the horizon): every path ends in the sky.

    With enough bounces the surface shows exactly the sky's radiance; with
    direct light only (depth 2) it shows the sky times the ambient term.
    """
    h, depth = bumps
    E = 1.0
    # faceted: interpolated shading normals do not conserve energy (directions below the facet are lost)
    kw = dict(
        effects=("shadow", "diffuse", "ambient", "interreflection"),
        elevation=-90.0,
        albedo=1.0,
        irradiance=E,
        spp=4,
        shading="faceted",
    )
    sky = E / math.pi
    deep = truth(h, depth, "wrap", depth_ir=8, **kw).render(0.0)
    assert deep.image.mean() == pytest.approx(sky, rel=1e-3)
    assert deep.image.max() <= sky * (1 + 1e-5)
    direct = truth(h, depth, "wrap", depth_ir=2, **kw).render(0.0)
    np.testing.assert_allclose(direct.image[..., 0], sky * direct.layers["ambient"], rtol=1e-5)
    assert direct.image.mean() < deep.image.mean() * 0.999


@pytest.mark.parametrize("boundary", ["wrap", "open"])
def test_path_tracer_handles_soft_light_specular_and_sky_together(bumps, boundary):
    h, depth = bumps
    kw = dict(
        effects=("shadow", "diffuse", "specular", "ambient", "interreflection"),
        kind="soft",
        radius=3.0,
        elevation=25.0,
        albedo=0.7,
        spp=4,
    )
    two = truth(h, depth, boundary, depth_ir=2, **kw).render(20.0)
    four = truth(h, depth, boundary, depth_ir=4, **kw).render(20.0)
    for f in (two, four):
        assert np.all(np.isfinite(f.image)) and np.all(f.image >= 0.0)
        assert np.all(np.isfinite(f.variance["image"]))
    assert four.image.mean() > two.image.mean()


# --------------------------------------------------------------------------
# Deep relief under a grazing light: a bounded margin, the endless tiling by hops
# --------------------------------------------------------------------------


@pytest.mark.slow(
    reason="the full margin's mesh is 20 tiles a side; test_a_low_soft_light_... keeps hops fast"
)
def test_deep_relief_keeps_a_small_margin_and_sees_the_same_shadows(variant, monkeypatch):
    """Depth 2 on 48 x 48 bricks (80 texels of relief) at 10 degrees would want a margin of 457 texels
    (a mesh 20 times the tile a side); the capped margin is 32 texels, and its rays hop to the same
    visibility, sample for sample, as the full margin's."""
    from hzval.core import conventions as cv
    from hzval.geometry import tile as mesh
    from hzval.materials.bricks import bricks

    h = bricks(48)
    capped = truth(h, 2.0, "wrap", elevation=10.0, spp=4)
    assert capped.margin == mesh.MIN_MARGIN_CAP
    assert capped.margin < mesh.wrap_margin(cv.heights_in_texels(h, 2.0), 10.0) / 10
    monkeypatch.setattr(mesh, "MAX_MARGIN_TILES", 1e9)
    full = truth(h, 2.0, "wrap", elevation=10.0, spp=4)
    assert full.margin > 400
    for az in (0.0, 37.0, -120.0):
        a, b = capped.render(az).layers["visibility"], full.render(az).layers["visibility"]
        assert 0.05 < a.mean() < 0.95  # real shadows, long ones
        assert np.abs(a - b).max() <= 1 / 4 + 1e-6 and np.mean(a != b) < 0.002  # at most a sample of four


@pytest.mark.slow(
    reason="a sweep of deep relief at a grazing light; tests/hard/test_geometry.py keeps depth 10 fast"
)
def test_the_depth_5_grazing_sweep_runs(variant, tmp_path):
    """Issue 16's case at a small size: depth 5 at 10 degrees was killed for memory at 512 x 512."""
    import json

    from hzval.cli import main as cli

    np.save(tmp_path / "deep.npy", np.random.default_rng(3).random((40, 40)).astype(np.float32))
    out = tmp_path / "o"
    assert (
        cli.main(
            [
                "sweep",
                str(tmp_path / "deep.npy"),
                "--depth",
                "5",
                "--elevation",
                "10",
                "--azimuths",
                "0,90",
                "--spp",
                "4",
                "--out",
                str(out),
                "--quiet",
            ]
        )
        == 0
    )
    m = json.loads((out / "metrics.json").read_text())
    assert m["parameters"]["depth"] == 5 and len(m["frames"]) == 2
    assert all(0 < f["techniques"]["horizon"]["visibility_mae"] < 1 for f in m["frames"])


# ----------------------------------------------------------------------
# Bands (module docstring, "Memory"): a large image is rendered band by band, bit for bit
# ----------------------------------------------------------------------


@pytest.mark.parametrize(
    "kw",
    [
        dict(boundary="wrap", effects=("shadow", "diffuse"), spp=16),
        dict(
            boundary="open",
            effects=("shadow", "diffuse", "specular", "ambient"),
            kind="soft",
            radius=8.0,
            spp=5,
        ),
        dict(boundary="wrap", effects=("shadow", "diffuse", "reflection_occlusion"), spp=4, supersampling=2),
        dict(
            boundary="wrap",
            effects=("shadow", "diffuse", "ambient", "interreflection"),
            spp=4,
            depth_ir=3,
            elevation=12.0,
        ),
        dict(boundary="open", effects=("shadow",), spp=1),
    ],
)
def test_bands_give_the_pixels_of_one_piece(kw):
    """Bands of 3 and of 7 pixel rows (the last one short) against one band, their camera hits
    traced again in each frame or kept: every layer, the image and the variances are equal, not
    close; the samples moved off edge lines are counted once."""
    from hzval.truth.plane import Truth

    h = np.random.default_rng(8).random((17, 13)).astype(np.float32)
    scn = make_scene(h.shape, 0.15, **kw)
    whole = Truth(scn, h)
    ss = scn.camera.supersampling
    frames = [whole.render(az) for az in (-40.0, 25.0)]
    for rows, keep in ((3, False), (7, False), (3, True)):
        banded = Truth(scn, h, band_samples=rows * 13 * ss * scn.spp, keep=keep)
        assert len(banded.bands) == -(-17 * ss // rows) and len(whole.bands) == 1
        assert banded.keeps is keep and whole.keeps
        assert banded.moved_off_edges == whole.moved_off_edges
        for az, f in zip((-40.0, 25.0), frames):
            g = banded.render(az)
            assert np.array_equal(g.image, f.image)
            assert g.layers.keys() == f.layers.keys() and g.variance.keys() == f.variance.keys()
            for k in f.layers:
                assert np.array_equal(g.layers[k], f.layers[k]), k
            for k in f.variance:
                assert np.array_equal(g.variance[k], f.variance[k], equal_nan=True), k


def test_large_images_are_banded_by_default():
    from hzval.truth.samples import BAND_SAMPLES, KEEP_SAMPLES, KEPT_BAND_SAMPLES, band_ranges, keeps_samples

    kept = band_ranges((2048, 2048), 16)  # 67M samples: kept, in bands
    assert keeps_samples(2048, 2048, 16) and not keeps_samples(4096, 4096, 16)
    assert len(kept) == 2048 * 2048 * 16 // KEPT_BAND_SAMPLES and kept[-1][1] == 2048 * 2048
    assert band_ranges((64, 64), 16) == [(0, 64 * 64)]  # a small image: one band
    bands = band_ranges((4096, 4096), 16)  # 268M: bands of whole rows
    assert 4096 * 4096 * 16 > KEEP_SAMPLES and len(bands) == 4096 * 4096 * 16 // BAND_SAMPLES
    assert bands[0] == (0, 256 * 4096) and bands[-1][1] == 4096 * 4096
    assert all(a % 4096 == 0 and b % 4096 == 0 for a, b in bands)
    assert band_ranges((5, 3), 10**6, band_samples=1) == [
        (i * 3, i * 3 + 3) for i in range(5)
    ]  # one row at least
