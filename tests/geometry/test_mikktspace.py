"""hzval.geometry.mikktspace against known answers and against the reference C compiled here."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from hzval.geometry import mikktspace as mk
from hzval.geometry import model

ORACLE = Path(__file__).resolve().parents[1] / "oracles" / "mikktspace"
GCC = shutil.which("gcc")

QUAD_P = np.array([[0.0, 0, 0], [2, 0, 0], [2, 1, 0], [0, 1, 0]])
QUAD_N = np.tile([0.0, 0, 1], (4, 1))
QUAD_UV = np.array([[0.0, 0], [1, 0], [1, 1], [0, 1]])
QUAD_F = np.array([[0, 1, 2], [0, 2, 3]])


def angle_deg(a, b) -> np.ndarray:
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b / np.linalg.norm(b, axis=-1, keepdims=True)
    return np.degrees(np.arccos(np.clip(np.sum(a * b, axis=-1), -1, 1)))


def test_a_planar_quads_tangent_is_plus_u_exactly():
    t = mk.corner_tangents(QUAD_P, QUAD_N, QUAD_UV, QUAD_F)
    assert np.array_equal(t.reshape(-1, 4), np.tile([1.0, 0, 0, 1], (6, 1)))


def test_a_mirrored_quad_has_w_minus_one_and_the_tangent_along_plus_u():
    mirrored = QUAD_UV * [-1.0, 1.0]  # u runs toward -x
    t = mk.corner_tangents(QUAD_P, QUAD_N, mirrored, QUAD_F).reshape(-1, 4)
    np.testing.assert_allclose(t, np.tile([-1.0, 0, 0, -1], (6, 1)), atol=1e-12)


def test_a_uv_spheres_tangents_run_along_its_parallels():
    """Exactly east, where the triangles on both sides of a meridian balance; on the UV seam, whose
    two copies of a vertex see one side each, the chord's half-segment off east."""
    segments = 64
    s = model.load("sphere", shape_args={"segments": segments})
    t = mk.corner_tangents(s.positions, s.normals, s.uvs, s.faces)
    p = s.positions[s.faces]
    pole = np.linalg.norm(p[..., :2], axis=-1) < 1e-6
    seam = np.isin(s.uvs[s.faces][..., 0], (0.0, 1.0))
    east = np.cross([0.0, 0.0, 1.0], p)  # along the parallel, toward increasing longitude
    off = angle_deg(t[..., :3][~pole], east[~pole])
    assert (off[~seam[~pole]] < 1e-4).all()
    assert (off[seam[~pole]] < 180.0 / segments + 1e-4).all() and off[seam[~pole]].max() > 1.0
    assert (t[..., 3][~pole] == 1.0).all()


def test_corner_order_and_triangle_order_change_nothing():
    s = model.load("mirrored-sphere")
    t = mk.corner_tangents(s.positions, s.normals, s.uvs, s.faces)
    turned = mk.corner_tangents(s.positions, s.normals, s.uvs, np.roll(s.faces, 1, axis=1))
    np.testing.assert_allclose(np.roll(turned, -1, axis=1), t, atol=1e-12)
    order = np.random.default_rng(3).permutation(len(s.faces))
    shuffled = mk.corner_tangents(s.positions, s.normals, s.uvs, s.faces[order])
    np.testing.assert_allclose(shuffled, t[order], atol=1e-12)


def test_a_uv_seam_keeps_a_frame_on_each_side():
    """Two quads folded at x = 1, the second's UV chart turned a quarter (its +u runs toward -y): the
    shared edge's vertices are not welded (their UVs differ), so each side keeps its own +u."""
    p = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [1, 0, 0], [2, 0, 1], [2, 1, 1], [1, 1, 0]])
    n = np.tile([0.0, 0, 1], (8, 1))
    uv = np.array([[0.0, 0], [1, 0], [1, 1], [0, 1], [5, 0], [5, 1], [4, 1], [4, 0]])
    f = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])
    t = mk.corner_tangents(p, n, uv, f)
    np.testing.assert_allclose(t[:2, :, :3].reshape(-1, 3), np.tile([1.0, 0, 0], (6, 1)), atol=1e-12)
    np.testing.assert_allclose(t[2:, :, :3].reshape(-1, 3), np.tile([0.0, -1, 0], (6, 1)), atol=1e-12)


