"""The base mesh (hzval.geometry.model): the built-in shapes' analytic properties, the readers' UV and
up-axis conventions, glTF TANGENT round trips, and bad files as one InputError naming the file."""

import math

import numpy as np
import pytest

from hzval.core.errors import InputError
from hzval.geometry import model
from tests.helpers import QUAD_F, QUAD_P, QUAD_UV, write_gltf, write_obj


def _edge_counts(mesh):
    return model.edge_table(mesh.faces, mesh.weld)[3]


# ------------------------------------------------------------------------------------------
# Shapes
# ------------------------------------------------------------------------------------------


def test_plane_is_todays_tile():
    m = model.load("plane")
    assert m.world_per_uv == 1.0
    assert m.record() == {
        "source": "plane",
        "triangles": 2,
        "world_per_uv": 1.0,
        "tangents": "computed",
        "tangent_method": "fged2",  # a built-in shape keeps the frames it was measured with
        "mirrored_fraction": 0.0,
        "seam_edges": 0,
    }
    np.testing.assert_array_equal(m.uvs, m.positions[:, :2])


def test_uv_scale_repeats_the_texture():
    m = model.load("plane", uv_scale=4)
    assert m.world_per_uv == pytest.approx(0.25)
    assert m.uvs.max() == 4


@pytest.mark.parametrize("radius", [0.5, 3.0])
def test_sphere_world_per_uv_is_its_analytic_area(radius):
    m = model.sphere(radius=radius, segments=256, rings=128)
    # the UV square less the poles' collapsed half cells; the area of the sphere itself
    uv_area = 1.0 - 1.0 / 128
    assert m.world_per_uv == pytest.approx(radius * math.sqrt(4 * math.pi / uv_area), rel=2e-4)
    centre, r = m.bounding_sphere()
    assert r == pytest.approx(radius) and np.allclose(centre, 0, atol=1e-12)


def test_cube_unwrap():
    c = model.cube()
    assert c.mirrored_fraction == pytest.approx(1 / 3)
    assert c.seam_edges == 12  # every edge of the cube joins two faces' different UVs
    assert c.world_per_uv == pytest.approx(1.0)
    assert c.bounding_sphere()[1] == pytest.approx(math.sqrt(3) / 2)
    # outward winding
    p = c.positions[c.faces]
    assert np.all(np.sum(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]) * c.normals[c.faces[:, 0]], -1) > 0)


@pytest.mark.parametrize("name", ["cube", "sphere", "cylinder", "torus", "mirrored-sphere"])
def test_closed_shapes_are_closed_and_outward(name):
    m = model.SHAPES[name]()
    assert np.all(_edge_counts(m) == 2)
    p = m.positions[m.faces]
    volume = np.sum(np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2]))) / 6
    assert volume > 0
    assert m.seam_edges > 0


def test_torus_radius_keywords():
    m = model.torus(major=2.0, minor=0.5, segments=128, sides=64)
    assert m.world_per_uv == pytest.approx(math.sqrt(4 * math.pi**2 * 2.0 * 0.5), rel=1e-3)


# ------------------------------------------------------------------------------------------
# Files
# ------------------------------------------------------------------------------------------


def test_obj_and_gltf_agree_on_uvs(tmp_path):
    uv = np.array([[0.1, 0.2], [0.9, 0.1], [0.8, 0.7], [0.2, 0.95]])
    a = model.load(write_obj(tmp_path / "q.obj", QUAD_P, uv, QUAD_F), up="z")
    b = model.load(write_gltf(tmp_path / "q.glb", QUAD_P, uv, QUAD_F), up="z")
    np.testing.assert_allclose(a.uvs, uv, atol=1e-12)
    np.testing.assert_allclose(b.uvs, uv, atol=1e-7)
    np.testing.assert_allclose(a.tangents, b.tangents, atol=1e-6)


def test_gltf_tangents_round_trip(tmp_path):
    n = np.tile([0.0, 0, 1], (4, 1))
    t = np.tile([0.0, 1, 0, -1], (4, 1))  # deliberately not the computed frame: the file's wins
    with_t = model.load(write_gltf(tmp_path / "t.gltf", QUAD_P, QUAD_UV, QUAD_F, n, t), up="z")
    assert with_t.tangent_source == "file" and with_t.record()["tangents"] == "file"
    np.testing.assert_allclose(with_t.tangents, t, atol=1e-7)
    assert with_t.mirrored_fraction == 1.0
    without = model.load(write_gltf(tmp_path / "n.glb", QUAD_P, QUAD_UV, QUAD_F, n), up="z")
    assert without.tangent_source == "computed"
    np.testing.assert_allclose(without.tangents, np.tile([1.0, 0, 0, 1], (4, 1)), atol=1e-7)


