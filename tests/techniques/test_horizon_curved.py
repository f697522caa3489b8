"""The curvature correction of the horizon map's sines (hzval.techniques.horizon_curved): exact on a ridge,
zero (bit for bit) on a flat surface, down on a convex surface and up on a concave one."""

import numpy as np
import pytest

from hzval.techniques import horizon_curved as hc


def _ridge(rows=16, cols=32, col=20, height=6.0):
    h = np.zeros((rows, cols), np.float32)
    h[:, col] = height
    return h


@pytest.mark.parametrize("kappa", [0.0, 0.05, -0.05, 0.5])
def test_a_ridge_ahead_is_seen_at_its_tangent_less_the_drop(kappa):
    h = _ridge()
    t = hc.bin_tangents(h, kappa, radius=16, angles=32, boundary="open")
    D = 8  # the texel D columns left of the ridge
    # only d = D meets the ridge (heights 0 elsewhere, read exactly at whole steps); at d != D the
    # flat floor is at -kappa d / 2, below the tangent plane on a convex surface, above on a concave one
    others = max(-0.5 * kappa * d for d in range(1, 17))
    assert t[0, 5, 20 - D] == pytest.approx(max(0.0, 6.0 / D - 0.5 * kappa * D, others), rel=1e-9)


def test_flat_changes_nothing():
    h = np.random.default_rng(1).random((16, 16)).astype(np.float32) * 4
    ds = hc.sine_change(h, 0.0)
    assert ds.shape == (16, 16, 8) and not ds.any()


def test_convex_lowers_every_horizon_and_concave_raises_it():
    h = np.random.default_rng(2).random((24, 24)).astype(np.float32) * 4
    down, up = hc.sine_change(h, 0.02), hc.sine_change(h, -0.02)
    assert down.max() <= 0.0 and down.mean() < -1e-3
    assert up.min() >= 0.0 and up.mean() > 1e-3
    # a smaller curvature lowers them less, texel by texel (each bin's tangent falls with kappa)
    small = hc.sine_change(h, 0.002)
    assert np.all(small >= down - 1e-6) and small.mean() < 0.0


def _context(size=32):
    from hzval.bake.maps import BakeParams, bake
    from hzval.scene import spec as sc
    from hzval.techniques import registry as technique

    scene = sc.override(sc.Scene(), height="bricks", size=size, effects="shadow", spp=1).validate()
    hm = sc.load_material_height(scene.material)
    baked = bake(hm.height, BakeParams(depth=scene.material.depth, boundary="wrap").validate())
    return technique.Context(scene, hm.height, baked, sc.load_albedo(scene.material, size, size))


def test_the_technique_is_a_plug_in_that_is_horizon_at_zero_curvature_and_brighter_when_convex():
    from hzval.techniques import registry as technique

    cls = technique.get("horizon-curved")
    assert cls.name == "horizon-curved" and "horizon-curved" not in technique.defaults()  # opt-in
    ctx = _context()
    base = technique.get("horizon").build(ctx)
    F = {k: cls.build(ctx, curvature=k) for k in (0.0, 2.0, -2.0)}
    for az in (0.0, 135.0):
        f0 = base.render(az, elevation_deg=12.0).layers["factor"]
        assert np.array_equal(F[0.0].render(az, elevation_deg=12.0).layers["factor"], f0)  # bit for bit
        convex, concave = (F[k].render(az, elevation_deg=12.0).layers["factor"] for k in (2.0, -2.0))
        assert np.all(convex >= f0 - 1e-6) and convex.mean() > f0.mean() + 1e-3  # lower horizons: more light
        assert np.all(concave <= f0 + 1e-6) and concave.mean() < f0.mean() - 1e-3
    assert F[2.0].parameters["curvature"] == 2.0


def test_a_curvature_that_is_not_a_number_is_refused():
    from hzval.core.errors import InputError
    from hzval.techniques import registry as technique

    with pytest.raises(InputError, match="curvature"):
        technique.get("horizon-curved").build(_context(16), curvature=float("nan"))
