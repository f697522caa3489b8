"""Every command reads a height map's sidecar (``m.toml`` beside ``m.png``) the same way: through
:func:`hzval.cli.scenes.scene_from_args`. Each command's stage is stopped where it is handed its
scene, and the scene is checked for the sidecar's depth and boundary, then for a flag's override."""

from __future__ import annotations

import numpy as np
import pytest

from hzval import materials
from hzval.cli import main as cli

# (command, extra argv, module and function that receive the scene first, the scene's position)
STAGES = {
    "sweep": ([], "hzval.pipeline.sweep", "run", 0),
    "tradeoff": ([], "hzval.commands.tradeoff", "check_fits", 0),
    "fit": (["--out", "OUT"], "hzval.techniques.fitted.training", "check_fits", 5),
    "models": ([], "hzval.commands.models", "run", 0),
    "views": ([], "hzval.commands.views", "run", 0),
    "export-scene": (["--out", "OUT"], "hzval.commands.export_scene", "check_fits", 0),
}


class Handed(Exception):
    """The stage was reached; its scene is ``args[0]``."""


@pytest.fixture
def sidecar_map(tmp_path):
    np.save(tmp_path / "m.npy", materials.generate("gravel", 16).height)
    (tmp_path / "m.toml").write_text('[material]\ndepth = 0.0375\nboundary = "open"\n')
    return tmp_path / "m.npy"


def scene_of(command: str, argv: list[str], monkeypatch, tmp_path):
    import importlib

    extra, module, name, at = STAGES[command]
    mod = importlib.import_module(module)

    def stop(*args, **kwargs):
        raise Handed(args[at])

    monkeypatch.setattr(mod, name, stop)
    extra = [str(tmp_path / "out") if a == "OUT" else a for a in extra]
    with pytest.raises(Handed) as got:
        cli.main([command, *argv, *extra])
    return got.value.args[0]


@pytest.mark.parametrize("command", list(STAGES))
def test_every_command_reads_the_sidecar(command, sidecar_map, monkeypatch, tmp_path):
    scene = scene_of(command, [str(sidecar_map)], monkeypatch, tmp_path)
    assert (scene.material.depth, scene.material.boundary) == (0.0375, "open")
    assert scene.name == "m"


@pytest.mark.parametrize("command", list(STAGES))
def test_a_flag_overrides_the_sidecar(command, sidecar_map, monkeypatch, tmp_path):
    scene = scene_of(command, [str(sidecar_map), "--depth", "0.02"], monkeypatch, tmp_path)
    assert (scene.material.depth, scene.material.boundary) == (0.02, "open")


def test_a_commands_own_defaults_yield_to_the_sidecar(tmp_path, monkeypatch):
    """views sweeps 4 samples by default, but a sidecar that asks for 8 gets 8; a flag beats both."""
    np.save(tmp_path / "m.npy", materials.generate("gravel", 16).height)
    (tmp_path / "m.toml").write_text("[samples]\nspp = 8\n")
    assert scene_of("views", [str(tmp_path / "m.npy")], monkeypatch, tmp_path).spp == 8
    assert scene_of("views", [str(tmp_path / "m.npy"), "--spp", "2"], monkeypatch, tmp_path).spp == 2
    assert scene_of("views", ["--material", "gravel"], monkeypatch, tmp_path).spp == 4


def test_bake_writes_the_sidecars_depth(sidecar_map, tmp_path):
    import json

    assert cli.main(["bake", str(sidecar_map), "--out", str(tmp_path / "b")]) == 0
    params = json.loads((tmp_path / "b" / "bake.json").read_text())["parameters"]
    assert (params["depth"], params["boundary"]) == (0.0375, "open")
