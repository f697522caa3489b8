"""hzval.truth.common: the plane's and the model's truths share one interface and one albedo lookup."""

from __future__ import annotations

import numpy as np

from hzval.geometry import model
from hzval.truth import common
from tests.helpers import material_height, model_case_scene


def test_both_truths_implement_the_interface(variant):
    from hzval.truth.model import ModelTruth
    from hzval.truth.plane import Truth

    plane = model_case_scene(n=16, effects="shadow,diffuse")
    assert isinstance(Truth(plane, material_height(plane)), common.TruthLike)
    cube = model_case_scene(n=16, mesh="cube", camera="perspective", view_elevation=35, view_azimuth=-30)
    assert isinstance(ModelTruth(cube, material_height(cube), model.load("cube")), common.TruthLike)
    assert not isinstance(object(), common.TruthLike)


def test_the_albedo_is_the_nearest_texel_with_y_up_the_image(variant):
    """Against NumPy: the texel of column floor(x) and row rows - ceil(y), clipped to the map, at
    random points, on the texels' edges and off the map."""
    import drjit as dr
    import mitsuba as mi

    rows, cols = 5, 7
    rng = np.random.default_rng(1)
    a = rng.random((rows, cols, 3), dtype=np.float32)
    scene = model_case_scene(n=16, effects="shadow,diffuse")
    texels = common.albedo_texels(scene, rows, cols, a)
    x = np.concatenate([rng.uniform(-1, cols + 1, 200), np.arange(cols + 1.0), [0.0, cols]])
    y = np.concatenate([rng.uniform(-1, rows + 1, 200), np.zeros(cols + 1), [rows, 0.0]])
    x, y = x.astype(np.float32), y.astype(np.float32)
    size = (dr.opaque(mi.Float, float(rows)), dr.opaque(mi.Float, float(cols)))
    got = np.array(common.albedo_at(texels, *size, mi.Float(x), mi.Float(y))).reshape(3, -1).T
    col = np.clip(np.floor(x).astype(int), 0, cols - 1)
    row = np.clip((rows - np.ceil(y)).astype(int), 0, rows - 1)
    np.testing.assert_array_equal(got, a[row, col])


def test_no_albedo_where_no_effect_reads_it():
    scene = model_case_scene(n=16, effects="shadow")
    assert common.albedo_texels(scene, 4, 4) is None
