"""The displaced mesh: geometry, margin, UVs and orientation against known answers."""

import math

import numpy as np
import pytest

from hzval.geometry import tile as mesh


def ray_down(scene, x, y):
    import mitsuba as mi

    si = scene.ray_intersect(mi.Ray3f(mi.Point3f(x, y, 1e4), mi.Vector3f(0, 0, -1)))
    return si


def scene_of(mesh):
    import mitsuba as mi

    return mi.load_dict({"type": "scene", "surface": mesh})


def test_vertices_sit_on_texel_centres_at_their_height(variant):
    rng = np.random.default_rng(0)
    h = rng.random((6, 9)).astype(np.float32)
    scene = scene_of(mesh.displaced_mesh(h, 0.5, "open"))
    rows, cols = h.shape
    for row, col in [(0, 0), (2, 5), (5, 8)]:
        si = ray_down(scene, col + 0.5, rows - row - 0.5)
        assert si.p.z[0] == pytest.approx(h[row, col] * 0.5 * cols, abs=1e-4)
        u, v = si.uv.x[0], si.uv.y[0]
        assert (u, v) == pytest.approx(((col + 0.5) / cols, (row + 0.5) / rows), abs=1e-5)


def test_open_mesh_covers_exactly_the_image(variant):
    h = np.zeros((5, 7), np.float32)
    m = mesh.displaced_mesh(h, 0.1, "open")
    bb = m.bbox()
    assert [bb.min.x, bb.min.y, bb.max.x, bb.max.y] == pytest.approx([0, 0, 7, 5])


def test_wrap_margin_holds_the_longest_shadow():
    h = np.zeros((10, 10), np.float32)
    h[0, 0] = 5.0
    m = mesh.wrap_margin(h, 10.0)
    assert m == math.ceil(5.0 / math.tan(math.radians(10))) + 1
    g = mesh.grid(h, "wrap", min_elevation_deg=10.0)
    assert g.z.shape == (10 + 2 * m, 10 + 2 * m)
    # the margin repeats the tile
    assert g.z[m, m] == 5.0 and g.z[m + 10, m + 10] == 5.0 and g.z[m - 10, m] == 5.0


def test_wrap_mesh_shows_the_neighbouring_tile(variant):
    h = np.zeros((4, 6), np.float32)
    h[1, 2] = 1.0
    scene = scene_of(mesh.displaced_mesh(h, 0.5, "wrap", margin=8))
    # the peak of the tile to the left: 6 texels to the left of (row 1, col 2)
    si = ray_down(scene, 2.5 - 6, 4 - 1 - 0.5)
    assert si.p.z[0] == pytest.approx(3.0, abs=1e-5)


def test_triangles_face_up():
    f = mesh.triangles(3, 4)
    assert f.shape == (2 * 2 * 3, 3)
    xs, ys = np.meshgrid(np.arange(4.0), -np.arange(3.0))  # row index grows toward -y
    p = np.stack([xs.ravel(), ys.ravel()], -1)
    a, b, c = p[f[:, 0]], p[f[:, 1]], p[f[:, 2]]
    cross = (b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0]
    assert (cross > 0).all()


def test_vertex_normals_match_the_normal_map(variant):
    from hzval.bake import maps as bake
    from hzval.core import conventions as cv

    h = np.tile(np.arange(8, dtype=np.float32) / 8, (5, 1))
    m = mesh.displaced_mesh(h, 0.25, "wrap", margin=2, normals=True)
    scene = scene_of(m)
    si = ray_down(scene, 3.5, 2.5)  # texel centre (row 2, col 3) is a vertex
    n_map = bake.normal_map(cv.heights_in_texels(h, 0.25), "wrap")[2, 3]
    assert [si.sh_frame.n.x[0], si.sh_frame.n.y[0], si.sh_frame.n.z[0]] == pytest.approx(n_map, abs=1e-4)
