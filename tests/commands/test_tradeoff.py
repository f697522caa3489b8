"""``hzval tradeoff``: every point measured, honest orderings, the Pareto front and the recommendation."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from hzval.cli import main as cli
from hzval.commands import tradeoff
from hzval.commands.tradeoff import Point
from hzval.scene.spec import MaterialSpec, Scene
from hzval.techniques import horizon

POINT_KEYS = {"name", "kind", "time_s", "storage_bytes", "visibility_mae", "flip_mean", "pareto"}


def wall_scene_and_height():
    """Walls 12 texels high every 32 texels: at 30 degrees their shadows are 20.8 texels long,
    longer than a radius-4 or radius-8 search sees."""
    h = np.zeros((32, 64), np.float32)
    h[:, ::32] = 1.0
    scene = Scene(
        name="walls",
        material=MaterialSpec(height="walls.npy", size=64, depth=12 / 64, boundary="wrap"),
        spp=4,
    )
    scene = dataclasses.replace(scene, light=dataclasses.replace(scene.light, azimuths_deg=(0.0, 180.0)))
    return scene, h


@pytest.fixture(scope="module")
def wall_points(variant):
    scene, h = wall_scene_and_height()
    only = [
        "(default)",
        "seed r4",
        "seed r8",
        "seed r32",
        "8-bit",
        "GPU path",
        "k = 2",
        "k = 32",
        "fitted",
        "truth, 1 ",
        "truth, 16",
    ]
    points, info = tradeoff.measure(scene, h, truth_spp=64, only=only)
    return {p.name: p for p in points}, info


def test_at_least_ten_points_with_every_field(wall_points):
    points, info = wall_points
    assert len(points) >= 10
    for p in points.values():
        d = p.as_dict()
        assert POINT_KEYS <= set(d)
        assert p.kind in tradeoff.KINDS
        assert p.time_s > 0 and p.storage_bytes > 0
        assert 0 <= p.visibility_mae <= 1 and 0 <= p.flip_mean <= 1
    assert info["truth_spp"] == 64


def test_a_short_radius_misses_long_shadows(wall_points):
    points, _ = wall_points
    r4, r8, r16, r32 = (
        points[n].visibility_mae for n in ("seed r4", "seed r8", "seed r16, 32 bins (default)", "seed r32")
    )
    assert r4 > r8 > r16 + 0.01  # shadows 20.8 texels long
    assert r32 <= r16 + 1e-6


def test_storage_of_8_bit_maps_and_the_cube(wall_points):
    points, _ = wall_points
    float_bytes = points["seed r16, 32 bins (default)"].storage_bytes
    assert float_bytes == 32 * 64 * 8 * 4
    assert points["8-bit horizon map"].storage_bytes == float_bytes // 4
    assert points["GPU path: 8-bit map + cube weights"].storage_bytes == float_bytes // 4 + horizon.CUBE_BYTES


def test_fitted_k_is_at_least_as_good_as_the_fixed_ones(wall_points):
    points, _ = wall_points
    fitted = points["k fitted to the truth"]
    for name in ("k = 2", "k = 32", "seed r16, 32 bins (default)"):
        assert fitted.visibility_mae <= points[name].visibility_mae + 1e-4, name
    assert 1 <= fitted.params["k"] <= 128


def test_the_truth_converges(wall_points):
    points, _ = wall_points
    one, sixteen = points["truth, 1 shadow ray per pixel"], points["truth, 16 shadow rays per pixel"]
    assert sixteen.visibility_mae < one.visibility_mae / 2
    # and every technique is further from the truth than a 16-ray truth
    assert all(p.visibility_mae > sixteen.visibility_mae for p in points.values() if p.kind != "truth")


def test_pareto_front_within_each_kind():
    pts = [
        Point("a", "bake", 1.0, 10, 0.1, 0),
        Point("b", "bake", 2.0, 10, 0.05, 0),
        Point("c", "bake", 2.0, 10, 0.2, 0),  # dominated by a and b
        Point("d", "technique", 9.0, 99, 0.9, 0),
    ]  # alone in its kind
    tradeoff.mark_pareto(pts)
    assert [p.pareto for p in pts] == [True, True, False, True]


def test_recommendation_takes_the_cheapest_within_tolerance():
    own = {"technique": "horizon"}
    pts = [
        Point("big (default)", "bake", 1.0, 1000, 0.100, 0, params=own),
        Point("small", "technique", 1.0, 100, 0.105, 0, params=own),
        Point("tiny but bad", "technique", 1.0, 10, 0.3, 0, params=own),
        Point("truth, 64", "truth", 1.0, 5, 0.005, 0, params={"spp": 64}),
    ]
    rec = tradeoff.recommend(pts)
    assert rec["setting"] == "small" and rec["best"] == "big (default)"
    assert rec["truth"] == "truth, 64"
    assert "own" not in rec  # the pick is a setting of the baked technique already
    assert rec["error_is"] == tradeoff.ERROR_IS[False]  # these points have no facing |F - V|
    pts.append(Point("terrain", "technique", 1.0, 50, 0.02, 0, params={"technique": "terrain"}))
    rec = tradeoff.recommend(pts)
    assert rec["setting"] == "terrain"
    assert rec["own"] == {
        "technique": "horizon",
        "setting": "small",
        "error": 0.105,
        "best": "big (default)",
        "best_error": 0.100,
    }


def test_cli_writes_json_plot_and_page(variant, tmp_path, capsys):
    out = tmp_path / "t"
    argv = [
        "tradeoff",
        "--size",
        "32",
        "--azimuths",
        "0,90",
        "--truth-spp",
        "16",
        "--spp",
        "4",
        "--only",
        "seed r4",
        "--only",
        "(default)",
        "--only",
        "8-bit horizon",
        "--quiet",
        "--out",
        str(out),
    ]
    assert cli.main(argv) == 0
    data = json.loads((out / "tradeoff.json").read_text())
    assert {p["name"] for p in data["points"]} == {
        "seed r4",
        "seed r16, 32 bins (default)",
        "8-bit horizon map",
    }
    for p in data["points"]:
        assert POINT_KEYS <= set(p)
    assert (out / "pareto.png").stat().st_size > 1000
    html = (out / "index.html").read_text()
    assert "Recommended" in html and "seed r4" in html
    assert "recommended:" in capsys.readouterr().out


def test_cli_rejects_an_empty_selection(variant, tmp_path, capsys):
    assert (
        cli.main(
            [
                "tradeoff",
                "--size",
                "16",
                "--azimuths",
                "0",
                "--truth-spp",
                "4",
                "--only",
                "nothing",
                "--quiet",
                "--out",
                str(tmp_path / "x"),
            ]
        )
        == 2
    )
    assert "no setting matches" in capsys.readouterr().err


@pytest.mark.slow
def test_full_tradeoff_of_the_builtin_material(variant, tmp_path):
    """Every setting, the built-in material at 64 px (slow: a converged truth and ~25 settings)."""
    out = tmp_path / "full"
    assert cli.main(["tradeoff", "--size", "64", "--truth-spp", "64", "--quiet", "--out", str(out)]) == 0
    data = json.loads((out / "tradeoff.json").read_text())
    assert len(data["points"]) >= 18


def test_the_headline_error_is_the_facing_one_where_measured():
    """The front and the recommendation read |F - V| over the pixels facing the light, as the sweep
    does; a point without one (another view) falls back on the whole image's."""
    a = Point("a", "technique", 1.0, 10, 0.30, 0, visibility_mae_facing=0.10)
    b = Point("b", "technique", 1.0, 10, 0.20, 0, visibility_mae_facing=0.15)
    assert (a.error, b.error) == (0.10, 0.15)
    tradeoff.mark_pareto([a, b])
    assert a.pareto and not b.pareto  # by the whole image b would win
    rec = tradeoff.recommend([a, b], tolerance=0.0)
    assert rec["setting"] == "a" and rec["error"] == 0.10 and rec["error_is"] == tradeoff.ERROR_IS[True]
    assert Point("c", "truth", 1.0, 1, 0.05, 0).error == 0.05
