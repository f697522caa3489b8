"""The displaced surface on a base mesh (hzval.geometry.displace, hzval.geometry.cells): the cut covers
every base
triangle once and keeps every piece inside one cell between texel centres, is watertight across UV
seams on closed shapes, reproduces the plane's heights at texel centres and the plane's own
tessellation (a fan of four about each cell's centre), and turns with the UVs."""

import numpy as np
import pytest
from scipy.spatial import Delaunay

from hzval.core import budget
from hzval.geometry import displace as dp
from hzval.geometry import model


def edge_counts(weld, faces):
    f = weld[faces]
    e = np.sort(np.stack([f, np.roll(f, -1, 1)], -1).reshape(-1, 2), 1)
    return np.unique(e, axis=0, return_counts=True)[1]


def uv_area(uv, faces):
    t = uv[faces]
    d1, d2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    return 0.5 * (d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1])


def scattered_plane(seed=0, points=40):
    """A unit quad cut into triangles of very different sizes (Delaunay of random points), UVs = xy:
    many base edges cross the cells, at every angle."""
    rng = np.random.default_rng(seed)
    xy = np.concatenate([[[0, 0], [1, 0], [1, 1], [0, 1]], rng.random((points, 2)) ** 3])
    tri = Delaunay(xy).simplices
    a = uv_area(xy, tri)
    tri[a < 0] = tri[a < 0][:, ::-1]
    p = np.concatenate([xy, np.zeros((len(xy), 1))], 1)
    return model.build("scattered", p, xy, tri, normals=np.tile([0.0, 0, 1], (len(xy), 1)))


@pytest.mark.parametrize("mesh", ["scattered", "cylinder", "cube", "sphere"])
def test_refinement_covers_each_base_triangle_once_cell_by_cell(mesh):
    base = scattered_plane() if mesh == "scattered" else model.load(mesh)
    r = dp.refine(base, (24, 24))
    a = uv_area(r.uvs, r.faces) * np.sign(base.uv_areas[r.base_face])
    assert a.min() > -1e-12  # nothing folds over
    total = np.bincount(r.base_face, a, minlength=len(base.faces))
    np.testing.assert_allclose(total, np.abs(base.uv_areas), rtol=1e-9, atol=1e-15)
    # every triangle inside one cell between texel centres: the bilinear surface's creases are edges
    uv = r.uvs[r.faces] * 24 - 0.5
    cell = np.floor(uv.mean(axis=1))
    assert np.all(uv >= cell[:, None, :] - 1e-9) and np.all(uv <= cell[:, None, :] + 1 + 1e-9)


def test_open_mesh_is_watertight_inside():
    base = scattered_plane(1)
    r = dp.refine(base, (32, 32), "open")
    c = edge_counts(r.weld, r.faces)
    assert set(np.unique(c)) == {1, 2}
    # the only open edges are on the quad's four sides
    f = r.weld[r.faces]
    e = np.sort(np.stack([f, np.roll(f, -1, 1)], -1).reshape(-1, 2), 1)
    keys, counts = np.unique(e, axis=0, return_counts=True)
    first = np.zeros(r.weld.max() + 1, np.int64)
    first[r.weld] = np.arange(len(r.weld))
    ends = r.positions[first[keys[counts == 1]]][..., :2]  # (E, 2, 2)
    on_side = np.any(np.all((np.abs(ends) < 1e-12) | (np.abs(ends - 1) < 1e-12), axis=1), axis=-1)
    assert on_side.all()


def test_plane_is_the_planes_tessellation():
    """The unit quad at one ring: a fan of four about every cell's centre inside the image, and of
    four about the centre of each border piece (half a cell, a quarter at the corners); the cells
    on the quad's own diagonal (its two base triangles meet there) in two fans of three."""
    n = 8
    r = dp.refine(model.plane(), (n, n), "open")
    centres = (np.arange(n - 1) + 1.0) / n  # inner cells' centres: texel corners
    key = {(round(a * 2 * n), round(b * 2 * n)) for a, b in r.positions[:, :2]}
    assert all((round(a * 2 * n), round(b * 2 * n)) in key for a in centres for b in centres)
    inner, border, corners, diagonal = (n - 1) ** 2, 4 * (n - 1), 4, n + 1
    assert len(r.faces) == 4 * (inner + border + corners) + 2 * diagonal


@pytest.mark.parametrize("name", ["cube", "sphere", "cylinder", "torus", "mirrored-sphere"])
def test_closed_shapes_stay_closed(name):
    base = model.load(name)
    r = dp.refine(base, (16, 16))
    assert np.all(edge_counts(r.weld, r.faces) == 2)
    # each position has one weld id and each weld id one position
    assert len(np.unique(r.positions, axis=0)) == r.weld.max() + 1
    h = np.random.default_rng(2).random((16, 16)).astype(np.float32)
    p, f = dp.displace(r, h, 0.1, base.world_per_uv, "wrap")
    assert len(np.unique(p, axis=0)) == r.weld.max() + 1  # the seams' sides share their positions
    v = p.astype(np.float64)[f]
    volume = np.sum(np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2]))) / 6
    b = base.positions[base.faces]
    assert volume > np.sum(np.einsum("ij,ij->i", b[:, 0], np.cross(b[:, 1], b[:, 2]))) / 6


