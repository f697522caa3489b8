"""The second audit (issue 42): nothing read or written outside the user's folders, one line and exit 2
for bad structure, and all-or-nothing reports. One test (or a few) per defect."""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

import numpy as np
import pytest

from hzval.cli import main as cli
from hzval.core.errors import InputError
from hzval.geometry import model
from tests.helpers import QUAD_F, QUAD_P, QUAD_UV, one_line, write_gltf


@pytest.fixture(scope="module")
def sweep_dir(tmp_path_factory, variant):
    out = tmp_path_factory.mktemp("audit2") / "sweep"
    argv = ["sweep", "--size", "32", "--azimuths", "0,90", "--spp", "2", "--techniques", "horizon"]
    assert cli.main([*argv, "--quiet", "--all-files", "--out", str(out)]) == 0
    return out


def engine_frames(tmp: Path, sweep_dir: Path) -> Path:
    """An engine's frames: the sweep's own horizon renders, one EXR per light."""
    d = tmp / "engine"
    d.mkdir()
    for f in json.loads((sweep_dir / "frames.json").read_text())["frames"]:
        shutil.copyfile(sweep_dir / "frames" / f["name"] / "horizon.exr", d / f"{f['name']}.exr")
    return d


def tampered(tmp: Path, sweep_dir: Path, name: str, edit) -> Path:
    """A copy of the sweep folder with ``edit(data)`` applied to its ``name`` JSON file."""
    copy = tmp / "tampered"
    shutil.copytree(sweep_dir, copy)
    data = json.loads((copy / name).read_text())
    edit(data)
    (copy / name).write_text(json.dumps(data))
    return copy


def snapshot(folder: Path) -> dict:
    return {
        p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()
    }


def score(frames: Path, sweep: Path, out: Path, *extra) -> int:
    return cli.main(["score", str(frames), "--against", str(sweep), "--out", str(out), *extra])


# 1. score reads and writes only inside its folders -----------------------------------------------


def test_a_frame_name_that_climbs_out_is_refused(tmp_path, sweep_dir, capsys):
    victim = tmp_path / "userdir"
    victim.mkdir()
    (victim / "truth.png").write_bytes(b"mine")
    frames = engine_frames(tmp_path, sweep_dir)
    shutil.copyfile(frames / "az+0.exr", frames / "..%2f..%2fuserdir.exr")

    def edit(d):
        d["frames"][0]["name"] = "../../../userdir"

    sweep = tampered(tmp_path, sweep_dir, "frames.json", edit)
    assert score(frames, sweep, tmp_path / "o") == 2
    one_line(capsys.readouterr().err, "frames.json", "frames[0].name")
    assert (victim / "truth.png").read_bytes() == b"mine" and sorted(victim.iterdir()) == [
        victim / "truth.png"
    ]
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("stored", ["/etc/hostname", "../../secret.txt", "frames/../../secret.txt"])
def test_a_stored_file_outside_the_sweep_is_refused(tmp_path, sweep_dir, capsys, stored):
    (tmp_path / "secret.txt").write_text("secret")

    def edit(d):
        d["frames"][1]["files"]["truth_png"] = stored

    sweep = tampered(tmp_path, sweep_dir, "metrics.json", edit)
    assert score(engine_frames(tmp_path, sweep_dir), sweep, tmp_path / "o") == 2
    one_line(capsys.readouterr().err, "metrics.json", "frames[1].files.truth_png")
    assert not (tmp_path / "o").exists()


def test_a_techniques_stored_file_outside_the_sweep_is_refused(tmp_path, sweep_dir, capsys):
    def edit(d):
        d["frames"][0]["techniques"]["horizon"]["files"]["png"] = "../../secret.txt"

    sweep = tampered(tmp_path, sweep_dir, "metrics.json", edit)
    assert score(engine_frames(tmp_path, sweep_dir), sweep, tmp_path / "o") == 2
    one_line(capsys.readouterr().err, "metrics.json", "frames[0].techniques.horizon.files.png")


def test_a_link_in_the_report_is_not_followed(tmp_path, sweep_dir):
    frames, out = engine_frames(tmp_path, sweep_dir), tmp_path / "o"
    assert score(frames, sweep_dir, out) == 0
    victim = tmp_path / "victim"
    victim.mkdir()
    (victim / "engine.png").write_bytes(b"mine")
    shutil.rmtree(out / "frames" / "az+0")
    (out / "frames" / "az+0").symlink_to(victim, target_is_directory=True)
    score(frames, sweep_dir, out, "--force")
    assert snapshot(victim) == {"engine.png": b"mine"}


