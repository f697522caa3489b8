"""The built-in materials: a registry of distinct, exactly tileable shapes with their albedo."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy import ndimage

from hzval import materials
from hzval.cli import main as cli
from hzval.core import conventions as cv
from hzval.materials import cobblestones, fabric, noise, panels, planks, spikes
from hzval.scene import files as scene_files
from hzval.scene import spec as sc

NAMES = materials.names()
WRAPPING = [n for n in NAMES if materials.get(n).boundary == "wrap"]


def test_registry_lists_the_figure_5_2_variety():
    assert set(NAMES) >= {
        "bricks",
        "cobblestones",
        "gravel",
        "fabric",
        "panels",
        "planks",
        "ridges",
        "spikes",
    }
    for name in NAMES:
        m = materials.get(name)
        assert m.name == name and m.label and m.summary and m.depth > 0 and m.boundary in ("wrap", "open")
    assert materials.get("ridges").boundary == "open"
    with pytest.raises(KeyError, match="cobblestones"):
        materials.get("marble")


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("shape", [(64, 64), (48, 80), (8, 8)])
def test_height_and_albedo_are_in_range(name, shape):
    g = materials.generate(name, shape)
    assert g.height.shape == shape and g.height.dtype == np.float32
    assert np.isfinite(g.height).all() and 0.0 <= g.height.min() and g.height.max() <= 1.0
    if name != "bricks":  # the bricks keep the scene's constant albedo
        assert g.albedo.shape == (*shape, 3) and g.albedo.dtype == np.float32
        assert 0.0 < g.albedo.min() and g.albedo.max() < 1.0
    assert not g.height.flags.writeable  # cached arrays cannot be changed under a later caller


@pytest.mark.parametrize("name", NAMES)
def test_deterministic_and_seeded(name):
    make = materials.get(name).make
    a, _ = make((64, 64), 3)
    b, _ = make((64, 64), 3)
    c, _ = make((64, 64), 4)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def _seam_statistic(h: np.ndarray) -> tuple[float, float]:
    """Largest jump across the wrap edges, and the largest jump inside the map."""
    wrap = max(np.abs(h[-1] - h[0]).max(), np.abs(h[:, -1] - h[:, 0]).max())
    inner = max(np.abs(np.diff(h, axis=0)).max(), np.abs(np.diff(h, axis=1)).max())
    return float(wrap), float(inner)


@pytest.mark.parametrize("name", WRAPPING)
@pytest.mark.parametrize("shape", [(128, 128), (96, 160), (97, 131)])
def test_wrapping_materials_tile_without_a_seam(name, shape):
    """Across the wrap edges, neighbours differ by no more than neighbours anywhere inside the map:
    the largest interior jump is the yardstick (steep rims make it generous, so a seam test follows)."""
    wrap, inner = _seam_statistic(materials.generate(name, shape).height)
    assert wrap <= inner


@pytest.mark.parametrize("name", ["bricks", "cobblestones", "fabric", "planks", "ridges"])
def test_the_seam_statistic_sees_a_seam(name):
    """The same statistic on a map that does not tile (the right half moved down by 29 rows, so a cut
    runs down the middle and across the wrap) must fail, or the test above proves nothing. (Not for
    the panels and spikes: a cut through their flat plates and ground is too gentle for it to see.)"""
    h = materials.generate(name, 128).height
    broken = np.concatenate([h[:, :64], np.roll(h, 29, axis=0)[:, 64:]], axis=1)
    wrap, inner = _seam_statistic(np.roll(broken, -64, axis=1))  # the cut now on the wrap edge
    assert wrap > _seam_statistic(h)[1]


def test_materials_are_distinct_shapes():
    maps = {n: materials.generate(n, 128).height for n in NAMES}
    for a in NAMES:
        for b in NAMES:
            if a < b:
                r = np.corrcoef(maps[a].ravel(), maps[b].ravel())[0, 1]
                assert abs(r) < 0.5, (a, b, r)


# --------------------------------------------------------------------------
# Each shape is the one it says it is
# --------------------------------------------------------------------------


def _blobs(mask: np.ndarray) -> int:
    """Connected components of ``mask`` on the torus (labels that meet across an edge are merged)."""
    labels, n = ndimage.label(mask)
    parent = list(range(n + 1))

    def find(i):
        while parent[i] != i:
            i = parent[i]
        return i

    for a, b in list(zip(labels[0], labels[-1])) + list(zip(labels[:, 0], labels[:, -1])):
        if a and b:
            parent[find(a)] = find(b)
    return len({find(i) for i in range(1, n + 1)})


def test_spikes_are_one_thin_cone_per_cell():
    h, _ = spikes.spikes(512)
    n = noise.count(512, spikes._ACROSS, spikes._MIN_PX)
    assert _blobs(h > 0.3) == n * n
    # thin: each cone's footprint is a disk of 14% of a cell in radius; tall: its top is at least 0.6
    r = spikes._RADIUS * 512 / n
    assert (h > 0.1).mean() < n * n * np.pi * r * r / 512**2
    labels, count = ndimage.label(h > 0.05)
    index = np.arange(1, count + 1)
    tops = np.asarray(ndimage.maximum(h, labels, index))
    assert np.min(tops[tops > 0.3]) > 0.5 * 0.6
    # at the default depth the tallest cone stands more than twice as tall as its footprint is wide
    width = 2 * np.sqrt(np.asarray(ndimage.sum(np.ones_like(h), labels, index)) / np.pi)  # texels
    tall = cv.heights_in_texels(h, spikes.MATERIAL.depth).max()
    assert tall > 2 * width[np.argmax(tops)]


def test_cobblestones_are_one_dome_per_cell_in_sand():
    h, albedo = cobblestones.cobblestones(256)
    n = noise.count(256, cobblestones._ACROSS, cobblestones._MIN_PX)
    assert _blobs(h > cobblestones._SAND + 0.2) == n * n
    sand = h < cobblestones._SAND + 0.05
    assert 0.02 < sand.mean() < 0.3  # joints between the stones
    # rounded: a stone's height rises all the way from its edge to its middle (a dome, not a block)
    c = noise.cells(np.random.default_rng(1), (256, 256), (n, n), jitter=0.7)
    inner = c.edge > 0.3 * c.cell_w
    rim = (c.edge > 0.1 * c.cell_w) & (c.edge < 0.15 * c.cell_w)
    assert h[inner].mean() > h[rim].mean() + 0.05


def test_fabric_warp_passes_over_where_its_parity_says():
    """Warp i is over weft j where i + j is even: there the crossing shows the warp's colour (blue),
    elsewhere the weft's (ochre); either way the crossing is high and the holes between threads low."""
    size = 192
    h, albedo = fabric.fabric(size)
    n = noise.count(size, fabric._ACROSS, fabric._MIN_PX, even=True)
    pitch = size / n
    for i in range(n):
        for j in range(n):
            x, y = int((i + 0.5) * pitch), int((j + 0.5) * pitch)  # crossing of warp i and weft j
            r, _, b = albedo[y, x]
            assert (b > r) == ((i + j) % 2 == 0), (i, j)
            assert h[y, x] > 0.8
    holes = h[(np.arange(n) * pitch).astype(int)][:, (np.arange(n) * pitch).astype(int)]
    assert holes.max() < 0.5