def test_displaced_cube_has_no_crack():
    base = model.cube()
    r = dp.refine(base, (8, 8))
    p, f = dp.displace(r, np.ones((8, 8), np.float32), 0.25, base.world_per_uv, "open")
    # welded vertices on the cube's edges share one point: the mean normal's direction
    seam = np.flatnonzero(np.bincount(r.weld)[r.weld] > 1)
    for w in np.unique(r.weld[seam])[:50]:
        assert len(np.unique(p[r.weld == w], axis=0)) == 1
    assert np.all(edge_counts(r.weld, f) == 2)
    # miter: a constant height grows the cube into the cube of edge 1.5, faces flat to the edges
    np.testing.assert_allclose(np.abs(p).max(axis=1), 0.75, rtol=1e-6)
    corner = np.flatnonzero(np.all(np.isclose(r.positions, 0.5), axis=1))
    np.testing.assert_allclose(p[corner], 0.75, rtol=1e-6)
    # mean: the corner moves along the diagonal by the height, (0.5, 0.5, 0.5) + 0.25 (1, 1, 1) / sqrt(3)
    q, _ = dp.displace(r, np.ones((8, 8), np.float32), 0.25, base.world_per_uv, "open", weld="mean")
    np.testing.assert_allclose(q[corner], 0.5 + 0.25 / np.sqrt(3), rtol=1e-6)
    face = np.flatnonzero(np.isin(r.weld, np.flatnonzero(np.bincount(r.weld) == 1)))
    np.testing.assert_allclose(np.abs(q[face]).max(axis=1), 0.75, rtol=1e-6)  # inside a face, both alike


@pytest.mark.parametrize("shape", [(16, 16), (8, 16)])
def test_plane_heights_at_texel_centres(shape):
    rows, cols = shape
    h = np.random.default_rng(3).random(shape).astype(np.float32)
    base = model.plane()
    r = dp.refine(base, shape)
    p, _ = dp.displace(r, h, 0.05, base.world_per_uv, "wrap")
    x = (np.arange(cols) + 0.5) / cols
    y = 1 - (np.arange(rows) + 0.5) / rows
    key = {(round(a * 4 * cols), round(b * 4 * rows)): i for i, (a, b) in enumerate(r.positions[:, :2])}
    idx = np.array([[key[(round(a * 4 * cols), round(b * 4 * rows))] for a in x] for b in y])
    np.testing.assert_allclose(p[idx, 2], h * 0.05, atol=1e-8)
    np.testing.assert_array_equal(p[:, :2], r.positions[:, :2].astype(np.float32))


@pytest.mark.parametrize("turn", ["mirror_u", "rotate_90"])
@pytest.mark.parametrize("boundary", ["wrap", "open"])
def test_surface_turns_with_the_uvs(turn, boundary):
    """A quad whose UVs are mirrored or turned, carrying the image mirrored or turned back, is the
    same surface (the issue's three quads)."""
    h = np.random.default_rng(4).random((12, 12)).astype(np.float32)
    a = model.plane()
    if turn == "mirror_u":
        uv, hb = a.positions[:, :2] * [-1, 1] + [1, 0], h[:, ::-1]
    else:
        uv, hb = np.stack([a.positions[:, 1], 1 - a.positions[:, 0]], -1), np.rot90(h, -1)
    b = model.build("turned", a.positions, uv, a.faces, normals=a.normals)
    pa, _ = dp.displace(dp.refine(a, h.shape), h, 0.1, 1.0, boundary)
    pb, _ = dp.displace(dp.refine(b, hb.shape), hb, 0.1, 1.0, boundary)
    sa, sb = pa[np.lexsort(pa[:, :2].T)], pb[np.lexsort(pb[:, :2].T)]
    np.testing.assert_allclose(sa, sb, atol=2e-7)


def test_refined_frames_keep_handedness_and_are_orthonormal():
    base = model.cube()
    r = dp.refine(base, (6, 6))
    np.testing.assert_allclose(np.sum(r.normals * r.tangents[:, :3], -1), 0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(r.tangents[:, :3], axis=-1), 1, atol=1e-12)
    np.testing.assert_array_equal(r.tangents[r.faces, 3].min(1), r.tangents[r.faces, 3].max(1))
    np.testing.assert_array_equal(r.tangents[r.faces[:, 0], 3], base.tangents[base.faces[r.base_face, 0], 3])


def test_estimate_bounds_the_refinement():
    for base in (model.sphere(), scattered_plane(5), model.cube()):
        tris, size = dp.estimate(base, (64, 64))
        r = dp.refine(base, (64, 64))
        assert 0.8 * tris <= len(r.faces) <= 1.25 * tris
        assert size == tris * budget.REFINE_BYTES_PER_TRIANGLE


