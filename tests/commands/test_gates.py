"""Gates (hzval.commands.gates): --fail-if conditions, the --baseline test, and both on real sweeps."""

from __future__ import annotations

import json

import pytest

from hzval.cli import main as cli
from hzval.commands import gates
from hzval.core.errors import InputError


def _frame(az, **techniques):
    return {
        "azimuth_deg": az,
        "truth_s": 0.5,
        "floor": {"flip_mean": 0.01},
        "truth": {"visibility_se": 1e-4, "partial_fraction": 0.01, "attached_fraction": 0.2},
        "techniques": {name: dict(values) for name, values in techniques.items()},
    }


def _metrics(frames, seed=0, spp=4):
    names = list(frames[0]["techniques"])
    return {
        "material": {"digest": "sha256:aa", "rows": 32, "cols": 32},
        "parameters": {
            "depth": 0.05,
            "spp": spp,
            "seed": seed,
            "azimuths_deg": [f["azimuth_deg"] for f in frames],
        },
        "techniques": {n: {} for n in names},
        "frames": frames,
    }


SWEEP = _metrics(
    [
        _frame(
            -30,
            horizon={"flip_mean": 0.02, "visibility_mae": 0.010},
            pom={"flip_mean": 0.01, "visibility_mae": 0.004},
        ),
        _frame(
            0,
            horizon={"flip_mean": 0.05, "visibility_mae": 0.030},
            pom={"flip_mean": 0.01, "visibility_mae": 0.040},
        ),
        _frame(
            30,
            horizon={"flip_mean": 0.08, "visibility_mae": 0.020, "psnr_db": None},
            pom={"flip_mean": 0.01, "visibility_mae": 0.010},
        ),
    ]
)


@pytest.mark.parametrize(
    "text, per_frame",
    [
        ("horizon.flip_mean>0.1", True),
        ("mean(horizon.flip_mean) >= 0.05", False),
        ("pom.visibility_mae>horizon.visibility_mae", True),
        ("max(terrain.leak_fraction)<1e-3", False),
        ("0.5<=truth_s", True),
    ],
)
def test_conditions_parse(text, per_frame):
    c = gates.parse(text)
    assert c.per_frame == per_frame and c.op in (">", ">=", "<", "<=")


@pytest.mark.parametrize(
    "text",
    [
        "horizon.flip_mean",
        "horizon.flip_mean>>1",
        "1>2",
        "horizon.flip_mean>abc(",
        "sum(horizon.flip_mean)>1",
        "horizon.flip_mean>0.1>0.2",
    ],
)
def test_bad_conditions_are_one_line_naming_the_flag(text):
    with pytest.raises(InputError) as e:
        gates.parse(text)
    assert e.value.what == "--fail-if" and "\n" not in str(e.value)


def test_per_frame_conditions_name_the_frames_that_fail():
    (line,) = gates.evaluate(gates.parse("horizon.flip_mean>0.04"), SWEEP)
    assert "2 of 3 frames" in line and "az+0 0.05" in line and "az+30 0.08" in line and "az-30" not in line
    assert gates.evaluate(gates.parse("horizon.flip_mean>0.08"), SWEEP) == []  # strict: 0.08 is not > 0.08
    assert gates.evaluate(gates.parse("horizon.flip_mean>=0.08"), SWEEP) != []
    (line,) = gates.evaluate(gates.parse("pom.visibility_mae>horizon.visibility_mae"), SWEEP)
    assert "1 of 3 frames (az+0 0.04 vs 0.03)" in line
    # mirrored: the same comparison written the other way round fails on the same frame
    assert (
        gates.evaluate(gates.parse("horizon.visibility_mae<pom.visibility_mae"), SWEEP)[0].count("az+0") == 1
    )


def test_aggregates_and_missing_values():
    assert gates.evaluate(gates.parse("mean(horizon.flip_mean)>0.051"), SWEEP) == []  # the mean is 0.05
    (line,) = gates.evaluate(gates.parse("max(horizon.flip_mean)>0.05"), SWEEP)
    assert "the sweep's max(horizon.flip_mean) = 0.08" in line
    assert gates.evaluate(gates.parse("mean(pom.flip_mean)<mean(horizon.flip_mean)"), SWEEP) != []
    assert gates.evaluate(gates.parse("horizon.psnr_db<100"), SWEEP) == []  # null: not tested
    with pytest.raises(InputError, match="did you mean horizon.flip_mean"):
        gates.evaluate(gates.parse("horizon.flp_mean>0"), SWEEP)
    (line,) = gates.evaluate(gates.parse("floor.flip_mean>=0.01"), SWEEP)
    assert "3 of 3" in line


def _scaled(metrics, factor, name="horizon", seed=0):
    frames = [
        {
            **f,
            "techniques": {
                **f["techniques"],
                name: {
                    k: (v * factor if isinstance(v, float) else v) for k, v in f["techniques"][name].items()
                },
            },
        }
        for f in metrics["frames"]
    ]
    return _metrics(frames, seed=seed)


