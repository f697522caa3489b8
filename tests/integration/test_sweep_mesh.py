"""``hzval sweep --mesh`` end to end: what a sweep on a model writes, and what it refuses.

A sweep on the built-in cube records the mesh, the camera that frames it and each frame's
macro-shadowed share, scores the techniques that render on models and names the one that does
not; a bad mesh is one line naming the file and the problem, exit 2, and no output folder.
"""

import json
from pathlib import Path

import pytest

from hzval.cli import main as cli
from hzval.techniques import registry as technique

SMALL = [
    "sweep",
    "--size",
    "24",
    "--depth",
    "0.1",
    "--spp",
    "1",
    "--azimuths",
    "-30,30",
    "--quiet",
    "--resolution",
    "40x40",
]


def test_a_sweep_on_the_cube(tmp_path, capsys):
    out = tmp_path / "cube"
    assert cli.main(SMALL + ["--mesh", "cube", "--out", str(out)]) == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["mesh"]["source"] == "cube" and m["mesh"]["triangles"] == 12
    assert m["mesh"]["mirrored_fraction"] > 0 and m["mesh"]["seam_edges"] == 12
    assert m["parameters"]["mesh"] == "cube"
    assert m["camera"]["kind"] == "perspective"  # the models' default view: three faces
    # every default but terrain, which sits models out
    assert set(m["techniques"]) == set(technique.defaults()) - {"terrain"}
    assert "on a model, the default terrain sits out" in m["warnings"]  # one line, not a warning
    for f in m["frames"]:
        assert 0.0 <= f["macro_shadowed"] <= 1.0
        for name in ("horizon", "pom"):
            t = f["techniques"][name]
            assert 0.0 <= t["visibility_mae"] <= 1.0 and "perfect_parallax_mae" in t
    assert (out / "index.html").is_file()
    err = capsys.readouterr().err
    assert "the default terrain sits out" in err and "terrain: not on a model" not in err


def test_a_technique_asked_for_by_name_that_sits_out_on_a_model_says_why(tmp_path, capsys):
    argv = SMALL + ["--techniques", "horizon,terrain", "--mesh", "cube", "--out", str(tmp_path / "c")]
    assert cli.main(argv) == 0
    assert "terrain: not on a model: Raudins' sweep" in capsys.readouterr().err


@pytest.mark.parametrize(
    "spec,needle",
    [("cubee", "did you mean cube"), ("nosuch.obj", "no such file"), ("mesh.stl", "unknown mesh format")],
)
def test_a_bad_mesh_is_one_line(tmp_path, capsys, spec, needle):
    out = tmp_path / "out"
    assert cli.main(SMALL + ["--mesh", spec, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0]
    assert not out.exists()


def test_a_mesh_without_uvs_is_refused(tmp_path, capsys):
    obj = tmp_path / "flat.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n")
    out = tmp_path / "out"
    assert cli.main(SMALL + ["--mesh", str(obj), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "flat.obj" in err[0]
    assert not out.exists()


@pytest.mark.slow
def test_parallax_and_mips_work_on_a_model(tmp_path):
    """On the cube in perspective, occlusion parallax mapping moves each sample's lookup along its
    own tangent frame toward the truth's hit: the horizon map's error comes down toward its perfect-
    parallax floor; a mip filter reads the pixels' footprints on the model."""
    runs = {}
    for name, flags in (
        ("plain", []),
        ("pom", ["--parallax", "occlusion"]),
        ("mips", ["--filter", "trilinear"]),
    ):
        out = tmp_path / name
        assert (
            cli.main(SMALL + ["--size", "48", "--spp", "2", "--mesh", "cube", "--out", str(out)] + flags) == 0
        )
        runs[name] = json.loads((out / "metrics.json").read_text())

    def err(m, key):
        return sum(f["techniques"]["horizon"][key] for f in m["frames"]) / len(m["frames"])

    plain, occl = err(runs["plain"], "visibility_mae"), err(runs["pom"], "visibility_mae")
    floor = err(runs["plain"], "perfect_parallax_mae")
    assert occl < plain and occl - floor < 0.5 * (plain - floor)
    assert runs["mips"]["parameters"]["filter"] == "trilinear"


def test_export_scene_writes_a_models_scene(tmp_path, variant):
    out = tmp_path / "x"
    cube = Path(__file__).resolve().parents[2] / "scenes" / "cube.toml"
    assert cli.main(["export-scene", "--scene", str(cube), "--size", "16", "--out", str(out)]) == 0
    assert {p.name for p in out.iterdir()} >= {"base.glb", "mesh.ply", "scene.xml"}