def test_twisted_cells_get_rings_within_the_tolerance():
    """A checkerboard of heights twists every cell by 4 texels: the fans are cut into rings until
    |d| / (16 n^2) <= tolerance, and a planar map (a ramp) gets none."""
    n = 8
    checker = (np.indices((n, n)).sum(0) % 2).astype(np.float32)
    ramp = np.tile(np.arange(n, dtype=np.float32) / n, (n, 1))
    one = dp.refine(model.plane(), (n, n), "wrap")
    flat = dp.refine(model.plane(), (n, n), "wrap", height=ramp, depth=1.0, tolerance=0.04)
    assert len(flat.faces) == len(one.faces)
    fine = dp.refine(model.plane(), (n, n), "wrap", height=checker, depth=1.0 / 2, tolerance=0.04)
    # heights 0 or 4 texels (depth 1/2 of 8): |d| = 8, sqrt(8 / (16 0.04)) = 3.5, so n = 4 rings,
    # 2n - 1 = 7 triangles a fan's edge
    assert len(fine.faces) == 7 * len(one.faces)


def test_sample_height_between_texel_centres():
    h = np.arange(12, dtype=np.float32).reshape(3, 4)
    uv = np.array([[0.5 / 4, 1 - 0.5 / 3], [1.5 / 4, 1 - 2.5 / 3], [1.0 / 4, 1 - 1.0 / 3], [0.0, 0.5]])
    np.testing.assert_allclose(dp.sample_height(h, uv, "open")[:3], [0, 9, 2.5])
    assert dp.sample_height(h, uv[3:], "wrap")[0] == pytest.approx(0.5 * (4 + 7))  # wraps to col 3
    assert dp.sample_height(h, uv[3:], "open")[0] == pytest.approx(4.0)  # clamps to col 0


def test_shading_normals_on_the_plane_are_the_normal_map():
    from hzval.bake.maps import normal_map

    h = np.random.default_rng(6).random((8, 8)).astype(np.float32)
    nmap = normal_map(h * 0.05 * 8, "wrap")
    base = model.plane()
    r = dp.refine(base, h.shape)
    n = dp.shading_normals(r, nmap, "wrap")
    x = (np.arange(8) + 0.5) / 8
    key = {(round(a * 32), round(b * 32)): i for i, (a, b) in enumerate(r.positions[:, :2])}
    idx = np.array([[key[(round(a * 32), round(b * 32))] for a in x] for b in x[::-1]])
    np.testing.assert_allclose(n[idx], nmap / np.linalg.norm(nmap, axis=-1, keepdims=True), atol=1e-6)


def test_shading_normals_follow_the_mirrored_frame():
    """On the cube's mirrored face -x the map's +x (toward +u) points along the face's +u axis."""
    base = model.cube()
    r = dp.refine(base, (4, 4))
    tilted = np.broadcast_to(np.array([0.6, 0.0, 0.8]), (4, 4, 3))
    n = dp.shading_normals(r, tilted, "wrap")
    for k, (name, normal, u_axis, _) in enumerate(model.CUBE_FACES):
        on = np.isin(r.base_face, [2 * k, 2 * k + 1])
        v = np.unique(r.faces[on])
        inner = v[np.abs(r.positions[v] @ np.array(normal, float) - 0.5) < 1e-9]
        inner = inner[
            np.all(np.abs(r.positions[inner] @ np.abs(np.array([u_axis, _], float)).T) < 0.49, axis=1)
        ]
        assert len(inner) >= 9
        np.testing.assert_allclose(
            n[inner],
            np.tile(0.6 * np.array(u_axis) + 0.8 * np.array(normal), (len(inner), 1)),
            atol=1e-6,
            err_msg=name,
        )


def test_long_thin_triangles_are_cut_cell_by_cell():
    """A cylinder of one stack has 16 x 1 long thin triangles on its side: the cut covers the base,
    stays closed along its seam (open at the rims) and every vertex's frame is the base triangle's
    own interpolation at that point."""
    base = model.cylinder(stacks=1, caps=False, segments=16)
    tex = (64, 64)
    r = dp.refine(base, tex)
    a = uv_area(r.uvs, r.faces) * np.sign(base.uv_areas[r.base_face])
    assert a.min() > -1e-15
    np.testing.assert_allclose(np.bincount(r.base_face, a), np.abs(base.uv_areas), rtol=1e-9)
    assert set(np.unique(edge_counts(r.weld, r.faces))) == {1, 2}
    f = base.faces[r.base_face]
    v = r.faces[:, 0]
    t = base.uvs[f]
    m = np.stack([t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]], -1)
    l12 = np.linalg.solve(m, (r.uvs[v] - t[:, 0])[..., None])[..., 0]
    bary = np.concatenate([1 - l12.sum(1, keepdims=True), l12], 1)
    n = np.einsum("kc,kcd->kd", bary, base.normals[f])
    np.testing.assert_allclose(r.normals[v], n / np.linalg.norm(n, axis=1, keepdims=True), atol=1e-9)