def test_the_baseline_test_fails_a_regression_and_nothing_else():
    same = gates.baseline_tests(SWEEP, SWEEP)
    assert same and gates.regressions(same) == []  # the same run: no change
    worse = gates.baseline_tests(_scaled(SWEEP, 1.1), SWEEP)  # horizon 10% worse everywhere
    lines = gates.regressions(worse)
    assert any("horizon.flip_mean regressed" in line for line in lines)
    assert any("horizon.visibility_mae regressed" in line for line in lines)
    assert not any("pom." in line for line in lines)
    better = gates.baseline_tests(_scaled(SWEEP, 0.9), SWEEP)  # an improvement is no failure
    assert gates.regressions(better) == []
    tiny = gates.baseline_tests(_scaled(SWEEP, 1.005), SWEEP)  # below the 1% tolerance
    assert gates.regressions(tiny) == []


def test_another_seed_is_tested_against_the_truths_noise():
    """With another seed the truth's noise moves |F-V| by about visibility_se per frame: a change of
    that size is not a regression, one of 30 standard errors is."""
    noisy = _metrics(
        [
            {
                **f,
                "techniques": {
                    **f["techniques"],
                    "horizon": {
                        **f["techniques"]["horizon"],
                        "visibility_mae": f["techniques"]["horizon"]["visibility_mae"] + 1.5e-4,
                    },
                },
            }
            for f in SWEEP["frames"]
        ],
        seed=7,
    )
    assert not [
        t
        for t in gates.baseline_tests(noisy, SWEEP)
        if t["metric"] == "visibility_mae" and gates.regressions([t], n_tests=1)
    ]
    far = _metrics(
        [
            {
                **f,
                "techniques": {
                    **f["techniques"],
                    "horizon": {
                        **f["techniques"]["horizon"],
                        "visibility_mae": f["techniques"]["horizon"]["visibility_mae"] + 3e-3,
                    },
                },
            }
            for f in SWEEP["frames"]
        ],
        seed=7,
    )
    (t,) = [
        t
        for t in gates.baseline_tests(far, SWEEP)
        if t["technique"] == "horizon" and t["metric"] == "visibility_mae"
    ]
    assert not t["same_truth"] and gates.regressions([t], n_tests=1)


def test_a_baseline_of_other_settings_is_refused():
    other = _metrics(SWEEP["frames"], spp=16)
    with pytest.raises(InputError, match="spp 16, this run's 4"):
        gates.check_same_settings(SWEEP, other, "base")
    with pytest.raises(InputError, match="no metrics.json"):
        gates.read_baseline("/nonexistent/folder")


ARGS = ("sweep", "--size", "32", "--azimuths=-60:60:60", "--spp", "4", "--quiet")


def test_gates_on_real_sweeps(variant, tmp_path, capsys):
    """A threshold exits 1 naming the frames and is listed at the top of the report; a rerun against
    the first run as baseline exits 0, a softer horizon (k 2) against it 1; a baseline of another scene
    exits 2 and writes nothing."""
    first = tmp_path / "first"
    assert cli.main([*ARGS, "--out", str(first), "--fail-if", "horizon.flip_mean>0.004"]) == 1
    err = capsys.readouterr().err
    assert "gate failed: --fail-if horizon.flip_mean>0.004:" in err and "az-60" in err
    m = json.loads((first / "metrics.json").read_text())
    assert m["gates"]["failed"] and m["gates"]["conditions"] == ["horizon.flip_mean>0.004"]
    html = (first / "index.html").read_text(encoding="utf-8")
    assert html.index("gate failed") < html.index('id="summary"') and "exit 1" in html
    assert cli.main([*ARGS, "--out", str(tmp_path / "again"), "--baseline", str(first)]) == 0
    assert (
        cli.main([*ARGS, "--out", str(tmp_path / "soft"), "--baseline", str(first), "--horizon-k", "2"]) == 1
    )
    err = capsys.readouterr().err
    assert "--baseline: horizon." in err and "regressed" in err and "pom." not in err
    assert cli.main([*ARGS, "--spp", "9", "--out", str(tmp_path / "other"), "--baseline", str(first)]) == 2
    assert "--baseline:" in capsys.readouterr().err and not (tmp_path / "other").exists()


def test_another_seed_alone_is_no_image_regression(variant, tmp_path):
    """Two sweeps that differ only in their seed: every frame of the second is read at the second
    seed's sample positions, which shifts its image scores alike. That shift is no regression (the
    frames' scatter used to stand in for the noise: PSNR 'regressed' at p 1e-11)."""
    from hzval.cli import main as cli

    argv = ["sweep", "--material", "gravel", "--size", "32", "--elevation", "20"]
    argv += ["--azimuths", "0,90,180,270", "--spp", "2", "--techniques", "horizon", "--quiet"]
    assert cli.main([*argv, "--out", str(tmp_path / "a")]) == 0
    assert (
        cli.main([*argv, "--seed", "1", "--out", str(tmp_path / "b"), "--baseline", str(tmp_path / "a")]) == 0
    )
    tests = json.loads((tmp_path / "b" / "metrics.json").read_text())["gates"]["tests"]
    image = [t for t in tests if t["metric"] in ("psnr_db", "rmse", "flip_mean", "delta_e2000_mean")]
    assert image and all(t["p"] is None for t in image)
    assert any(t["p"] is not None for t in tests if t["metric"] == "visibility_mae")  # still tested
