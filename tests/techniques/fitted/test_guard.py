"""The fit's guard (hzval.techniques.fitted.guard): a texel keeps its fitted sines only where no training
light
nearby does worse than with the bake.

Synthetic error maps check the neighbourhood (wrap and open), the reverting, the rounds and the
block granularity; a real fit of a small brick wall checks, through the sweep's own render, that
on every training light no kept texel's neighbourhood regresses beyond the tolerance.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hzval.bake import maps as bake
from hzval.scene import spec as sc
from hzval.techniques import horizon
from hzval.techniques.fitted import fit
from hzval.techniques.fitted import guard as fit_guard
from hzval.techniques.fitted import training as fitted_training


def test_neighbourhood_sum_wraps_or_cuts():
    x = np.zeros((5, 6), np.float32)
    x[0, 0] = 1.0
    wrap = fit_guard.neighbourhood_sum(x, "wrap")
    assert wrap.sum() == 9 and wrap[4, 5] == 1 and wrap[1, 1] == 1 and wrap[2, 2] == 0
    cut = fit_guard.neighbourhood_sum(x, "open")
    assert cut.sum() == 4 and cut[4, 5] == 0 and cut[1, 1] == 1
    y = np.arange(30, dtype=np.float32).reshape(5, 6)
    # the transpose's neighbourhood sum is the neighbourhood sum's transpose
    np.testing.assert_array_equal(
        fit_guard.neighbourhood_sum(y.T.copy(), "wrap"), fit_guard.neighbourhood_sum(y, "wrap").T
    )


def _errors_from(maps):
    """An ``errors`` callable: per light, |F - V| of a map is ``maps[light](sines)``."""

    def errors(sines, baked):
        return [m(sines) for m in maps]

    return errors


def test_a_regressing_texel_and_its_neighbours_go_back_to_the_bake():
    n = 12
    baked = np.zeros((n, n, 8), np.float32)
    fitted = np.full((n, n, 8), 0.5, np.float32)

    # light 0: the fit is better everywhere; light 1: worse at texel (6, 6) only, by 0.3
    def light0(s):
        return np.where(s[..., 0] > 0, 0.0, 0.1).astype(np.float32)

    def light1(s):
        e = np.zeros((n, n), np.float32)
        e[6, 6] = 0.3 if s[6, 6, 0] > 0 else 0.0
        return e

    out, rec = fit_guard.guard(baked, fitted, _errors_from([light0, light1]), "wrap", tolerance=0.05)
    reverted = out[..., 0] == 0
    assert reverted[5:8, 5:8].all() and reverted.sum() == 9  # the 3 x 3 whose pixels read it
    assert (out[~reverted] == 0.5).all() and rec["kept_fitted"] == pytest.approx(1 - 9 / n**2)
    assert rec["verified"] and rec["worst_regression_kept"] <= 0.05
    # within the tolerance nothing goes back
    out, rec = fit_guard.guard(baked, fitted, _errors_from([light0, light1]), "wrap", tolerance=0.5)
    assert (out == fitted).all() and rec["kept_fitted"] == 1.0 and rec["rounds"] == 1


def test_a_block_format_reverts_whole_blocks():
    n = 12
    baked, fitted = np.zeros((n, n, 8), np.float32), np.ones((n, n, 8), np.float32)

    def light(s):
        e = np.zeros((n, n), np.float32)
        e[5, 5] = 1.0 if s[5, 5, 0] > 0 else 0.0
        return e

    out, _ = fit_guard.guard(baked, fitted, _errors_from([light]), "open", cell=4)
    reverted = out[..., 0] == 0
    assert reverted[4:8, 4:8].all() and reverted.sum() == 16  # the 3 x 3 lies in one 4 x 4 block


def test_a_real_fit_regresses_nowhere_beyond_the_tolerance(variant):
    from hzval.materials.bricks import bricks

    n = 24
    scene = sc.override(sc.Scene(), size=n, depth=0.1, spp=2, effects="shadow")
    h = bricks(n)
    b = bake.bake(h, bake.BakeParams(depth=0.1).validate())
    lights = "20,40@0:270:90"
    r = fit.fit(h, b, scene, lights=lights, held_out="", guard=fit_guard.TOLERANCE, progress=False)
    g = r.settings["guard"]
    assert g["verified"] and 0 < g["kept_fitted"] < 1
    kept = np.any(r.horizon != b.horizon, axis=-1)
    V = fitted_training.visibility(scene, h, r.lights)
    fs = fitted_training.fit_scene(scene)
    base = horizon.Horizon(fs, b, None)
    own = horizon.Horizon(fs, dataclasses.replace(b, horizon=r.horizon), None)
    for (e, az), v in zip(r.lights, V):
        d = np.abs(own.render(az, elevation_deg=e).layers["factor"] - v) - np.abs(
            base.render(az, elevation_deg=e).layers["factor"] - v
        )
        worst = fit_guard.neighbourhood_sum(d.astype(np.float32), "wrap")
        assert worst[kept].max() <= fit_guard.TOLERANCE + 1e-5
    assert r.mae["training"]["fitted"] < r.mae["training"]["baked"]


def test_cli_guard_is_recorded_and_a_bad_one_refused(variant, tmp_path, capsys):
    import json

    from hzval.cli import main as cli

    out = tmp_path / "fit"
    assert cli.main(["fit", "--material", "bricks", "--size", "16", "--guard", "-1", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--guard" in err[0] and not out.exists()
    assert (
        cli.main(
            [
                "fit",
                "--material",
                "bricks",
                "--size",
                "16",
                "--lights",
                "20,40@0:270:90",
                "--held-out",
                "",
                "--guard",
                "0.1",
                "--quiet",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    record = json.loads((out / "fit.json").read_text())
    assert record["settings"]["guard"]["tolerance"] == 0.1 and record["settings"]["guard"]["verified"]
    assert record["mae"]["training"]["lights_worse"] >= 0 and "cpu" in record["seconds"]