def test_degenerate_uv_triangles_give_no_nan():
    p = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 2, 0]])
    n = np.tile([0.0, 0, 1], (5, 1))
    uv = np.array([[0.0, 0], [1, 0], [1, 1], [0, 1], [0, 1]])  # the last triangle has no UV area
    f = np.array([[0, 1, 2], [0, 2, 3], [3, 2, 4]])
    t = mk.corner_tangents(p, n, uv, f)
    assert np.isfinite(t).all()
    np.testing.assert_allclose(t[2, :, :3], np.tile([1.0, 0, 0], (3, 1)), atol=1e-12)  # joins a group


def test_per_vertex_splits_only_where_corners_disagree():
    s = model.load("mirrored-sphere")
    corners = mk.corner_tangents(s.positions, s.normals, s.uvs, s.faces)
    p, n, uv, f, t = mk.per_vertex(s.positions, s.normals, s.uvs, s.faces, corners)
    np.testing.assert_array_equal(t[f], corners)
    np.testing.assert_array_equal(p[f], s.positions[s.faces])
    quad = mk.per_vertex(QUAD_P, QUAD_N, QUAD_UV, QUAD_F, mk.corner_tangents(QUAD_P, QUAD_N, QUAD_UV, QUAD_F))
    np.testing.assert_array_equal(quad[3], QUAD_F)  # nothing to split: the mesh as it was


# The reference, compiled ----------------------------------------------------------------------


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    if GCC is None:
        pytest.skip("gcc is not installed: cannot compile the reference tests/oracles/mikktspace")
    exe = tmp_path_factory.mktemp("mikk") / "driver"
    cmd = [GCC, "-O2", "-o", str(exe), str(ORACLE / "driver.c"), str(ORACLE / "mikktspace.c"), "-lm"]
    done = subprocess.run(cmd, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr

    def run(positions, normals, uvs, faces, tmp: Path) -> np.ndarray:
        corners = np.concatenate([positions[faces], normals[faces], uvs[faces]], axis=-1)
        with open(tmp / "in.bin", "wb") as fh:
            np.array([len(faces)], "<i4").tofile(fh)
            corners.astype("<f4").tofile(fh)
        ran = subprocess.run([str(exe), str(tmp / "in.bin"), str(tmp / "out.bin")], capture_output=True)
        assert ran.returncode == 0, ran.stderr
        return np.fromfile(tmp / "out.bin", "<f4").reshape(len(faces), 3, 4).astype(np.float64)

    return run


def seams_and_mirrors():
    """A UV-mapped model with seams and mirrored islands: the mirrored sphere and the cube side by
    side, their normals and positions jittered so that no frame is a textbook one."""
    rng = np.random.default_rng(7)
    a, b = model.load("mirrored-sphere"), model.load("cube")
    p = np.concatenate([a.positions, b.positions + [3.0, 0, 0]])
    p = p + rng.normal(0, 0.01, p.shape)
    n = np.concatenate([a.normals, b.normals]) + rng.normal(0, 0.05, p.shape)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    uv = np.concatenate([a.uvs, b.uvs * 0.9 + 0.05])
    f = np.concatenate([a.faces, b.faces + len(a.positions)])
    return p, n, uv, f


@pytest.mark.gcc
def test_the_reference_agrees_on_seams_and_mirrored_islands(reference, tmp_path):
    p, n, uv, f = seams_and_mirrors()
    p, n, uv = (x.astype(np.float32).astype(np.float64) for x in (p, n, uv))  # as the reference reads
    ours = mk.corner_tangents(p, n, uv, f)
    theirs = reference(p, n, uv, f, tmp_path)
    close = (angle_deg(ours[..., :3], theirs[..., :3]) < 1.0) & (ours[..., 3] == theirs[..., 3])
    assert close.mean() >= 0.99, close.mean()
    assert (ours[..., 3] == -1).any() and (ours[..., 3] == 1).any()  # both handednesses were tested


@pytest.mark.gcc
def test_the_reference_agrees_on_a_degenerate_and_frameless_mix(reference, tmp_path):
    p = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 2, 0], [1, 0, 0]])
    n = np.tile([0.0, 0, 1], (6, 1))
    uv = np.array([[0.0, 0], [1, 0], [1, 1], [0, 1], [0, 1], [1, 0]])
    f = np.array([[0, 1, 2], [0, 2, 3], [3, 2, 4], [1, 5, 2]])  # no UV area; two equal positions
    ours, theirs = mk.corner_tangents(p, n, uv, f), reference(p, n, uv, f, tmp_path)
    np.testing.assert_allclose(ours, theirs, atol=1e-6)


