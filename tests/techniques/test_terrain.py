"""Raudins' terrain shadows (hzval.techniques.terrain) against answers known in advance.

Flat ground is lit; a wall of height h casts a shadow h / tan(e) long on
the side away from the light (as the truth's test in tests/truth/test_plane.py
measures it, with its helpers); ``wrap`` carries shadows across the edge and
``open`` does not; the Dr.Jit and NumPy implementations agree; the factor is
finite and in [0, 1] at grazing, zenith and below-horizon lights; and on the
brick material it is closer to the truth's visibility than the horizon map.
"""

import math

import numpy as np
import pytest

from hzval.core.errors import InputError
from hzval.techniques import surface, terrain
from tests.helpers import WALL_AT, WALL_H, column_wall, make_scene, row_wall, wall_shadow_extents


def shadow(h, depth, boundary="open", impl="drjit", **kw):
    return terrain.TerrainShadow(
        make_scene(np.shape(h), depth, boundary, **kw), np.asarray(h, np.float32), impl=impl
    )


@pytest.mark.parametrize("boundary", ["wrap", "open"])
@pytest.mark.parametrize("impl", terrain.IMPLS)
def test_flat_map_is_fully_lit(variant, boundary, impl):
    ts = shadow(np.full((12, 16), 0.3), 0.1, boundary, impl, elevation=10.0, spp=4)
    for azimuth in (0.0, 77.0, 200.0, -45.0):
        f = ts.render(azimuth)
        assert np.all(f.layers["factor"] == 1.0)
        assert np.all(f.image == 1.0)  # shadow only: E times the factor


@pytest.fixture(scope="module")
def walls(variant):
    return {
        ("col", e): shadow(column_wall(40, 40, WALL_AT), WALL_H / 40, elevation=e) for e in (30.0, 50.0)
    } | {("row", e): shadow(row_wall(40, 40, WALL_AT), WALL_H / 40, elevation=e) for e in (30.0, 50.0)}


@pytest.mark.parametrize("elevation", [30.0, 50.0])
@pytest.mark.parametrize("azimuth", [0.0, 45.0, 90.0, 180.0])
def test_wall_casts_a_shadow_h_over_tan_e_long_away_from_the_light(walls, azimuth, elevation):
    """Measured as tests/truth/test_plane.py measures the truth, within a texel.

    The technique interpolates the boundary linearly between texel centres
    (Raudins interpolates it across triangles), so on the wall's far face,
    between its top and the next texel centre, part is lit that the mesh
    shadows: the shadow comes out 0.5-0.8 texel short across the wall, never
    long (along a diagonal azimuth that is up to 1.1 texels along the ray).
    """
    expected = WALL_H / math.tan(math.radians(elevation))
    for across, c in wall_shadow_extents(
        lambda: walls["col", elevation].render(azimuth).layers["factor"],
        lambda: walls["row", elevation].render(azimuth).layers["factor"],
        azimuth,
    ):
        assert expected * c - 1.0 < across <= expected * c + 0.05


@pytest.mark.parametrize("impl", terrain.IMPLS)
def test_wrap_shadow_crosses_the_edge_and_open_does_not(variant, impl):
    """A wall at column 37 of 40 lit from -x (azimuth 180) casts its shadow toward +x, past the right
    edge: wrap brings it back at the left, open does not."""
    h = column_wall(24, 40, 37)
    depth = WALL_H / 40  # 4 texels high: 6.9 texels of shadow at 30 degrees
    wrapped = shadow(h, depth, "wrap", impl).render(180.0).layers["factor"]
    opened = shadow(h, depth, "open", impl).render(180.0).layers["factor"]
    assert wrapped[:, :4].max() < 0.5  # columns 0-3: 38.5 .. 43.5 along the tiled ground
    assert np.all(opened[:, :30] == 1.0)  # nothing beyond the edge
    assert opened[:, 38:].max() < 0.5  # its own shadow inside the map


def test_wrap_finds_occluders_several_tiles_away_at_grazing_light(variant):
    """At 1 degree a 4-texel wall shadows 229 texels: more than 11 tiles of 20 away, it still does."""
    h = column_wall(8, 20, 10)
    F = shadow(h, 4.0 / 20, "wrap", elevation=1.0, spp=1).render(180.0).layers["factor"]
    assert np.all(F[:, np.arange(20) != 10] < 0.5)  # every ground column is in the wall's shadow


@pytest.mark.parametrize("boundary", ["wrap", "open"])
@pytest.mark.parametrize("kind", ["hard", "soft"])
def test_drjit_and_numpy_agree(variant, boundary, kind):
    from hzval.materials.bricks import bricks

    h = bricks(64)[:48, :56]  # not square: the transposed sweeps differ
    kw = dict(elevation=25.0, kind=kind, radius=4.0 if kind == "soft" else 0.0, spp=4)
    a = shadow(h, 0.05, boundary, "drjit", **kw)
    b = shadow(h, 0.05, boundary, "numpy", **kw)
    for az in (0.0, 33.0, 90.0, 135.0, 200.0, -60.0):
        Fa, Fb = a.factor(az), b.factor(az)
        assert np.abs(Fa - Fb).mean() < 1e-4
        assert np.abs(Fa - Fb).max() < 0.02  # float32 against float64 at a ramp of 0.02 texel