def test_panels_have_four_rows_of_rivets_per_panel_and_seams():
    h, _ = panels.panels(512)
    g = noise.count(512, panels._ACROSS, panels._MIN_PX)
    rivets = h > panels._PLATE + 0.05 + 0.12  # well above the plate, its bulge and dents
    per_panel = 4 * panels._RIVETS  # corners are shared by two rows
    assert _blobs(rivets) == g * g * per_panel
    assert np.isclose(h[0, 256 + 64], panels._SEAM, atol=0.02)  # a seam runs along the tile's edge


def test_planks_have_grooves_between_rows():
    h, _ = planks.planks(240)
    n = noise.count(240, planks._ROWS, planks._MIN_ROW_PX)
    edges = (np.arange(n) * 240 / n).astype(int)
    # the texel row at a board edge lies half a texel up the V groove's wall: far below the boards
    assert np.all(h[edges].mean(axis=1) < planks._GROOVE + 0.2)
    assert np.median(h) > 0.6


# --------------------------------------------------------------------------
# Scenes, the command line
# --------------------------------------------------------------------------


def test_a_scene_takes_its_materials_depth_boundary_and_albedo():
    s = sc.override(sc.Scene(), height="ridges", size=32)
    assert (s.material.depth, s.material.boundary) == (0.08, "open")
    a = sc.load_albedo(s.material, 32, 32)
    np.testing.assert_array_equal(a, materials.generate("ridges", 32).albedo)
    assert sc.override(sc.Scene(), height="ridges", depth=0.02).material.depth == 0.02
    # back to the bricks: their own defaults again, and the constant albedo
    b = sc.override(s, height="bricks")
    assert (b.material.depth, b.material.boundary) == (0.05, "wrap")
    assert np.all(sc.load_albedo(b.material, 8, 8) == sc.DEFAULT_ALBEDO)


def test_scene_files_name_built_in_materials(tmp_path):
    p = tmp_path / "s.toml"
    p.write_text('[material]\nheight = "spikes"\nsize = 16\n')
    s = scene_files.load_scene(p)
    assert s.material.height == "spikes" and s.material.depth == materials.get("spikes").depth
    p.write_text('[material]\nheight = "spikes"\nsize = 4\n')
    with pytest.raises(Exception, match="at least 8"):
        scene_files.load_scene(p)


def test_hzval_materials_lists_them(capsys):
    assert cli.main(["materials"]) == 0
    out = capsys.readouterr().out
    for name in NAMES:
        assert name in out


def test_sweep_of_a_built_in_material(variant, tmp_path, capsys):
    out = tmp_path / "o"
    assert (
        cli.main(
            [
                "sweep",
                "--material",
                "gravel",
                "--size",
                "24",
                "--azimuths",
                "0",
                "--techniques",
                "horizon",
                "--out",
                str(out),
                "--quiet",
            ]
        )
        == 0
    )
    import json

    m = json.loads((out / "metrics.json").read_text())
    assert m["material"]["name"] == "gravel" and m["parameters"]["depth"] == materials.get("gravel").depth
    assert cli.main(["sweep", "x.png", "--material", "gravel", "--out", str(out)]) == 2
    assert "not both" in capsys.readouterr().err


def test_export_writes_a_built_in_materials_albedo(variant, tmp_path):
    from hzval.commands import export_scene

    s = sc.override(sc.Scene(), height="planks", size=16)
    written = export_scene.write_scene(s, materials.generate("planks", 16).height, tmp_path)
    assert tmp_path / "albedo.png" in written
    s2 = dataclasses.replace(s, material=dataclasses.replace(s.material, albedo=0.5))
    assert tmp_path / "albedo.png" not in export_scene.write_scene(
        s2, materials.generate("planks", 16).height, tmp_path / "b"
    )
