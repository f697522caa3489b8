"""The Technique interface and its registry (hzval.techniques.registry).

Every registered technique builds from a Context and renders frames of the
documented form; selection follows the declared effects; and a technique
added by one registry line - here a toy that never shadows, defined in this
file - reaches the sweep, metrics.json, the report, the terminal table, the
check and the tradeoff with no other change, and its scores are the ones
its factor implies (F = 1: |F - V| = mean(1 - V), no false shadows).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from hzval.bake import maps as bake
from hzval.cli import main as cli
from hzval.commands import check, tradeoff
from hzval.core.errors import InputError
from hzval.pipeline import sweep
from hzval.scene import spec as sc
from hzval.scene.spec import Frame
from hzval.techniques import registry as technique
from hzval.techniques import surface


class NeverShadow(technique.Technique):
    """A toy technique: the unshadowed shading everywhere (F = 1)."""

    name = "never"
    label = "never shadows"
    summary = "a test's technique: F = 1 everywhere"
    file_stem = "never"

    def __init__(self, ctx):
        self.simulated = self.simulates(ctx.scene)
        self._plain = surface.unshadowed(ctx)

    @classmethod
    def build(cls, ctx, **settings):
        return cls(ctx)

    def render(self, azimuth_deg, *, elevation_deg=None) -> Frame:
        frame, _ = self._plain.render(azimuth_deg, elevation_deg)
        return self._plain.shade(azimuth_deg, elevation_deg, np.ones(frame.image.shape[:2], np.float32), 0.0)


@pytest.fixture
def with_toy(monkeypatch):
    monkeypatch.setitem(technique.REGISTRY, "never", f"{__name__}:NeverShadow")


def small_context(effects=("shadow", "diffuse"), n=24):
    from hzval.materials.bricks import bricks

    scene = sc.override(sc.Scene(), size=n, depth=0.2, effects=",".join(effects), spp=2, azimuths="0")
    h = bricks(n)
    params = bake.BakeParams(depth=scene.material.depth)
    return technique.Context(scene, h, bake.bake(h, params), sc.load_albedo(scene.material, n, n))


@pytest.mark.parametrize("name", technique.names())
def test_every_technique_renders_a_documented_frame(variant, name):
    ctx = small_context()
    try:
        t = technique.get(name).build(ctx)
    except technique.Unavailable as e:  # the GLSL ones, where no OpenGL 3.3 context can be made
        pytest.skip(str(e))
    assert t.name == name and technique.get(name).applies(ctx.scene)
    assert set(t.simulated) <= set(ctx.scene.effects)
    f = t.render(30.0)
    assert f.image.shape == (24, 24, 3) and f.image.dtype == np.float32 and np.isfinite(f.image).all()
    F = f.layers["factor"]
    assert F.shape == (24, 24) and F.min() >= 0 and F.max() <= 1 and F.min() < 1  # the bricks cast shadows
    assert f.seconds > 0
    json.dumps(t.parameters)  # metrics.json can hold it
    # what it reads besides the normal map, which every technique shades with: the terminator term
    # reads nothing more
    assert t.storage_bytes() > 0 or getattr(t, "textures", None) == ()


def test_selection_follows_the_declared_effects(variant):
    lit = small_context(("diffuse",)).scene
    assert [t.name for t in technique.select(None, lit)] == [
        n for n in technique.names() if not technique.get(n).needs and technique.get(n).by_default
    ]
    shadowed = small_context().scene
    assert [t.name for t in technique.select(None, shadowed)] == [
        n for n in technique.names() if technique.get(n).by_default
    ]
    assert [t.name for t in technique.select(None, shadowed, exclude=("terrain",))] == [
        n for n in technique.names() if n != "terrain" and technique.get(n).by_default
    ]
    assert "horizon-fit" not in technique.defaults()  # opt-in: only by name
    assert [t.name for t in technique.select(["horizon-fit", "horizon"], shadowed)] == [
        "horizon",
        "horizon-fit",
    ]
    with pytest.raises(InputError, match="needs the scene to declare shadow"):
        technique.select(["terrain"], lit)
    with pytest.raises(InputError, match="unknown technique 'nope'"):
        technique.select(["nope"], shadowed)


def test_one_registry_line_adds_a_technique_everywhere(variant, with_toy, tmp_path, capsys):
    out = tmp_path / "out"
    assert (
        cli.main(
            ["sweep", "--size", "24", "--azimuths", "-30,30", "--spp", "2", "--quiet", "--out", str(out)]
        )
        == 0
    )
    table = capsys.readouterr().out
    m = json.loads((out / "metrics.json").read_text())
    assert "never" in m["techniques"] and m["simulated"]["never"] == ["shadow", "diffuse"]
    from hzval.io import codecs

    for f in m["frames"]:
        own = f["techniques"]["never"]
        V = codecs.read_exr(out / f["files"]["visibility"])["Y"].astype(np.float64)
        assert own["visibility_mae"] == pytest.approx(np.mean(1.0 - V), abs=1e-6)
        assert own["false_shadow_fraction"] == 0.0
        assert own["leak_fraction"] == pytest.approx(np.mean(V < 0.5), abs=1e-9)
        assert (out / own["files"]["visdiff_png"]).is_file()
    html = (out / "index.html").read_text(encoding="utf-8")
    assert "never shadows" in html and "never |F−V|" in html and "never_flip.png" in html
    assert any(line.split()[:1] == ["never"] for line in table.splitlines()[2:])
    # the command line knows it too: --no-never leaves it out
    assert (
        cli.main(
            [
                "sweep",
                "--size",
                "24",
                "--azimuths",
                "0",
                "--spp",
                "1",
                "--no-never",
                "--quiet",
                "--out",
                str(tmp_path / "out2"),
            ]
        )
        == 0
    )
    assert "never" not in json.loads((tmp_path / "out2" / "metrics.json").read_text())["techniques"]
    # the check guards it, and the tradeoff measures it
    scene = check.check_scene(sc.override(sc.Scene(), size=24, azimuths="0", spp=1))
    assert "never" in check.renderers(scene, __import__("hzval.materials.bricks").materials.bricks.bricks(24))
    assert any(s.technique == "never" for s in tradeoff.settings(scene))


def test_options_defaults_are_the_bakes():
    o = sweep.Options()
    d = bake.BakeParams()
    assert (o.radius, o.angles, o.method, o.directions) == (d.radius, d.angles, d.method, d.directions)