def test_y_up_file_turns_z_up(tmp_path):
    # the quad standing in the file's x-z floor, normal +y (up): in hzval's world it lies at z = 0
    p = QUAD_P[:, [0, 2, 1]] * [1, 1, -1]
    path = tmp_path / "y.obj"
    path.write_text(
        "\n".join(
            [f"v {x} {y} {z}" for x, y, z in p]
            + [f"vt {u} {v}" for u, v in QUAD_UV]
            + ["vn 0 1 0", "f 1/1/1 2/2/1 3/3/1", "f 1/1/1 3/3/1 4/4/1"]
        )
        + "\n"
    )
    m = model.load(str(path))
    assert m.up == "y"
    np.testing.assert_allclose(m.positions, QUAD_P, atol=1e-12)
    np.testing.assert_allclose(m.normals, np.tile([0.0, 0, 1], (4, 1)), atol=1e-12)
    np.testing.assert_allclose(m.tangents, np.tile([1.0, 0, 0, 1], (4, 1)), atol=1e-12)


def test_gltf_written_by_trimesh_reads_back(tmp_path):
    import trimesh
    from PIL import Image

    s = model.sphere(segments=12, rings=6)
    visual = trimesh.visual.TextureVisuals(uv=s.uvs, image=Image.new("RGB", (4, 4)))
    tm = trimesh.Trimesh(s.positions, s.faces, vertex_normals=s.normals, visual=visual, process=False)
    path = tmp_path / "s.glb"
    path.write_bytes(trimesh.exchange.gltf.export_glb(tm))
    m = model.load(str(path), up="z")
    assert len(m.faces) == len(s.faces)
    np.testing.assert_allclose(m.world_per_uv, s.world_per_uv, rtol=1e-6)
    np.testing.assert_allclose(m.uvs[m.faces], s.uvs[s.faces], atol=1e-6)


def test_ply_with_uvs(tmp_path):
    import trimesh

    c = model.cube()
    tm = trimesh.Trimesh(c.positions, c.faces, visual=trimesh.visual.TextureVisuals(uv=c.uvs), process=False)
    path = tmp_path / "c.ply"
    tm.export(str(path))
    m = model.load(str(path), up="z")
    assert m.mirrored_fraction == pytest.approx(1 / 3)
    assert m.seam_edges == 12


# ------------------------------------------------------------------------------------------
# Bad meshes
# ------------------------------------------------------------------------------------------


def _refused(path, match, **kw):
    with pytest.raises(InputError, match=match) as e:
        model.load(str(path), **kw)
    assert str(path) in str(e.value) and "\n" not in str(e.value)