# 4. every value that scales an image is checked --------------------------------------------------


@pytest.mark.parametrize("exposure", [-3.14, 0, 1e309])
def test_an_exposure_that_is_not_positive_and_finite_is_refused(tmp_path, sweep_dir, capsys, exposure):
    def edit(d):
        d["exposure"] = exposure

    sweep = tampered(tmp_path, sweep_dir, "frames.json", edit)
    assert score(engine_frames(tmp_path, sweep_dir), sweep, tmp_path / "o") == 2
    one_line(capsys.readouterr().err, "frames.json", "exposure")


# 5. score is all or nothing over an existing report ----------------------------------------------


def test_a_late_failure_leaves_the_earlier_report_byte_for_byte(tmp_path, sweep_dir, monkeypatch, capsys):
    frames, out = engine_frames(tmp_path, sweep_dir), tmp_path / "o"
    assert score(frames, sweep_dir, out) == 0
    before = snapshot(out)
    from hzval.report import pages as report

    def fail(*a, **k):
        raise InputError(out / "index.html", "a late failure")

    monkeypatch.setattr(report, "render_html", fail)
    assert score(frames, sweep_dir, out) == 2
    assert snapshot(out) == before


# 6. bad structure is one line and exit 2, never a traceback --------------------------------------


@pytest.mark.parametrize("name", ["frames.json", "metrics.json"])
def test_deeply_nested_json_is_one_line(tmp_path, sweep_dir, capsys, name):
    sweep = tmp_path / "s"
    shutil.copytree(sweep_dir, sweep)
    (sweep / name).write_text("[" * 100_000 + "]" * 100_000)
    assert score(engine_frames(tmp_path, sweep_dir), sweep, tmp_path / "o") == 2
    one_line(capsys.readouterr().err, name, "nests deeper")


def test_a_deeply_nested_engine_toml_is_one_line(tmp_path, sweep_dir, capsys):
    frames = engine_frames(tmp_path, sweep_dir)
    (frames / "engine.toml").write_text("a = " + "[" * 5000 + "]" * 5000 + "\n")
    assert score(frames, sweep_dir, tmp_path / "o") == 2
    one_line(capsys.readouterr().err, "engine.toml")


@pytest.mark.parametrize("key, value", [("camera", [1, 2]), ("techniques", ["horizon"]), ("frames", [1, 2])])
def test_a_malformed_metrics_json_is_one_line(tmp_path, sweep_dir, capsys, key, value):
    def edit(d):
        d[key] = value

    sweep = tampered(tmp_path, sweep_dir, "metrics.json", edit)
    assert score(engine_frames(tmp_path, sweep_dir), sweep, tmp_path / "o") == 2
    one_line(capsys.readouterr().err, "metrics.json", key)


# 2. and 3. glTF: buffers inside the model's folder, node trees walked once -----------------------


def gltf_with(tmp_path: Path, edit) -> Path:
    folder = tmp_path / "model"
    folder.mkdir()
    path = Path(write_gltf(folder / "q.gltf", QUAD_P, QUAD_UV, QUAD_F))
    data = json.loads(path.read_text())
    edit(data, folder)
    path.write_text(json.dumps(data))
    return path


@pytest.mark.parametrize("where", ["parent", "absolute", "scheme"])
def test_a_gltf_buffer_outside_the_models_folder_is_refused(tmp_path, where):
    def edit(d, folder):
        outside = tmp_path / "secret.bin"
        shutil.copyfile(folder / d["buffers"][0]["uri"], outside)
        d["buffers"][0]["uri"] = {
            "parent": "../secret.bin",
            "absolute": str(outside),
            "scheme": outside.as_uri(),
        }[where]

    path = gltf_with(tmp_path, edit)
    with pytest.raises(InputError, match=r"buffers\[0\]\.uri") as e:
        model.load(str(path), up="z")
    assert str(path) in str(e.value) and "bytes" not in str(e.value)


