"""The split of the horizon map's error (horizon-fit's ``split``) in the report and the terminal table.

A sweep with ``--techniques horizon,horizon-fit`` writes ``plots/horizon_fit_split.png`` and a
table of each frame's parts; the stacked bars' heights are the parts of ``metrics.json``, their
sum the baked map's |F - V|; a negative part (the fit worse than the bake on a frame) is drawn
hatched and flagged; a sweep without horizon-fit has no split.
"""

from __future__ import annotations

import copy

import pytest

from hzval.pipeline import records as pipeline_records
from hzval.pipeline import sweep
from hzval.report import columns as report_columns
from hzval.report import plots as report_plots
from hzval.scene import spec as sc

FEW = "20,40@0:270:90"


@pytest.fixture(scope="module")
def split_sweep(tmp_path_factory, request):
    request.getfixturevalue("variant")
    out = tmp_path_factory.mktemp("split")
    scene = sc.override(sc.Scene(), size=16, depth=0.1, spp=2, azimuths="0,45,90")
    opts = sweep.Options(
        techniques=("horizon", "horizon-fit"), settings={"horizon-fit": {"lights": FEW, "held_out": ""}}
    )
    return out, sweep.run(scene, out, options=opts, progress=False)


def test_the_report_shows_the_split_per_frame(split_sweep):
    out, m = split_sweep
    parts = m["techniques"]["horizon-fit"]["split_parts"]
    assert [p["key"] for p in parts] == ["representation", "bake_loss"]
    assert (out / "plots" / "horizon_fit_split.png").stat().st_size > 1000
    html = (out / "index.html").read_text()
    assert 'id="split-horizon-fit"' in html and "plots/horizon_fit_split.png" in html
    assert "what the bake loses" in html and "what eight directions cannot hold" in html
    for f in m["frames"]:
        s = f["techniques"]["horizon-fit"]["split"]
        assert f"{s['bake_loss']:.4f}" in html and f"{s['representation']:.4f}" in html
        # the parts sum to the baked map's error
        assert f"{f['techniques']['horizon']['visibility_mae']:.4f}" in html


def test_the_terminal_table_has_the_split(split_sweep):
    _, m = split_sweep
    text = pipeline_records.summary_table(m)
    line = " ".join(text[text.index("horizon-fit split:") :].split("\n  "))
    line = line.splitlines()[0]
    frames = [f["techniques"]["horizon-fit"]["split"] for f in m["frames"]]
    for k in ("representation", "bake_loss"):
        mean = sum(f[k] for f in frames) / len(frames)
        assert f"{k} {mean:.4f}" in line, (k, line)


def _captured_bars(monkeypatch, metrics):
    """The bars plot_split draws: ``(x, bottom, height, hatched)`` per bar."""
    figs = []
    monkeypatch.setattr(report_plots, "_save", lambda fig, path: figs.append(fig))
    views = report_columns.technique_views(metrics)
    (sv,) = report_plots.split_views(metrics, views)
    report_plots.plot_split(None, metrics["frames"], sv)
    ax = figs[0].axes[0]
    return [
        (round(p.get_x() + p.get_width() / 2, 6), p.get_y(), p.get_height(), bool(p.get_hatch()))
        for p in ax.patches
    ]


def test_the_bars_are_the_parts_and_a_negative_part_is_hatched(split_sweep, monkeypatch):
    _, m = split_sweep
    m = copy.deepcopy(m)
    frames = m["frames"]
    frames[1]["techniques"]["horizon-fit"]["split"] = {"representation": 0.03, "bake_loss": 0.02}
    frames[2]["techniques"]["horizon-fit"]["split"] = {"representation": 0.01, "bake_loss": -0.004}
    bars = _captured_bars(monkeypatch, m)
    at45 = sorted((b, h) for x, b, h, hatch in bars if x == 45.0 and h > 0 and not hatch)
    assert at45 == [(0.0, pytest.approx(0.03)), (pytest.approx(0.03), pytest.approx(0.02))]
    hatched = [(x, b, h) for x, b, h, hatch in bars if hatch]
    assert hatched == [(90.0, pytest.approx(0.006), pytest.approx(0.004))]
    ctx = report_plots.split_context(
        frames, report_plots.split_views(m, report_columns.technique_views(m))[0]
    )
    assert (
        ctx["negative"] == 1
        and ctx["rows"][2]["cells"][1]["negative"]
        and ctx["rows"][2]["total"] == "0.0060"
    )


def test_no_split_without_its_parts(split_sweep):
    _, m = split_sweep
    m = copy.deepcopy(m)
    views = report_columns.technique_views(m)
    assert [sv.view.name for sv in report_plots.split_views(m, views)] == ["horizon-fit"]
    del m["techniques"]["horizon-fit"]["split_parts"]
    assert report_plots.split_views(m, views) == []
    for f in m["frames"]:
        f["techniques"].pop("horizon-fit")
    assert "bake_loss" not in pipeline_records.summary_table(m)
