"""The smaller things of issue 32, each one line naming its flag: --variant after the command, an
unknown material, --size with a file, sidecar typos, and no folder left by a failed run."""

from __future__ import annotations

import numpy as np
import pytest

from hzval import materials
from hzval.cli import main as cli
from hzval.io import codecs


def _err(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert err.startswith("hzval: error:") and "\n" not in err and "usage:" not in err, err
    return err


def test_variant_before_or_after_the_command():
    for argv in (
        ["--variant", "llvm_ad_rgb", "sweep"],
        ["sweep", "--variant", "llvm_ad_rgb"],
        ["score", "f", "--against", "s", "--variant", "llvm_ad_rgb"],
    ):
        assert cli.build_parser().parse_args(argv).variant == "llvm_ad_rgb", argv


def test_an_unknown_material_is_one_line_with_the_nearest_names(tmp_path, capsys):
    assert cli.main(["sweep", "--material", "brickz", "--out", str(tmp_path / "o")]) == 2
    err = _err(capsys)
    assert "--material: unknown material 'brickz'; did you mean bricks?" in err and "cobblestones" in err
    assert cli.main(["suite", "gravl", "--out", str(tmp_path / "s")]) == 2
    assert "did you mean gravel?" in _err(capsys)
    assert not (tmp_path / "o").exists() and not (tmp_path / "s").exists()


@pytest.fixture()
def height_file(tmp_path):
    path = tmp_path / "stones.png"
    codecs.write_png(path, np.round(materials.generate("cobblestones", 24).height * 65535).astype(np.uint16))
    return path


def test_size_with_a_height_map_file_is_an_error(height_file, tmp_path, capsys):
    for argv in (["sweep", str(height_file), "--size", "64"], ["bake", str(height_file), "--size", "64"]):
        assert cli.main([*argv, "--out", str(tmp_path / "o")]) == 2
        err = _err(capsys)
        assert "--size: 64 applies to built-in materials only" in err and "(24x24)" in err
    scene = tmp_path / "scene.toml"
    scene.write_text(f'[material]\nheight = "{height_file.name}"\n')
    assert cli.main(["sweep", "--scene", str(scene), "--size", "64", "--out", str(tmp_path / "o")]) == 2
    assert "--size: 64 applies to built-in materials only" in _err(capsys)
    height_file.with_suffix(".toml").write_text("[material]\nsize = 64\n")  # a sidecar
    assert cli.main(["sweep", str(height_file), "--out", str(tmp_path / "o")]) == 2
    assert "stones.toml: material.size applies to built-in materials only" in _err(capsys)
    assert not (tmp_path / "o").exists()


def test_a_sidecar_typo_names_the_key_and_the_file(height_file, tmp_path, capsys):
    height_file.with_suffix(".toml").write_text("[material]\ndpeth = 0.1\n")
    assert cli.main(["sweep", str(height_file), "--out", str(tmp_path / "o")]) == 2
    err = _err(capsys)
    assert "stones.toml: unknown key 'dpeth' in [material]; did you mean 'depth'?" in err


def test_a_failed_run_into_a_new_folder_leaves_no_folder(height_file, tmp_path, capsys):
    """The set-up fails after the bake (a one-layer horizon map): neither bake/ nor the lock is left."""
    layer = tmp_path / "h0.png"
    codecs.write_png(layer, np.zeros((24, 24, 4), np.uint8))
    out = tmp_path / "new" / "deeper"
    assert (
        cli.main(
            [
                "sweep",
                str(height_file),
                "--azimuths",
                "0",
                "--spp",
                "1",
                "--quiet",
                "--techniques",
                "horizon",
                "--horizon-map",
                str(layer),
                "--out",
                str(out),
            ]
        )
        == 2
    )
    assert "h0.png" in _err(capsys)
    assert not (tmp_path / "new").exists()