def test_an_embedded_gltf_buffer_still_reads(tmp_path):
    import base64

    def edit(d, folder):
        blob = (folder / d["buffers"][0]["uri"]).read_bytes()
        d["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(blob).decode()

    mesh = model.load(str(gltf_with(tmp_path, edit)), up="z")
    assert len(mesh.faces) == len(QUAD_F)


@pytest.mark.parametrize(
    "nodes", [[{"mesh": 0, "children": [0]}], [{"mesh": 0, "children": [1, 1]}, {"mesh": 0}]]
)
def test_a_gltf_node_reached_twice_is_refused_at_once(tmp_path, nodes):
    def edit(d, folder):
        d["nodes"] = nodes

    t0 = time.perf_counter()
    with pytest.raises(InputError, match="twice"):
        model.load(str(gltf_with(tmp_path, edit)), up="z")
    assert time.perf_counter() - t0 < 5


def test_the_cli_refuses_a_gltf_buffer_outside_in_one_line(tmp_path, variant, capsys):
    def edit(d, folder):
        shutil.copyfile(folder / d["buffers"][0]["uri"], tmp_path / "secret.bin")
        d["buffers"][0]["uri"] = "../secret.bin"

    path = gltf_with(tmp_path, edit)
    argv = [
        "sweep",
        "--mesh",
        str(path),
        "--size",
        "16",
        "--azimuths",
        "0",
        "--quiet",
        "--out",
        str(tmp_path / "o"),
    ]
    assert cli.main(argv) == 2
    one_line(capsys.readouterr().err, "q.gltf", "buffers[0].uri")
    assert not (tmp_path / "o").exists()


def test_the_path_rule_in_isolation(tmp_path):
    from hzval.io import paths

    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "link").symlink_to(tmp_path)
    assert paths.inside(tmp_path / "in", "a/b.png", "f.json", "k") == tmp_path / "in" / "a" / "b.png"
    for bad in ("link/x", "..", "/x", "", "a/../../x"):
        with pytest.raises(InputError, match="f.json"):
            paths.inside(tmp_path / "in", bad, "f.json", "k")
    for bad in ("..", ".", "a/b", "a\\b", "-x", "x\x00", 3):
        with pytest.raises(InputError, match="not a file name"):
            paths.file_name(bad, "f.json", "k")
    assert np.all([paths.file_name(n, "f", "k") == n for n in ("az+0", "el30_az-45", "a.b")])


# 4. gates, baselines, scene files and check's references ----------------------------------------


@pytest.mark.parametrize("operand", ["1" * 5000 + "x", "9" * 32_000])
def test_a_long_fail_if_is_refused_in_one_line(operand):
    from hzval.commands import gates

    with pytest.raises(InputError, match="--fail-if"):
        gates.parse(f"{operand}>horizon.flip_mean")


def test_the_fail_if_grammar_still_reads_numbers_and_aggregates():
    from hzval.commands import gates

    c = gates.parse("mean(horizon.flip_mean) >= 1.5e-3")
    assert (c.left.aggregate, c.left.path, c.op, c.right.number) == (
        "mean",
        "horizon.flip_mean",
        ">=",
        0.0015,
    )
    assert gates.parse("horizon.visibility_mae<.5").right.number == 0.5
    assert gates.parse("-2.>floor.flip_mean").left.number == -2.0
    with pytest.raises(InputError, match="neither a number"):
        gates.parse("1.2.3>horizon.flip_mean")


@pytest.mark.parametrize("text", ["[" * 100_000 + "]" * 100_000, '{"frames": ', '{"frames": 3}'])
def test_a_malformed_baseline_is_one_line(tmp_path, text):
    from hzval.commands import gates

    (tmp_path / "metrics.json").write_text(text)
    with pytest.raises(InputError) as exc:
        gates.read_baseline(tmp_path)
    assert str(exc.value).startswith("--baseline") and "\n" not in str(exc.value)


