"""KTX 2.0 files (hzval.io.ktx2) against the specification's rules, read by an independent parser
(tests/oracles/ktx2_parser.py), their BC blocks decoded by a second decoder (Pillow's), and
hzval export-textures end to end: an export of a BC7 sweep scores as that sweep."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from hzval.cli import main as cli
from hzval.core.errors import InputError
from hzval.io import ktx2
from tests.helpers import one_line
from tests.oracles import ktx2_parser as oracle

BLOCK_FORMATS = [n for n, f in ktx2.FORMATS.items() if f.block == 4]
ALL = list(ktx2.FORMATS)


def texture(name: str, width: int = 13, height: int = 9, seed: int = 0) -> ktx2.Texture:
    fmt = ktx2.FORMATS[name]
    rng = np.random.default_rng(seed)
    levels = []
    for i in range(1 + int(math.log2(max(width, height)))):
        w, h = max(1, width >> i), max(1, height >> i)
        levels.append(ktx2.encode_level(rng.random((h, w, fmt.channels)).astype(np.float32), fmt))
    return ktx2.Texture(fmt, width, height, levels)


@pytest.mark.parametrize("zstd", [False, True])
@pytest.mark.parametrize("name", ALL)
def test_a_written_file_keeps_the_specifications_rules(tmp_path, name, zstd):
    tex = texture(name)
    ktx2.write(tmp_path / "t.ktx2", tex, zstd=zstd)
    p = oracle.parse((tmp_path / "t.ktx2").read_bytes())
    fmt = ktx2.FORMATS[name]
    assert (p.vk_format, p.width, p.height) == (fmt.vk, 13, 9)
    assert p.type_size == (2 if fmt.half else 1) and p.scheme == (2 if zstd else 0)
    # a full chain: levels down to 1 x 1
    assert p.level_count == 1 + int(math.log2(13)) == len(p.levels)
    offsets = [offset for offset, _, _ in p.levels]
    assert offsets == sorted(offsets, reverse=True)  # level 0 first in the index, last in the file
    align = 1 if zstd else math.lcm(fmt.block_bytes, 4)
    for i, (offset, length, full) in enumerate(p.levels):
        w, h = max(1, 13 >> i), max(1, 9 >> i)
        assert full == -(-w // fmt.block) * -(-h // fmt.block) * fmt.block_bytes
        assert offset % align == 0 and (zstd or length == full)
    last = p.levels[0][0] + p.levels[0][1]
    assert last == len(p.raw)
    d = p.dfd
    assert d["vendor_and_type"] == 0 and d["version"] == 2 and d["size"] == 24 + 16 * len(d["samples"])
    assert d["transfer"] == 1 and d["primaries"] == 1  # data: linear
    assert d["dims"][:2] == (fmt.block - 1,) * 2 and d["planes"][0] == fmt.block_bytes
    assert sum(s["bits"] for s in d["samples"]) == 8 * fmt.block_bytes
    keys = [k for k, _, _ in p.kv]
    assert keys == sorted(keys) and {"KTXorientation", "KTXwriter"} <= set(keys)
    assert dict((k, v) for k, v, _ in p.kv)["KTXorientation"] == b"rd\0"


@pytest.mark.parametrize("name", ALL)
def test_what_is_written_reads_back(tmp_path, name):
    tex = texture(name, seed=3)
    ktx2.write(tmp_path / "t.ktx2", tex, zstd=True)
    back = ktx2.read(tmp_path / "t.ktx2")
    assert back.format == tex.format and back.levels == tex.levels and (back.width, back.height) == (13, 9)


@pytest.mark.parametrize("name", BLOCK_FORMATS)
def test_bc_blocks_decode_alike_in_a_second_decoder(tmp_path, name):
    """texture2ddecoder (hzval's) and Pillow's DDS decoder give the same texels."""
    from hzval import materials

    h = materials.generate("cobblestones", 64).height
    fmt = ktx2.FORMATS[name]
    values = np.stack([np.roll(h, 5 * c, axis=1) for c in range(fmt.channels)], -1).astype(np.float32)
    ktx2.write(tmp_path / "t.ktx2", ktx2.Texture(fmt, 64, 64, [ktx2.encode_level(values, fmt)]))
    p = oracle.parse((tmp_path / "t.ktx2").read_bytes())
    theirs = oracle.bc_level(p, 0, 64, 64)[..., : fmt.channels]
    ours = ktx2.decode_level(ktx2.read(tmp_path / "t.ktx2"), 0)
    assert np.array_equal(np.round(ours * 255).astype(np.uint8), theirs)


def test_a_file_that_is_not_ktx2_is_one_line(tmp_path):
    (tmp_path / "x.ktx2").write_bytes(b"not a texture")
    with pytest.raises(InputError, match="not a KTX 2.0 file"):
        ktx2.read(tmp_path / "x.ktx2")
    tex = texture("BC7_UNORM_BLOCK")
    ktx2.write(tmp_path / "t.ktx2", tex)
    (tmp_path / "cut.ktx2").write_bytes((tmp_path / "t.ktx2").read_bytes()[:-100])
    with pytest.raises(InputError, match="truncated"):
        ktx2.read(tmp_path / "cut.ktx2")


# --------------------------------------------------------------------------------------------------
# hzval export-textures
# --------------------------------------------------------------------------------------------------

SWEEP = ["sweep", "--material", "gravel", "--size", "64", "--azimuths", "0,45", "--spp", "4", "--quiet"]


@pytest.fixture(scope="module")
def bc7_sweep(tmp_path_factory, variant):
    out = tmp_path_factory.mktemp("ktx") / "sweep"
    assert cli.main([*SWEEP, "--horizon-storage", "bc7", "--ao-storage", "u8", "--out", str(out)]) == 0
    return out


def test_an_export_of_a_bc7_sweep_scores_as_that_sweep(bc7_sweep, tmp_path):
    out = tmp_path / "textures"
    assert cli.main(["export-textures", str(bc7_sweep), "--zstd", "--out", str(out)]) == 0
    described = json.loads((out / "textures.json").read_text())["files"]
    assert described["horizon0.ktx2"]["format"] == "VK_FORMAT_BC7_UNORM_BLOCK"
    assert described["ambient.ktx2"]["format"] == "VK_FORMAT_R8_UNORM"  # --ao-storage u8
    assert described["bent_normal.ktx2"]["format"] == "VK_FORMAT_R16G16B16A16_SFLOAT"
    for name in described:
        p = oracle.parse((out / name).read_bytes())
        assert p.level_count == 7 and p.dfd["transfer"] == 1
    layers = f"{out / 'horizon0.ktx2'},{out / 'horizon1.ktx2'}"
    again = tmp_path / "again"
    assert cli.main([*SWEEP, "--horizon-map", layers, "--techniques", "horizon", "--out", str(again)]) == 0
    a = json.loads((bc7_sweep / "metrics.json").read_text())["frames"]
    b = json.loads((again / "metrics.json").read_text())["frames"]
    for fa, fb in zip(a, b):
        want, got = (f["techniques"]["horizon"]["visibility_mae_facing"] for f in (fa, fb))
        assert got == pytest.approx(want, abs=1e-4)


def test_export_of_a_bake_and_a_fit(tmp_path, variant):
    assert cli.main(["bake", "--size", "32", "--out", str(tmp_path / "b")]) == 0
    assert cli.main(["export-textures", str(tmp_path / "b"), "--out", str(tmp_path / "tb")]) == 0
    names = {p.name for p in (tmp_path / "tb").glob("*.ktx2")}
    assert names == {
        f"{n}.ktx2" for n in ("horizon0", "horizon1", "normal", "ambient", "bent_normal", "ssbump")
    }
    fit = [
        "fit",
        "--size",
        "16",
        "--lights",
        "30@0,90",
        "--held-out",
        "45@45",
        "--spp",
        "1",
        "--storage",
        "u8",
    ]
    assert cli.main([*fit, "--out", str(tmp_path / "f")]) == 0
    assert cli.main(["export-textures", str(tmp_path / "f"), "--out", str(tmp_path / "tf")]) == 0
    described = json.loads((tmp_path / "tf" / "textures.json").read_text())["files"]
    assert set(described) == {"horizon0.ktx2", "horizon1.ktx2"}
    assert described["horizon0.ktx2"]["format"] == "VK_FORMAT_R8G8B8A8_UNORM"


def test_a_folder_without_a_bake_is_one_line_and_nothing_is_written(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    assert cli.main(["export-textures", str(tmp_path / "empty"), "--out", str(tmp_path / "o")]) == 2
    one_line(capsys.readouterr().err, "holds no bake")
    assert not (tmp_path / "o").exists()


def test_an_out_that_holds_other_files_is_refused(bc7_sweep, tmp_path, capsys):
    out = tmp_path / "o"
    out.mkdir()
    (out / "mine.txt").write_text("keep")
    assert cli.main(["export-textures", str(bc7_sweep), "--out", str(out)]) == 2
    assert (out / "mine.txt").read_text() == "keep" and not list(out.glob("*.ktx2"))
    capsys.readouterr()


def test_a_ktx2_layer_that_is_not_rgba_is_one_line(tmp_path):
    from hzval.io import external

    ktx2.write(tmp_path / "r.ktx2", texture("R8_UNORM"))
    with pytest.raises(InputError, match="must be RGBA"):
        external.read_layers([Path(tmp_path / "r.ktx2")])


def test_an_8_bit_export_is_within_half_a_level_of_the_bake(tmp_path, variant):
    from hzval.bake import maps as bake

    run = tmp_path / "s"
    assert cli.main([*SWEEP, "--techniques", "horizon", "--horizon-storage", "u8", "--out", str(run)]) == 0
    assert cli.main(["export-textures", str(run), "--out", str(tmp_path / "t")]) == 0
    sines = bake.read_bake(run / "bake").horizon
    for i in range(2):
        p = oracle.parse((tmp_path / "t" / f"horizon{i}.ktx2").read_bytes())
        assert p.vk_format == ktx2.FORMATS["R8G8B8A8_UNORM"].vk
        offset, length, _ = p.levels[0]
        texels = np.frombuffer(p.raw[offset : offset + length], np.uint8).reshape(64, 64, 4) / 255.0
        assert np.abs(texels - sines[..., 4 * i : 4 * i + 4]).max() <= 0.5 / 255 + 1e-6
