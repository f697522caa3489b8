"""``hzval export-scene``: the truth as a Mitsuba 3 scene file, and Mitsuba's own renderer as a cross-check.

Mitsuba's ``direct`` integrator renders the exported scene (its own sensor,
emitter, BSDF and shadow rays from ``spawn_ray``); it must agree with
hzval's truth within the noise and the self-intersection leak that
hzval.truth.plane documents. Measured here (64 spp each): mean difference
1e-4 to 2e-4 and mean |difference| 0.0008 to 0.0032 of white, on a wall
and on the bricks, lit from two sides.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest

from hzval.cli import main as cli
from hzval.commands import export_scene
from hzval.core import shading
from hzval.materials.bricks import bricks
from hzval.scene import spec as sc
from hzval.truth import plane as truth
from tests.helpers import column_wall, make_scene

CASES = {
    "wall": lambda: (
        column_wall(40, 40, 20),
        make_scene((40, 40), 4 / 40, "open", effects=("shadow", "diffuse"), spp=64, elevation=30.0),
    ),
    "bricks": lambda: (bricks(48), sc.override(sc.Scene(), size=48, spp=64, depth=0.1)),
}


@pytest.mark.parametrize("case", list(CASES))
@pytest.mark.parametrize("azimuth", [180.0, 30.0])
def test_mitsubas_direct_integrator_agrees_with_the_truth(variant, tmp_path, case, azimuth):
    h, sc = CASES[case]()
    export_scene.write_scene(sc, h, tmp_path, azimuth_deg=azimuth)
    mine = truth.Truth(sc, h).render(azimuth)
    theirs = export_scene.mitsuba_render(tmp_path / "scene.xml")
    assert theirs.shape == mine.image.shape
    d = (theirs - mine.image)[..., 0] * shading.exposure(sc)
    assert abs(d.mean()) < 0.002  # no bias beyond the leak
    assert np.abs(d).mean() < 0.006  # noise of two 64-spp renders
    # the shadows are where the truth has them: pixels the truth sees in full shadow stay dark
    dark = mine.layers["visibility"] == 0
    assert dark.mean() > 0.02
    assert (theirs[..., 0][dark] * shading.exposure(sc) < 0.05).mean() > 0.97


def test_the_scene_file_names_what_the_truth_traces(variant, tmp_path):
    h, sc = CASES["wall"]()
    written = export_scene.write_scene(sc, h, tmp_path, azimuth_deg=90.0)
    assert sorted(p.name for p in written) == ["mesh.ply", "scene.xml"]
    root = ET.parse(tmp_path / "scene.xml").getroot()
    assert root.find("integrator").get("type") == "direct"
    assert root.find("sensor").get("type") == "orthographic"
    assert root.find("sensor/film/rfilter").get("type") == "box"
    d = [float(x) for x in root.find("emitter/vector").get("value").split(",")]
    L = sc.light.direction(90.0)
    np.testing.assert_allclose(d, -L, atol=1e-8)
    assert root.find("shape/bsdf").get("type") == "diffuse"
    assert [p.name for p in tmp_path.glob(".*")] == [".hzval"]  # the marker; no temporary files left


def test_cli_writes_it_and_refuses_what_the_direct_integrator_cannot_do(variant, tmp_path, capsys):
    out = tmp_path / "scene"
    assert cli.main(["export-scene", "--size", "24", "--azimuth", "-30", "--out", str(out)]) == 0
    assert (out / "scene.xml").is_file() and (out / "mesh.ply").is_file()
    assert "mitsuba" in capsys.readouterr().out
    bad = tmp_path / "bad"
    assert cli.main(["export-scene", "--size", "24", "--effects", "shadow,ambient", "--out", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("hzval: error:") and "\n" not in err and not bad.exists()


def test_a_model_exports_its_frames_its_displaced_mesh_and_a_scene_mitsuba_renders(variant, tmp_path):
    """On a model with mirrored UVs and no TANGENT of its own: base.glb holds the MikkTSpace frames
    hzval used (read back, they are the same), mesh.ply the displaced model, and scene.xml renders."""
    from hzval.geometry import model

    out = tmp_path / "m"
    argv = ["export-scene", "--material", "spikes", "--size", "24", "--mesh", "mirrored-sphere"]
    assert cli.main([*argv, "--tangents", "mikktspace", "--out", str(out)]) == 0
    used = model.load("mirrored-sphere", tangents="mikktspace")
    back = model.load(str(out / "base.glb"))
    assert back.tangent_method == "file" and (back.faces == used.faces).all()
    np.testing.assert_allclose(back.tangents, used.tangents, atol=1e-6)
    np.testing.assert_allclose(back.uvs, used.uvs, atol=1e-6)
    assert (out / "mesh.ply").stat().st_size > 0
    image = export_scene.mitsuba_render(out / "scene.xml", spp=4)
    assert image.shape[2] == 3 and image.max() > 0 and (image == 0).any()  # the sphere, and sky
