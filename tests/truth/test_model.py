"""The truth on a model and the techniques on it (hzval.truth.model), against what must hold.

- A unit quad whose UVs are its (x, y) is the plane: its camera is the tile's, its techniques'
  factors the plane's pixel for pixel, its truth the plane's to the noise.
- The same surface on a quad mirrored in u (the photo mirrored back) or with its UVs turned 90
  degrees (the photo turned back) renders the same truth and the same factors, pixel by pixel:
  the tangent frames, not the world, carry the light into the texture's space.
- Where the light is seen, the truth's shading is the techniques' (at the truth's own hits).
- The displaced cube is closed: seen from above, no pixel over its top face sees through it.
- The base mesh's shadow (a torus under a low light) is the truth's shadow too.
"""

import numpy as np

from hzval.bake.maps import BakeParams, bake
from hzval.geometry import model
from hzval.scene import spec as sc
from hzval.techniques import registry as technique
from hzval.techniques import surface
from hzval.truth import plane as truth
from hzval.truth.model import ModelTruth
from tests.helpers import material_height, model_case_scene


def _context(scene, h, points):
    b = bake(h, BakeParams(depth=scene.material.depth, boundary=scene.material.boundary))
    rows, cols = h.shape
    return technique.Context(scene, h, b, sc.load_albedo(scene.material, rows, cols), points=points)


def _quad(uvs):
    """A unit quad at z = 0 with the corner UVs ``uvs`` of (0,0), (1,0), (1,1), (0,1)."""
    p = np.array([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], float)
    return model.build("quad", p, np.array(uvs, float), np.array([(0, 1, 2), (0, 2, 3)]))


QUADS = {
    "xy": ([(0, 0), (1, 0), (1, 1), (0, 1)], lambda a: a),
    "mirrored-u": ([(1, 0), (0, 0), (0, 1), (1, 1)], lambda a: a[:, ::-1]),
    "turned-90": ([(1, 0), (1, 1), (0, 1), (0, 0)], np.rot90),
}


def _render_quad(scene, h, name):
    uvs, turn = QUADS[name]
    hq = np.ascontiguousarray(turn(h))
    mt = ModelTruth(scene, hq, _quad(uvs))
    tech = technique.get("horizon").build(_context(scene, hq, mt.samples()))
    return mt, [(mt.render(az), tech.render(az)) for az in scene.light.azimuths_deg]


def test_quads_carrying_one_surface_agree_pixel_by_pixel(variant):
    scene = model_case_scene()
    h = material_height(scene)
    runs = {name: _render_quad(scene, h, name) for name in QUADS}
    mt0, frames0 = runs["xy"]
    seen = mt0.seen
    assert seen.mean() > 0.3
    for name, (mt, frames) in runs.items():
        np.testing.assert_array_equal(mt.seen, seen)
        for (t0, f0), (t, f) in zip(frames0, frames):
            F0, F = f0.layers["factor"][seen], f.layers["factor"][seen]
            assert np.abs(F - F0).mean() < 0.02, name
            V0, V = t0.layers["visibility"][seen], t.layers["visibility"][seen]
            assert abs(V.mean() - V0.mean()) < 0.01, name
            e0, e = np.abs(F0 - V0).mean(), np.abs(F - V).mean()
            assert abs(e - e0) <= 0.03 * e0 + 1e-3, name


def test_the_xy_quad_is_the_plane(variant):
    """The unit quad with UVs = (x, y), orthographic at 60 degrees: the camera frames it as the plane
    frames the tile, so the techniques' factors are the plane's pixel for pixel, and the truth's
    surface (cut along the texel grid, a fan about every cell's centre) is the plane's: the same
    mean V and |F - V| to the noise of the few samples that land differently."""
    scene = model_case_scene(n=64)
    h = material_height(scene)
    mt, frames = _render_quad(scene, h, "xy")
    plane = truth.Truth(scene, h)
    tech = technique.get("horizon").build(_context(scene, h, None))
    for az, (t, f) in zip(scene.light.azimuths_deg, frames):
        p = plane.render(az)
        m = mt.seen & (p.mask if p.mask is not None else True)
        assert m.mean() > 0.8
        Fp, F = tech.render(az).layers["factor"][m], f.layers["factor"][m]
        np.testing.assert_allclose(F, Fp, atol=1e-4)
        Vp, V = p.layers["visibility"][m], t.layers["visibility"][m]
        assert abs(V.mean() - Vp.mean()) < 0.002
        assert abs(np.abs(F - V).mean() - np.abs(Fp - Vp).mean()) <= 0.02 * np.abs(Fp - Vp).mean()


def test_lit_truth_is_the_unshadowed_shading_at_its_hits(variant):
    scene = model_case_scene(
        n=48,
        mesh="cube",
        camera="perspective",
        view_elevation=35,
        view_azimuth=-30,
        boundary="wrap",
        effects="shadow,diffuse",
    )
    h = material_height(scene)
    mt = ModelTruth(scene, h, model.load("cube"))
    plain = surface.unshadowed(_context(scene, h, mt.samples("truth")))
    for az in scene.light.azimuths_deg:
        t = mt.render(az)
        lit = mt.seen & (t.layers["visibility"] == 1.0)
        assert lit.mean() > 0.2
        diff = np.abs(t.image - plain.render(az)[0].image)[lit]
        assert diff.max() < 1e-4


def test_the_displaced_cube_is_closed(variant):
    """From straight above (orthographic, top), every pixel whose centre lies over the cube's top
    face sees the cube: a crack at a welded seam would let a camera ray through."""
    n = 64
    scene = model_case_scene(
        n=n,
        mesh="cube",
        camera="top",
        boundary="wrap",
        depth=0.1,
        view_elevation=None,
        view_azimuth=None,
        resolution=None,
    )
    mt = ModelTruth(scene, material_height(scene), model.load("cube"))
    v = mt.view
    c = (np.arange(n) + 0.5) / n * 2 - 1  # film coordinates of pixel centres
    half = v.film_size[0] / 2
    inside = np.abs(c * half) < 0.45  # the top face spans [-0.5, 0.5]
    over = inside[None, :] & inside[:, None]
    assert over.sum() > 0.3 * n * n
    assert mt.seen[over].all()


def test_the_base_meshs_shadow_is_the_truths(variant):
    """A torus under a low light shadows itself: the truth is dark where the base mesh is."""
    scene = model_case_scene(
        n=32,
        mesh="torus",
        camera="perspective",
        view_elevation=50,
        view_azimuth=-90,
        boundary="wrap",
        elevation=12,
        azimuths="0",
        resolution=(64, 64),
    )
    mt = ModelTruth(scene, material_height(scene), model.load("torus"))
    assert mt.macro_shadowed(0.0) > 0.02
    t = mt.render(0.0)
    L = scene.light.direction(0.0)
    M = np.asarray(mt.macro(L), np.float32).reshape(-1, scene.spp)
    V = t.layers["visibility"].ravel()
    dark = (M.mean(axis=1) == 0.0) & mt.seen.ravel()
    assert dark.sum() > 10
    assert V[dark].mean() < 0.1
