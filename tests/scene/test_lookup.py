"""The techniques with a tangent frame per sample (hzval.scene.lookup.Samples.frames), as on a model.

Two invariances pin the per-sample path down without a model: where every
sample's frame is the world's, the horizon map, the ray march and the plain
shading render what they render on the plane; and where every frame is the
world's turned about its normal by an angle, a light turned the other way
by that angle gives the plane's answer for the light itself, so the frame,
not the world, decides what a sample sees. The base mesh's shadow multiplies
every technique's factor, and only the factor.
"""

import math

import numpy as np
import pytest

from hzval.bake.maps import BakeParams, bake
from hzval.scene import lookup
from hzval.scene import spec as sc
from hzval.techniques import registry as technique
from hzval.techniques import surface


def _scene(n=24, effects="shadow,diffuse", spp=2):
    return sc.override(sc.Scene(), size=n, depth=0.15, spp=spp, azimuths="0", effects=effects)


def _contexts(scene, turn_deg=0.0, macro=None):
    """The plane's context, and one whose samples carry frames turned by ``turn_deg`` about +z."""
    hm = sc.load_material_height(scene.material)
    rows, cols = hm.height.shape
    b = bake(hm.height, BakeParams(depth=scene.material.depth, boundary=scene.material.boundary))
    albedo = sc.load_albedo(scene.material, rows, cols)
    plane = technique.Context(scene, hm.height, b, albedo)
    own = plane.samples()
    c, s = math.cos(math.radians(turn_deg)), math.sin(math.radians(turn_deg))
    frame = np.array([c, s, 0.0, -s, c, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0], np.float32)
    frames = np.broadcast_to(frame, (own.x.size, lookup.FRAME_FLOATS)).copy()
    framed = lookup.Samples(own.x, own.y, own.rows, own.cols, own.spp, frames=frames, macro=macro)
    return plane, technique.Context(scene, hm.height, b, albedo, points=framed)


@pytest.mark.parametrize("name", ["horizon", "pom"])
def test_world_frames_render_the_plane(variant, name):
    plane, framed = _contexts(_scene())
    T = technique.get(name)
    a, b = T.build(plane), T.build(framed)
    for az in (0.0, 70.0, 200.0):
        fa, fb = a.render(az), b.render(az)
        np.testing.assert_allclose(fb.layers["factor"], fa.layers["factor"], atol=1e-5)
        np.testing.assert_allclose(fb.image, fa.image, atol=1e-5)


def test_world_frames_shade_as_the_plane(variant):
    plane, framed = _contexts(_scene(effects="shadow,diffuse,ambient"))
    pa, pb = surface.unshadowed(plane), surface.unshadowed(framed)
    np.testing.assert_allclose(pb.ambient_image, pa.ambient_image, atol=1e-6)
    for az in (0.0, 135.0):
        np.testing.assert_allclose(pb.render(az)[0].image, pa.render(az)[0].image, atol=1e-5)


@pytest.mark.parametrize("name", ["horizon", "pom"])
def test_a_turned_frame_sees_the_light_turned_back(variant, name):
    """Frames turned by +40 degrees about the normal (t at azimuth 40): the world's light at azimuth
    a + 40 is at a in every frame, so the framed render of a + 40 is the plane's render of a."""
    plane, framed = _contexts(_scene(), turn_deg=40.0)
    T = technique.get(name)
    a, b = T.build(plane), T.build(framed)
    for az in (0.0, 110.0):
        np.testing.assert_allclose(
            b.render(az + 40.0).layers["factor"], a.render(az).layers["factor"], atol=2e-4
        )


@pytest.mark.parametrize("name", ["horizon", "pom"])
def test_the_base_meshs_shadow_multiplies_the_factor(variant, name):
    """``macro``: the left half of the image in the base mesh's shadow. There the factor and the
    direct light are 0; elsewhere everything is the plane's."""
    scene = _scene(spp=1)
    n = scene.material.size
    dark = np.ones((n, n), np.float32)
    dark[:, : n // 2] = 0.0

    def macro(direction):
        from hzval.core.backend import mi

        return mi.Float(dark.ravel())

    plane, framed = _contexts(scene, macro=macro)
    T = technique.get(name)
    a, b = T.build(plane), T.build(framed)
    fa, fb = a.render(30.0), b.render(30.0)
    np.testing.assert_allclose(fb.layers["factor"], fa.layers["factor"] * dark, atol=1e-5)
    lit = dark > 0
    np.testing.assert_allclose(fb.image[lit], fa.image[lit], atol=1e-5)
    assert np.all(fb.image[~lit] == 0.0)  # diffuse and shadow only: no ambient term
