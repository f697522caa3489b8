"""The truth's mesh in bands (hzval.truth.bands) gives the single mesh's answers, bit for bit.

A band's mesh holds only the cells its samples' rays can reach; the test compares whole frames of a
truth in bands with the single mesh's, ``open`` and ``wrap``, at azimuths along +-x, +-y and between,
with bands narrower than the shadows' reach (so rays cross bands and, ``wrap``, the tile's edge). A
cover too narrow (the reach taken away) must then differ: the comparison can fail.
"""

import dataclasses

import numpy as np
import pytest

from hzval import materials
from hzval.core import budget, resources
from hzval.geometry import tile as mesh
from hzval.truth import bands as truth_bands
from hzval.truth import memory
from tests.helpers import make_scene

AZIMUTHS = (-60.0, 0.0, 90.0, -90.0, 20.0, 135.0, 180.0)


def _scene(h, boundary, **kw):
    sc = make_scene(h.shape, 0.05, boundary, effects=("shadow", "diffuse"), spp=4, **kw)
    return dataclasses.replace(sc, light=dataclasses.replace(sc.light, azimuths_deg=AZIMUTHS))


@pytest.fixture(scope="module")
def bricks():
    return materials.generate("bricks", 128).height.astype(np.float32)


def _same_frames(h, boundary, n_bands):
    from hzval.truth.plane import Truth

    sc = _scene(h, boundary)
    one = Truth(sc, h)
    rows = h.shape[0]
    # sample bands and meshes of rows / 16 rows: narrower than the shadows' reach along y
    bands = Truth(sc, h, mesh_band_rows=rows // n_bands, band_samples=rows // 16 * h.shape[1] * 4)
    assert len(bands.mesh_bands) == n_bands and bands.mesh is None
    up, down = truth_bands.reach(sc, bands.relief, bands.lift, AZIMUTHS)
    assert rows // n_bands < up - truth_bands.PAD_TEXELS < rows / 2 and up == down
    total = mesh.triangle_count(bands._levels)
    assert (
        bands.band_triangles_largest < total < bands.band_triangles_built
    )  # each band a part, and its cover
    for az in AZIMUTHS + (250.0,):  # 250: a light of its own pass
        a, b = one.render(az), bands.render(az)
        assert set(a.layers) == set(b.layers)
        for k in a.layers:
            np.testing.assert_array_equal(a.layers[k], b.layers[k], err_msg=f"{boundary} {az} {k}")
        np.testing.assert_array_equal(a.image, b.image)
        assert 0.3 < float(a.layers["visibility"].mean()) < 0.95


@pytest.mark.parametrize("boundary", ["open", "wrap"])
def test_bands_give_the_single_mesh_frames_bit_for_bit(variant, bricks, boundary):
    _same_frames(bricks, boundary, 16)


@pytest.mark.slow
@pytest.mark.parametrize("boundary", ["open", "wrap"])
def test_bands_give_the_single_mesh_frames_bit_for_bit_at_512(variant, boundary):
    _same_frames(materials.generate("bricks", 512).height.astype(np.float32), boundary, 16)


def test_a_cover_without_the_reach_differs(variant, bricks, monkeypatch):
    from hzval.truth.plane import Truth

    sc = _scene(bricks, "wrap")
    one = Truth(sc, bricks)
    monkeypatch.setattr(
        truth_bands, "reach", lambda *a, **k: (truth_bands.PAD_TEXELS, truth_bands.PAD_TEXELS)
    )
    short = Truth(sc, bricks, mesh_band_rows=8, band_samples=8 * 128 * 4)
    a, b = one.render(90.0).layers["visibility"], short.render(90.0).layers["visibility"]
    # shadows cut at the bands' edges: more light, in many pixels
    assert b.mean() > a.mean() and np.count_nonzero(b > a) > 20 and np.count_nonzero(b < a) == 0


def test_cover_runs_wrap_around_the_tile():
    h = np.zeros((16, 8), np.float32)
    g = mesh.grid(h, "wrap", margin=3)
    # y in [14, 18]: the tile's top rows and, modulo 16, the margin's bottom rows (y in [-2, 2])
    # cell i spans y from 17.5 - i to 18.5 - i: cells 0-4 in the tile's top, 16-20 the margin below
    assert truth_bands.cover_runs(g, 16, 14.0, 18.0, True) == [(0, 5), (16, 21)]
    assert truth_bands.cover_runs(g, 16, 14.0, 18.0, False) == [(0, 5)]
    open_g = mesh.grid(h, "open")
    assert truth_bands.cover_runs(open_g, 16, 4.0, 6.0, False) == [(10, 13)]


def test_why_not_names_the_rays_that_leave_a_band():
    h = np.zeros((8, 8), np.float32)
    assert truth_bands.why_not(_scene(h, "wrap")) is None
    assert "ambient" in truth_bands.why_not(
        dataclasses.replace(_scene(h, "wrap"), effects=("shadow", "ambient"))
    )
    assert "faceted" in truth_bands.why_not(_scene(h, "wrap", shading="faceted"))
    assert "horizon" in truth_bands.why_not(_scene(h, "wrap", kind="soft", radius=10.0, elevation=5.0))


def test_a_refusal_in_bands_names_the_flag_and_the_bands(variant, monkeypatch):
    from hzval.bake import maps as bake
    from hzval.core.errors import InputError
    from hzval.pipeline import sweep
    from hzval.scene.spec import load_material_height

    sc = _scene(np.zeros((1024, 1024), np.float32), "wrap")  # 4 sample bands of 256 rows
    sc = dataclasses.replace(
        sc, material=dataclasses.replace(sc.material, height="bricks", size=1024), spp=16
    )
    height = load_material_height(sc.material).height
    monkeypatch.setattr(budget, "PEAK_TARGET_BYTES", 2**20)  # a mesh in bands, whatever the map
    plan = memory.truth_plan(sc, height)
    assert plan.band_rows is not None and 0 < plan.band_triangles < plan.triangles
    monkeypatch.setattr(resources, "available_bytes", lambda: 2**20)
    monkeypatch.setattr(bake, "check_fits", lambda *a: None)  # the bake's own check would refuse first
    with pytest.raises(InputError) as err:
        memory.check_fits(sc, sweep.Options().bake_params(sc), height, plan)
    text = str(err.value)
    assert "--truth-tolerance" in text and "in bands of" in text and "\n" not in text


def test_a_refusal_at_once_says_why_not_in_bands(variant, monkeypatch):
    from hzval.bake import maps as bake
    from hzval.core.errors import InputError
    from hzval.pipeline import sweep
    from hzval.scene.spec import load_material_height

    sc = _scene(np.zeros((64, 64), np.float32), "wrap")
    sc = dataclasses.replace(
        sc, material=dataclasses.replace(sc.material, height="bricks", size=64), effects=("shadow", "ambient")
    )
    height = load_material_height(sc.material).height
    monkeypatch.setattr(budget, "PEAK_TARGET_BYTES", 2**20)
    plan = memory.truth_plan(sc, height)
    assert plan.band_rows is None and "ambient" in plan.why_single
    monkeypatch.setattr(resources, "available_bytes", lambda: 2**20)
    monkeypatch.setattr(bake, "check_fits", lambda *a: None)
    with pytest.raises(InputError, match="--truth-tolerance.*not in bands: ambient"):
        memory.check_fits(sc, sweep.Options().bake_params(sc), height, plan)


def test_bands_of_a_soft_light_and_a_magnified_image_are_the_single_mesh(variant, bricks):
    from hzval.truth.plane import Truth

    h = bricks[:64, :64]
    sc = _scene(h, "open", kind="soft", radius=8.0, supersampling=2)  # 128 x 128 pixels
    one = Truth(sc, h)
    bands = Truth(sc, h, mesh_band_rows=16, band_samples=8 * 128 * 4)
    assert len(bands.mesh_bands) == 8
    up, down = truth_bands.reach(sc, bands.relief, bands.lift, AZIMUTHS)
    assert up == down and up > 2 * truth_bands.PAD_TEXELS  # a soft light's directions: the whole run
    for az in (90.0, -60.0, 180.0):
        a, b = one.render(az), bands.render(az)
        np.testing.assert_array_equal(a.layers["visibility"], b.layers["visibility"])
        np.testing.assert_array_equal(a.image, b.image)


def test_a_truth_in_bands_lit_from_a_higher_elevation_traces_that_elevation(variant, bricks):
    """A sweep over several elevations builds one truth at the lowest and lights it from each in turn
    (``Truth.light_at``); in bands, whose shadow rays are traced for every light at once, the higher
    elevation must be traced anew: its V is a truth's built for it, not the lowest's."""
    from hzval.truth.plane import Truth

    h = bricks[:64, :64].copy()
    low = _scene(h, "wrap", elevation=15.0)
    high = dataclasses.replace(low, light=low.light.at(55.0))
    moved = Truth(low, h, mesh_band_rows=16, band_samples=8 * 64 * 4)
    moved.light_at(55.0)
    own = Truth(high, h, mesh_band_rows=16, band_samples=8 * 64 * 4)
    for az in (0.0, 135.0):
        a, b = moved.render(az).layers["visibility"], own.render(az).layers["visibility"]
        assert np.mean(np.abs(a - b)) < 1e-3, az
        assert a.mean() > Truth(low, h).render(az).layers["visibility"].mean() + 0.05  # 55 lights more