def test_a_deeply_nested_scene_is_one_line(tmp_path, capsys):
    scene = tmp_path / "deep.toml"
    scene.write_text("a = " + "[" * 5000 + "]" * 5000 + "\n")
    assert cli.main(["sweep", "--scene", str(scene), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    one_line(capsys.readouterr().err, "deep.toml")
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("name", ["../../escaped", "a/b", "..", "-rf"])
def test_check_refuses_a_scene_name_that_is_not_one_folder(tmp_path, name, capsys):
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    (scenes / "s.toml").write_text(f'name = "{name}"\n')
    assert cli.main(["check", "--scenes", str(scenes), "--references", str(tmp_path / "r")]) == 2
    one_line(capsys.readouterr().err, "s.toml", "is not a file name")


def test_check_update_never_writes_outside_references(tmp_path, capsys):
    scenes, refs = tmp_path / "scenes", tmp_path / "refs"
    scenes.mkdir()
    (scenes / "evil.toml").write_text('name = "../../escaped"\n')
    argv = ["check", "--scenes", str(scenes), "--references", str(refs), "--update"]
    assert cli.main(argv) == 2
    one_line(capsys.readouterr().err, "evil.toml", "name")
    assert not (tmp_path / "escaped").exists() and not refs.exists()


def test_a_deeply_nested_horizon_encoding_is_one_line(tmp_path):
    from hzval.io import external

    enc = tmp_path / "enc.toml"
    enc.write_text("a = " + "[" * 5000 + "]" * 5000 + "\n")
    with pytest.raises(InputError, match="nests deeper"):
        external.Encoding.from_toml(enc)


# 7. stored inputs are found from any folder --------------------------------------------------------


def test_score_on_a_model_sweep_runs_from_any_folder(tmp_path, monkeypatch, variant, capsys):
    """The sweep ran in ``work/`` with relative paths; ``score`` runs in ``elsewhere/`` and still finds
    the height map and the mesh (recorded relative to the sweep's folder) for its tangent-bug match."""
    from hzval import materials
    from hzval.io import codecs
    from tests.helpers import write_obj

    work, elsewhere = tmp_path / "work", tmp_path / "elsewhere"
    work.mkdir(), elsewhere.mkdir()
    np.save(work / "map.npy", materials.generate("gravel", 24).height)
    write_obj(work / "quad.obj", QUAD_P, QUAD_UV, QUAD_F)
    monkeypatch.chdir(work)
    argv = ["sweep", "map.npy", "--mesh", "quad.obj", "--resolution", "32x24", "--azimuths", "0,90"]
    assert (
        cli.main([*argv, "--spp", "1", "--techniques", "horizon", "--all-files", "--quiet", "--out", "s"])
        == 0
    )
    metrics = json.loads((work / "s" / "metrics.json").read_text())
    assert metrics["parameters"]["mesh"] == "../quad.obj" and metrics["material"]["path"] == "../map.npy"
    frames = work / "engine"
    frames.mkdir()
    for f in json.loads((work / "s" / "frames.json").read_text())["frames"]:
        d = work / "s" / "frames" / f["name"]
        shutil.copyfile(d / "horizon.exr", frames / f"{f['name']}.exr")
        factor = codecs.read_exr(d / "horizon_factor.exr")["Y"]  # NaN off the model: an engine's 1
        codecs.write_exr(frames / f"f_{f['name']}.exr", {"Y": np.nan_to_num(factor, nan=1.0)})
    monkeypatch.chdir(elsewhere)
    assert score(Path("../work/engine"), Path("../work/s"), Path("o")) == 0, capsys.readouterr().err
    result = json.loads((elsewhere / "o" / "metrics.json").read_text())
    assert result["tangent_bug"]["best"] == "none"


def test_a_moved_height_map_is_named(tmp_path, sweep_dir):
    from hzval.pipeline import bug_match

    metrics = json.loads((sweep_dir / "metrics.json").read_text())
    metrics["parameters"]["mesh"] = "sphere"
    metrics["material"]["path"] = "../gone.png"
    with pytest.raises(InputError, match="material.path '../gone.png': no such file"):
        bug_match.scene_of(metrics, sweep_dir)


# 5. and 9. views and models: all or nothing, and Ctrl-C stops them between cases -----------------


@pytest.fixture(scope="module")
def views_dir(tmp_path_factory, variant):
    from hzval.commands import views
    from hzval.scene import spec as sc

    out = tmp_path_factory.mktemp("views") / "v"
    scene = sc.override(sc.Scene(), height="gravel", size=16, azimuths="0", spp=1)
    views.run(scene, out, views=["top", "ortho-45"], lookups=["bilinear"], progress=False)
    return scene, out


def test_a_late_failure_in_views_leaves_the_earlier_report(tmp_path, views_dir, monkeypatch):
    from hzval.commands import views
    from hzval.pipeline import sweep

    scene, first = views_dir
    out = tmp_path / "v"
    shutil.copytree(first, out)
    before, real, calls = snapshot(out), sweep.run, []

    def failing(*a, **k):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(*a, **k)

    monkeypatch.setattr(sweep, "run", failing)
    with pytest.raises(KeyboardInterrupt):
        views.run(scene, out, views=["top", "ortho-45"], lookups=["bilinear"], progress=False)
    assert snapshot(out) == before


def test_ctrl_c_during_a_cases_swap_stops_views_there(tmp_path, views_dir, monkeypatch):
    """The signal comes while the first sweep swaps its report in (held): that sweep finishes, and the
    run stops before the second, leaving the earlier report as it was."""
    import os
    import signal

    from hzval.commands import views
    from hzval.core import errors
    from hzval.io import staging
    from hzval.pipeline import sweep

    scene, first = views_dir
    out = tmp_path / "v"
    shutil.copytree(first, out)
    before, swap, real, calls = snapshot(out), staging.Staging.swap, sweep.run, []

    def interrupted_swap(self):
        os.kill(os.getpid(), signal.SIGINT)
        swap(self)

    def counted(*a, **k):
        calls.append(1)
        return real(*a, **k)

    monkeypatch.setattr(staging.Staging, "swap", interrupted_swap)
    monkeypatch.setattr(sweep, "run", counted)
    with pytest.raises(errors.Interrupted):
        views.run(scene, out, views=["top", "ortho-45"], lookups=["bilinear"], progress=False)
    assert len(calls) == 1 and snapshot(out) == before


# 10. degenerate meshes are refused before anything is rendered, naming the mesh --------------------


@pytest.mark.parametrize(
    "positions, uv_scale, message",
    [
        (QUAD_P * 1e-200, 1.0, "1e-200 units across"),
        (QUAD_P * 1e200, 1.0, "1e\\+200 units across"),
        (QUAD_P * 0.0, 1.0, "0 units across"),  # a glTF node scale of 0
        (np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]], float), 1.0, "collinear"),
        (QUAD_P, 1e-9, "--uv-scale"),
    ],
)
def test_a_degenerate_mesh_is_refused_naming_it(positions, uv_scale, message):
    with pytest.raises(InputError, match=message) as exc:
        model.build("m.obj", positions, QUAD_UV, QUAD_F, uv_scale=uv_scale)
    assert str(exc.value).startswith("m.obj:")


