"""Tangent frames (hzval.geometry.tangents): FGED2's CalculateTangents on analytic meshes, the invariances
a frame must have (rotation, mirroring), and tangent space <-> world."""

import numpy as np
import pytest

from hzval.geometry import model
from hzval.geometry import tangents as tg


def _rotation(seed=0):
    q, _ = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    return q * np.sign(np.linalg.det(q))


def test_plane_frame_is_x_y_z():
    m = model.plane()
    np.testing.assert_allclose(m.tangents, np.tile([1.0, 0, 0, 1], (4, 1)), atol=1e-15)
    np.testing.assert_allclose(m.normals, np.tile([0.0, 0, 1], (4, 1)), atol=1e-15)
    t, b, n = tg.orthonormal(m.normals, m.tangents[:, :3], m.tangents[:, 3])
    np.testing.assert_allclose(b, np.tile([0.0, 1, 0], (4, 1)), atol=1e-15)


def test_affine_uv_map_gives_its_derivatives():
    """P = A (u, v): dP/du is A's first column, rejected from the normal; w from dP/dv's side."""
    a = np.array([[2.0, 0.7], [0.3, 1.5], [0.0, 0.0]])
    uv = np.random.default_rng(1).random((5, 2))
    p = uv @ a.T
    f = np.array([[0, 1, 2], [1, 3, 2], [2, 3, 4]])

    def d(tri):
        return np.linalg.det(uv[tri[1:]] - uv[tri[0]])

    f = np.array([tri if d(tri) > 0 else tri[::-1] for tri in f])
    t = tg.compute(p, np.tile([0.0, 0, 1], (5, 1)), uv, f)
    np.testing.assert_allclose(t[:, :3], np.tile(a[:, 0] / np.linalg.norm(a[:, 0]), (5, 1)), atol=1e-12)
    np.testing.assert_array_equal(t[:, 3], 1.0)
    flipped = tg.compute(p * [1, -1, 1], np.tile([0.0, 0, 1], (5, 1)), uv, f)  # dP/dv now on the -b side
    np.testing.assert_array_equal(flipped[:, 3], -1.0)


@pytest.mark.parametrize("name", ["+x", "-x", "+y", "-y", "+z", "-z"])
def test_cube_faces_frames_follow_the_unwrap(name):
    m = model.cube()
    k = [f[0] for f in model.CUBE_FACES].index(name)
    _, normal, u_axis, v_axis = model.CUBE_FACES[k]
    rows = slice(4 * k, 4 * k + 4)
    t = m.tangents[rows]
    np.testing.assert_allclose(t[:, :3], np.tile(u_axis, (4, 1)), atol=1e-12)
    b = t[:, 3:] * np.cross(m.normals[rows], t[:, :3])
    np.testing.assert_allclose(b, np.tile(v_axis, (4, 1)), atol=1e-12)
    np.testing.assert_array_equal(t[:, 3], -1.0 if name in ("-x", "-z") else 1.0)


def test_rotating_the_mesh_rotates_its_frames():
    s = model.sphere(segments=16, rings=8)
    r = _rotation(3)
    t = tg.compute(s.positions @ r.T, s.normals @ r.T, s.uvs, s.faces)
    np.testing.assert_allclose(t[:, :3], s.tangents[:, :3] @ r.T, atol=1e-12)
    np.testing.assert_array_equal(t[:, 3], s.tangents[:, 3])
    np.testing.assert_allclose(tg.rotate(s.tangents, r), t, atol=1e-12)


def test_mirroring_u_flips_w_and_the_tangent():
    s = model.torus(segments=12, sides=8)
    uv = s.uvs * [-1, 1] + [1, 0]
    t = tg.compute(s.positions, s.normals, uv, s.faces)
    np.testing.assert_allclose(t[:, :3], -s.tangents[:, :3], atol=1e-12)
    np.testing.assert_array_equal(t[:, 3], -s.tangents[:, 3])
    # the bitangent, along +v, is the same vector
    np.testing.assert_allclose(
        t[:, 3:] * np.cross(s.normals, t[:, :3]),
        s.tangents[:, 3:] * np.cross(s.normals, s.tangents[:, :3]),
        atol=1e-12,
    )


def test_to_world_and_back():
    rng = np.random.default_rng(4)
    n, t, w = rng.normal(size=(50, 3)), rng.normal(size=(50, 3)), rng.choice([-1.0, 1.0], 50)
    v = rng.normal(size=(50, 3))
    back = tg.to_tangent(tg.to_world(v, n, t, w), n, t, w)
    np.testing.assert_allclose(back, v, atol=1e-12)
    tt, b, nn = tg.orthonormal(n, t, w)
    np.testing.assert_allclose(tg.to_world(np.tile([0.0, 0, 1], (50, 1)), n, t, w), nn, atol=1e-12)
    np.testing.assert_allclose(np.sum(tt * nn, -1), 0, atol=1e-12)
    np.testing.assert_allclose(np.cross(nn, tt) * w[:, None], b, atol=1e-12)


def test_to_world_on_drjit_matches_numpy(variant):
    from hzval.core.backend import mi

    n, t, v = np.array([[0.1, 0.2, 1.0]]), np.array([[1.0, 0.3, 0.0]]), np.array([[0.3, -0.5, 0.8]])
    got = tg.to_world(mi.Vector3f(v.T), mi.Vector3f(n.T), mi.Vector3f(t.T), mi.Float(-1.0))
    np.testing.assert_allclose(
        np.array(got).reshape(3, -1).T, tg.to_world(v, n, t, np.array([-1.0])), atol=1e-6
    )


def test_face_frames_of_the_flat_cube_are_its_vertex_frames():
    c = model.cube()
    f = tg.frames(c, "face")
    np.testing.assert_allclose(f.tangent, c.tangents[c.faces[:, 0]], atol=1e-12)
    np.testing.assert_allclose(f.normal, c.normals[c.faces[:, 0]], atol=1e-12)
    assert tg.frames(c).per == "vertex"
    with pytest.raises(ValueError):
        tg.frames(c, "corner")


def test_file_tangents_are_orthonormalised_and_signed():
    n = np.tile([0.0, 0, 1], (2, 1))
    t = tg.from_file([[2.0, 0, 0.5, -0.3], [0.0, 1, 0, 1]], n)
    np.testing.assert_allclose(t, [[1, 0, 0, -1], [0, 1, 0, 1]], atol=1e-12)
    with pytest.raises(ValueError, match="along the normal"):
        tg.from_file([[0.0, 0, 1, 1], [0.0, 1, 0, 1]], n)