@pytest.mark.parametrize("boundary", ["wrap", "open"])
@pytest.mark.parametrize(
    "elevation, expect", [(0.5, None), (90.0, 1.0), (89.99, None), (0.0, 0.0), (-5.0, 0.0)]
)
def test_factor_is_finite_in_unit_range_at_extreme_lights(variant, boundary, elevation, expect):
    from hzval.materials.bricks import bricks

    for kind in ("hard", "soft"):
        ts = shadow(
            bricks(32),
            0.05,
            boundary,
            elevation=elevation,
            kind=kind,
            radius=2.0 if kind == "soft" else 0.0,
            spp=2,
        )
        for az in (0.0, 45.0, 170.0):
            F = ts.render(az).layers["factor"]
            assert np.isfinite(F).all() and F.min() >= 0 and F.max() <= 1
            if expect is not None:
                assert np.all(F == expect)
        if elevation == 0.5:
            assert F.mean() < 0.9  # grazing light: mostly shadowed bricks


def test_soft_light_widens_the_penumbra_with_distance(variant):
    """Behind a wall, a disk light's ramp runs from h/tan(e + rho) to h/tan(e - rho)."""
    h, e, rho = 8.0, 30.0, 5.0
    ts = shadow(column_wall(16, 64, 40), h / 64, elevation=e, kind="soft", radius=rho, spp=16)
    F = ts.render(0.0).layers["factor"].mean(axis=0)
    top = 40.5
    d_lo, d_hi = h / math.tan(math.radians(e + rho)), h / math.tan(math.radians(e - rho))  # 11.4, 17.2
    x = np.arange(64) + 0.5
    assert np.all(F[(top - x > d_hi + 1) & (x < 40)] == 1.0)
    assert np.all(F[(top - x < d_lo - 1) & (top - x > 1.5)] == 0.0)
    partial = (F > 0) & (F < 1) & (x < 39)
    assert partial.sum() >= d_hi - d_lo - 1


def test_bad_ramp_and_impl_are_refused(variant):
    with pytest.raises(InputError, match="ramp"):
        terrain.TerrainShadow(make_scene((4, 4), 0.1), np.zeros((4, 4)), ramp=0.0)
    with pytest.raises(InputError, match="impl"):
        terrain.TerrainShadow(make_scene((4, 4), 0.1), np.zeros((4, 4)), impl="cuda-please")


@pytest.fixture(scope="module")
def bricks64(variant):
    from hzval.bake import maps as bake
    from hzval.scene import spec as sc
    from hzval.techniques import horizon
    from hzval.truth import plane as truth

    scn = sc.Scene(material=sc.MaterialSpec(size=64), effects=("shadow", "diffuse")).validate()
    height = sc.load_material_height(scn.material).height
    bk = bake.bake(height, bake.BakeParams(depth=scn.material.depth, boundary="wrap"))
    return scn, height, bk, truth.Truth(scn, height), horizon.Horizon(scn, bk)


def test_closer_to_the_truth_than_the_horizon_map_on_bricks(bricks64):
    """Mean |F - V| over Figure 5.3's sweep at 64 px: terrain 0.012, horizon map 0.021 (measured)."""
    from hzval.metrics import compare

    scn, height, bk, tr, ap = bricks64
    shared = surface.Unshadowed(scn, bk)
    ts = terrain.TerrainShadow(scn, height, bake=bk, unshadowed=shared)
    terrain_mae, horizon_mae = [], []
    for az in scn.light.azimuths_deg:
        V = tr.render(az).layers["visibility"]
        plain = ap.render(az, shadows=False)
        f = ts.render(az)
        terrain_mae.append(compare.visibility_metrics(V, f.layers["factor"])[0])
        horizon_mae.append(compare.visibility_metrics(V, ap.render(az).layers["factor"])[0])
        # the image is the plain render times the factor (shadow and diffuse, no ambient)
        np.testing.assert_allclose(f.image, plain.image * f.layers["factor"][..., None], rtol=1e-6)
        assert f.seconds >= shared.render(az)[0].seconds > 0  # the shared unshadowed render counts
    assert np.mean(terrain_mae) < 0.016
    assert np.mean(terrain_mae) < np.mean(horizon_mae)
    assert max(terrain_mae) < 0.03


def test_without_a_bake_it_shades_with_its_own_normal_map(bricks64):
    scn, height, bk, _, ap = bricks64
    own = terrain.TerrainShadow(scn, height)
    shared = terrain.TerrainShadow(scn, height, bake=bk, unshadowed=surface.Unshadowed(scn, bk))
    a, b = own.render(20.0), shared.render(20.0)
    np.testing.assert_allclose(a.image, b.image, atol=1e-5)
    assert own.simulated == shared.simulated == ("shadow", "diffuse")


def test_ambient_is_not_shadowed(variant):
    """With ambient declared, image = direct F + ambient: a fully shadowed
    pixel keeps its sky, albedo * A * E / pi (A its ambient-map layer, uniform albedo)."""
    from hzval.bake import maps as bake
    from hzval.core.shading import SKY_RADIANCE_PER_IRRADIANCE

    h = column_wall(16, 32, 20)
    scn = make_scene(
        h.shape, 4 / 32, "open", effects=("shadow", "diffuse", "ambient"), spp=4, albedo=0.5, irradiance=2.0
    )
    bk = bake.bake(h, bake.BakeParams(depth=4 / 32, boundary="open"))
    f = terrain.TerrainShadow(scn, h, bake=bk).render(0.0)
    dark = f.layers["factor"] == 0
    assert dark.sum() > 16
    sky = 0.5 * 2.0 * SKY_RADIANCE_PER_IRRADIANCE * f.layers["ambient"][dark]
    assert np.all(sky > 0.05)  # the sky is there, and not tiny
    np.testing.assert_allclose(f.image[dark], np.repeat(sky[:, None], 3, axis=1), rtol=1e-5)