def test_bad_meshes_name_the_file(tmp_path):
    (tmp_path / "nouv.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    _refused(tmp_path / "nouv.obj", "no texture coordinates")
    (tmp_path / "empty.obj").write_text("# nothing\n")
    _refused(tmp_path / "empty.obj", "empty")
    _refused(write_obj(tmp_path / "nan.obj", QUAD_P * [1, np.nan, 1], QUAD_UV, QUAD_F), "NaN")
    _refused(write_obj(tmp_path / "flat.obj", QUAD_P, np.zeros((4, 2)) + 0.5, QUAD_F), "zero area")
    half = QUAD_UV.copy()
    half[3] = half[2]  # the second triangle's UVs collapse to a segment
    _refused(write_obj(tmp_path / "deg.obj", QUAD_P, half, QUAD_F), "1 of 2 triangles have degenerate")
    fan = np.array([[0.0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -1, 0], [0.5, 0, 1]])
    _refused(
        write_obj(
            tmp_path / "fin.obj",
            fan,
            fan[:, :2] * 0.3 + 0.4 + fan[:, 2:] * 0.1,
            [[0, 1, 2], [1, 0, 3], [0, 1, 4]],
        ),
        "non-manifold",
    )
    _refused(tmp_path / "x.stl", "unknown mesh format")
    _refused(tmp_path / "missing.glb", "no such file")
    (tmp_path / "junk.glb").write_bytes(b"not a glb at all")
    _refused(tmp_path / "junk.glb", "cannot be read")
    _refused(
        write_gltf(
            tmp_path / "badt.glb",
            QUAD_P,
            QUAD_UV,
            QUAD_F,
            np.tile([0.0, 0, 1], (4, 1)),
            np.tile([0.0, 0, 1, 1], (4, 1)),
        ),
        "TANGENT",
    )


def test_gltf_without_its_buffer_or_with_compression(tmp_path):
    import json

    path = write_gltf(tmp_path / "q.gltf", QUAD_P, QUAD_UV, QUAD_F)
    doc = json.loads((tmp_path / "q.gltf").read_text())
    (tmp_path / "q.bin").unlink(missing_ok=True)
    for b in doc["buffers"]:
        b["uri"] = "gone.bin"
    (tmp_path / "q.gltf").write_text(json.dumps(doc))
    _refused(path, "buffer data is missing")
    doc["extensionsRequired"] = ["KHR_draco_mesh_compression"]
    (tmp_path / "q.gltf").write_text(json.dumps(doc))
    _refused(path, "KHR_draco_mesh_compression")


def test_unknown_shape_and_flags():
    with pytest.raises(InputError, match="did you mean cube") as e:
        model.load("cubes")
    assert e.value.what == "--mesh"
    with pytest.raises(InputError, match="--uv-scale"):
        model.load("plane", uv_scale=0)
    with pytest.raises(InputError, match="--up"):
        model.load("plane", up="x")


def test_shape_arguments():
    assert model.load("sphere", shape_args={"radius": 2.0}).bounding_sphere()[1] == pytest.approx(2.0)
    assert len(model.load("torus", shape_args={"segments": 8, "sides": 4}).faces) == 64
    with pytest.raises(InputError, match="no argument 'radius'") as e:
        model.load("torus", shape_args={"radius": 1})
    assert "major" in str(e.value)
    with pytest.raises(InputError, match="positive"):
        model.load("sphere", shape_args={"radius": -1})
    with pytest.raises(InputError, match="whole number"):
        model.load("sphere", shape_args={"segments": 8.5})
    with pytest.raises(InputError, match="multiple of 4"):
        model.load("cylinder", shape_args={"segments": 6})


def _cube_corners():
    """The cube as 8 shared corners, each face's UVs in its own cell of a 3 x 2 atlas (mirrored
    where :data:`hzval.geometry.model.CUBE_FACES` mirrors), so no two faces share a UV at a corner."""
    c = model.cube()
    cell = np.repeat(np.array([[0, 0], [1, 0], [2, 0], [0, 1], [1, 1], [2, 1]]), 4, axis=0)
    uv = c.uvs * 0.3 + 0.01 + cell * 0.33
    corners, idx = np.unique(np.round(c.positions, 9), axis=0, return_inverse=True)
    return c, uv, corners, idx.ravel()


def test_ply_with_per_face_texcoords(tmp_path):
    """A scanner's PLY: shared vertices, UVs per face corner (``property list uchar float texcoord``)."""
    c, uv, corners, idx = _cube_corners()
    lines = [
        "ply",
        "format ascii 1.0",
        f"element vertex {len(corners)}",
        "property float x",
        "property float y",
        "property float z",
        f"element face {len(c.faces)}",
        "property list uchar int vertex_indices",
        "property list uchar float texcoord",
        "end_header",
    ]
    lines += [" ".join(map(str, p)) for p in corners]
    for f in c.faces:
        lines.append("3 " + " ".join(map(str, idx[f])) + " 6 " + " ".join(f"{u} {v}" for u, v in uv[f]))
    (tmp_path / "wedge.ply").write_text("\n".join(lines) + "\n")
    m = model.load(str(tmp_path / "wedge.ply"), up="z")
    assert m.mirrored_fraction == pytest.approx(1 / 3) and m.seam_edges == 12
    assert np.all(_edge_counts(m) == 2)
    assert m.world_per_uv == pytest.approx(1 / 0.3)


def test_obj_with_quads_and_shared_positions(tmp_path):
    c, uv, corners, idx = _cube_corners()
    lines = [f"v {x} {y} {z}" for x, y, z in corners] + [f"vt {u} {v}" for u, v in uv]
    for k in range(6):  # each face one quad, counterclockwise seen from outside
        quad = list(range(4 * k, 4 * k + 4))
        quad = quad if c.faces[2 * k][0] == 4 * k else quad[::-1]
        lines.append("f " + " ".join(f"{idx[v] + 1}/{v + 1}" for v in quad))
    (tmp_path / "quads.obj").write_text("\n".join(lines) + "\n")
    m = model.load(str(tmp_path / "quads.obj"), up="z")
    assert len(m.faces) == 12 and m.seam_edges == 12
    assert m.mirrored_fraction == pytest.approx(1 / 3)
    # no normals in the file: each corner's is the mean of its three faces' (one per position)
    corner = np.abs(m.normals).min(axis=1)
    np.testing.assert_allclose(corner, 1 / np.sqrt(3), rtol=1e-9)