# Which frames a loaded mesh uses (--tangents) -----------------------------------------------------


def test_auto_uses_a_files_tangents_unchanged_and_mikktspace_without(tmp_path):
    from hzval.geometry import tangents as tg
    from tests.helpers import QUAD_F as F
    from tests.helpers import QUAD_P as P
    from tests.helpers import QUAD_UV as UV
    from tests.helpers import write_gltf

    # orthonormal file tangents that MikkTSpace would not give (turned 30 degrees in the plane)
    c, s = np.cos(np.radians(30)), np.sin(np.radians(30))
    own = np.tile([c, s, 0.0, -1.0], (4, 1))
    with_t = write_gltf(tmp_path / "t.gltf", P, UV, F, normals=np.tile([0.0, 0, 1], (4, 1)), tangents=own)
    for method in ("auto", "file"):
        m = model.load(str(with_t), up="z", tangents=method)
        np.testing.assert_allclose(m.tangents, own, atol=1e-7)
        assert m.tangent_method == "file"
    bare = model.load(str(write_gltf(tmp_path / "b.gltf", P, UV, F)), up="z")
    assert bare.tangent_method == "mikktspace"
    np.testing.assert_allclose(bare.tangents, np.tile([1.0, 0, 0, 1], (4, 1)), atol=1e-12)
    fged2 = model.load(str(with_t), up="z", tangents="fged2")
    np.testing.assert_array_equal(
        fged2.tangents, tg.compute(fged2.positions, fged2.normals, fged2.uvs, fged2.faces)
    )


def test_fged2_gives_the_frames_the_shapes_always_had():
    from hzval.geometry import tangents as tg

    for shape in ("sphere", "mirrored-sphere", "torus"):
        m = model.load(shape, tangents="fged2")
        assert m.tangent_method == "fged2" and model.load(shape).tangent_method == "fged2"  # auto
        np.testing.assert_array_equal(m.tangents, tg.compute(m.positions, m.normals, m.uvs, m.faces))


def test_file_frames_on_a_mesh_without_them_is_one_line_naming_the_flag():
    from hzval.core.errors import InputError

    with pytest.raises(InputError, match="--tangents: sphere: the mesh has no TANGENT"):
        model.load("sphere", tangents="file")


def test_mikktspace_splits_the_mirror_line_of_a_mirrored_sphere():
    m = model.load("mirrored-sphere", tangents="mikktspace")
    assert m.tangent_method == "mikktspace" and np.isfinite(m.tangents).all()
    corners = mk.corner_tangents(m.positions, m.normals, m.uvs, m.faces)
    np.testing.assert_allclose(m.tangents[m.faces], corners, atol=1e-12)  # one frame a vertex
    assert set(np.unique(m.tangents[:, 3])) == {-1.0, 1.0}


@pytest.mark.gcc
def test_export_scene_writes_the_references_frames_of_a_users_model(reference, tmp_path, variant):
    """The Done-when of issue 40: a glTF with seams and mirrored islands and no TANGENT, exported by
    ``hzval export-scene``; base.glb's tangents, corner by corner, against the reference's."""
    from hzval.cli import main as cli
    from tests.helpers import write_gltf

    p, n, uv, f = seams_and_mirrors()
    src = write_gltf(tmp_path / "user.gltf", p, uv, f, normals=n)
    out = tmp_path / "export"
    argv = ["export-scene", "--material", "gravel", "--size", "16", "--mesh", str(src), "--up", "z"]
    assert cli.main([*argv, "--out", str(out)]) == 0
    written = model.load(str(out / "base.glb"), up="y")
    read = model.load(str(src), up="z", tangents="fged2")  # the arrays hzval read, before any frames
    theirs = reference(read.positions, read.normals, read.uvs, read.faces, tmp_path)
    ours = written.tangents[written.faces]
    close = (angle_deg(ours[..., :3], theirs[..., :3]) < 1.0) & (ours[..., 3] == theirs[..., 3])
    assert close.mean() >= 0.99, close.mean()