def test_a_degenerate_mesh_is_refused_before_the_sweep_writes(tmp_path, variant, capsys):
    from tests.helpers import write_obj

    write_obj(tmp_path / "line.obj", [[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]], QUAD_UV, QUAD_F)
    argv = ["sweep", "--mesh", str(tmp_path / "line.obj"), "--size", "16", "--resolution", "16x16"]
    assert cli.main([*argv, "--quiet", "--out", str(tmp_path / "o")]) == 2
    one_line(capsys.readouterr().err, "line.obj", "collinear")
    assert not (tmp_path / "o").exists()


def test_small_and_large_meshes_in_range_still_sweep(tmp_path, variant):
    from tests.helpers import write_obj

    for scale in (2e-6, 5e6):
        write_obj(tmp_path / "q.obj", QUAD_P * scale, QUAD_UV, QUAD_F)
        argv = ["sweep", "--mesh", str(tmp_path / "q.obj"), "--size", "16", "--resolution", "16x16"]
        argv += ["--azimuths", "0", "--spp", "1", "--techniques", "horizon", "--quiet"]
        assert cli.main([*argv, "--out", str(tmp_path / f"o{scale:g}")]) == 0


# Also seen: a local cluster's scratch space ----------------------------------------------------------


def test_a_local_clusters_scratch_space_is_removed(tmp_path, monkeypatch, variant):
    import tempfile

    system_tmp = tmp_path / "tmp"
    system_tmp.mkdir()
    monkeypatch.setenv("TMPDIR", str(system_tmp))  # the workers' processes read it too
    monkeypatch.setattr(tempfile, "tempdir", None)
    argv = ["suite", "planks", "--size", "16", "--azimuths", "0", "--spp", "1", "--techniques", "horizon"]
    assert cli.main([*argv, "--workers", "1", "--quiet", "--out", str(tmp_path / "o")]) == 0
    assert sorted(p.name for p in system_tmp.iterdir()) == []
