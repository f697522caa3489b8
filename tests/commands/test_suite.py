"""hzval suite: many materials, one overview; in this process, on a pool of workers, on a cluster."""

from __future__ import annotations

import json
import math
from urllib.parse import quote

import numpy as np
import pytest

from hzval import materials
from hzval.cli import main as cli
from hzval.commands import suite
from hzval.core.errors import InputError
from hzval.io import codecs, staging
from hzval.pipeline import sweep
from hzval.scene import files as scene_files
from tests.helpers import interrupt_material

SMALL = dict(size=24, azimuths="-30,0,30", spp=4)
#: Scores a suite row must reproduce from a standalone sweep (times differ run to run).
SCORES = ("visibility_mae", "leak_fraction", "false_shadow_fraction", "flip_mean", "delta_e2000_mean", "rmse")


def _folder(tmp_path):
    """A folder of height maps: one with a sidecar scene, one without, one that is not a height map."""
    d = tmp_path / "maps"
    d.mkdir()
    h = materials.generate("cobblestones", 32).height
    codecs.write_png(d / "stones.png", np.round(h * 65535).astype(np.uint16))
    (d / "stones.toml").write_text(
        '[material]\ndepth = 0.3\nboundary = "open"\n[light]\nelevation_deg = 40\n'
    )
    np.save(d / "dome.npy", materials.generate("gravel", 24).height)
    (d / "broken.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 20)
    (d / "notes.txt").write_text("not a height map")
    return d


def test_default_entries_are_the_built_in_materials():
    items = suite.entries()
    assert [e.name for e in items] == materials.names()
    ridges = next(e for e in items if e.name == "ridges")
    assert ridges.scene.material.boundary == "open" and ridges.origin == "built-in"


def test_entries_read_folders_sidecars_scene_files_and_names(tmp_path):
    d = _folder(tmp_path)
    items = suite.entries([d, "spikes", "spikes"], elevation=20)
    names = [e.name for e in items]
    assert names == ["broken", "dome", "stones", "spikes", "spikes-2"]
    stones = items[2].scene
    assert (stones.material.depth, stones.material.boundary) == (0.3, "open")  # the sidecar's
    assert stones.light.elevation_deg == 20  # the flags win
    assert items[1].scene.material.depth == 0.05 and items[1].scene.material.boundary == "wrap"
    assert all(e.scene.name == e.name for e in items)
    with pytest.raises(InputError, match="no such file"):
        suite.entries([tmp_path / "nothing"])
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="no height maps"):
        suite.entries([tmp_path / "empty"])


def test_a_folder_of_scene_files_is_a_suite_of_them():
    """`hzval suite scenes/`: the shipped scenes, each by its own name; wall.toml is wall.png's sidecar."""
    from hzval.commands import check

    items = {e.name: e for e in suite.entries([check.repository_path("scenes")])}
    assert set(materials.names()) | {"wall", "wall-soft"} <= set(items)
    assert items["wall"].scene.material.depth == 0.125 and items["wall"].origin.endswith("wall.toml")
    assert items["spikes"].scene.material.height == "spikes"


@pytest.fixture(scope="module")
def in_process(tmp_path_factory, variant):
    tmp = tmp_path_factory.mktemp("suite")
    items = suite.entries([_folder(tmp), "planks"], **SMALL)
    out = tmp / "out"
    return items, out, suite.run(items, out, workers=0, command="hzval suite (test)", progress=False)


def test_a_failed_material_is_reported_and_the_others_are_not_lost(in_process):
    items, out, result = in_process
    rows = {r["name"]: r for r in result["materials"]}
    assert set(rows) == {e.name for e in items}
    assert rows["broken"]["status"] == "failed" and "broken.png" in rows["broken"]["error"]
    assert result["materials"][0]["name"] == "broken"  # worst first: failures lead
    for name in ("dome", "stones", "planks"):
        assert rows[name]["status"] == "ok"
        assert (out / name / "index.html").is_file() and (out / name / "metrics.json").is_file()
    assert result["suite"]["failed"] == 1
    on_disk = json.loads((out / "suite.json").read_text())
    assert [r["name"] for r in on_disk["materials"]] == [r["name"] for r in result["materials"]]


def test_rows_are_sorted_worst_first_and_equal_their_sweeps_means(in_process):
    _, out, result = in_process
    ok = [r for r in result["materials"] if r["status"] == "ok"]
    from hzval.report import ranking

    # worst first by |F - V| over the pixels facing the light, as the sweep's report and ranking have it
    worst = [ranking.visibility_of(r["techniques"]["horizon"]) for r in ok]
    assert worst == sorted(worst, reverse=True)
    for r in ok:
        metrics = json.loads((out / r["name"] / "metrics.json").read_text())
        for name, t in r["techniques"].items():
            for key in (*SCORES, "visibility_mae_facing"):  # each under its own name, as metrics.json
                values = [f["techniques"][name][key] for f in metrics["frames"]]
                assert t[key] == pytest.approx(float(np.mean(values)), rel=1e-12), (r["name"], name, key)


def test_a_material_equals_its_standalone_sweep(in_process, tmp_path, capsys):
    """The acceptance criterion: a suite's material scores exactly what `hzval sweep` does, run as a
    user would, on the height map (with its sidecar) and the suite's flags."""
    items, out, _ = in_process
    stones = next(e for e in items if e.name == "stones")
    path = stones.scene.material.height
    assert (
        cli.main(
            [
                "sweep",
                path,
                "--azimuths",
                SMALL["azimuths"],
                "--spp",
                str(SMALL["spp"]),
                "--out",
                str(tmp_path / "alone"),
                "--quiet",
            ]
        )
        == 0
    )
    alone = json.loads((tmp_path / "alone" / "metrics.json").read_text())
    suite_metrics = json.loads((out / "stones" / "metrics.json").read_text())
    settings = ("k", "path", "ambient")  # the CLI states the horizon map's default settings, Options() not
    assert {k: v for k, v in alone["parameters"].items() if k not in settings} == {
        k: v for k, v in suite_metrics["parameters"].items() if k not in settings
    }
    assert max(f["techniques"]["horizon"]["visibility_mae"] for f in alone["frames"]) > 0.01  # not trivial
    for a, b in zip(alone["frames"], suite_metrics["frames"]):
        for name in alone["techniques"]:
            for key in SCORES:
                assert a["techniques"][name][key] == b["techniques"][name][key]
        assert a["floor"] == b["floor"]


def test_the_overview_page_links_every_report_and_shows_thumbnails(in_process):
    _, out, result = in_process
    html = (out / "index.html").read_text()
    for r in result["materials"]:
        if r["status"] == "ok":
            assert f'href="{r["name"]}/index.html"' in html
            assert len(r["thumbs"]) == 3  # three lights
            for _az, images in r["thumbs"].items():
                assert set(images) == {"truth", *r["techniques"]}
                for rel in images.values():
                    assert (out / rel).is_file() and f'src="{quote(rel)}"' in html
        else:
            assert r["error"].split(":")[0] in html
    assert "sort" in html and "worst first" in html


@pytest.mark.slow(
    reason="starts a two-process Dask cluster; test_cli_suite_exit_status_and_table keeps a pool fast"
)
def test_workers_on_a_cluster_give_the_same_numbers(in_process, tmp_path, monkeypatch):
    """A Dask cluster the test starts itself (two worker processes), addressed like a remote one; the
    output folder given relative to this process's directory, which the workers do not share."""
    distributed = pytest.importorskip("distributed")
    items, out, result = in_process
    monkeypatch.chdir(tmp_path)
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
    ) as c:
        remote = suite.run(items, "cluster", cluster=c.scheduler_address, progress=False)
    assert remote["suite"]["cluster"] == c.scheduler_address and "dask" in remote["suite"]["engine"]
    here = {r["name"]: r for r in result["materials"]}
    for r in remote["materials"]:
        assert r["status"] == here[r["name"]]["status"]
        if r["status"] == "ok":
            for name, t in r["techniques"].items():
                for key in SCORES:
                    assert t[key] == here[r["name"]]["techniques"][name][key], (r["name"], name, key)


def test_a_cluster_that_is_not_there_is_one_line(tmp_path, monkeypatch):
    pytest.importorskip("distributed")
    monkeypatch.setattr(suite, "CONNECT_TIMEOUT_S", 1)
    with pytest.raises(InputError, match="no Dask scheduler"):
        suite.run(suite.entries(["planks"], **SMALL), tmp_path, cluster="tcp://127.0.0.1:9", progress=False)


def test_cli_suite_exit_status_and_table(variant, tmp_path, capsys):
    d = _folder(tmp_path)
    code = cli.main(
        [
            "suite",
            str(d / "stones.png"),
            "planks",
            "--size",
            "24",
            "--azimuths",
            "0",
            "--spp",
            "4",
            "--techniques",
            "horizon,terrain",
            "--workers",
            "0",
            "--out",
            str(tmp_path / "o"),
            "--quiet",
        ]
    )
    assert code == 0
    out = capsys.readouterr().out
    assert "stones" in out and "planks" in out and "overview" in out
    assert max(len(line) for line in out.splitlines() if "overview" not in line) <= 100
    assert out.splitlines()[0].split()[:3] == ["technique", "|F-V|", "FLIP"]  # ranked across materials
    rows = json.loads((tmp_path / "o" / "suite.json").read_text())["materials"]
    assert all(set(r["techniques"]) == {"horizon", "terrain"} for r in rows)
    assert (
        cli.main(
            [
                "suite",
                str(d),
                "--azimuths",
                "0",
                "--spp",
                "4",
                "--techniques",
                "horizon",
                "--workers",
                "1",
                "--out",
                str(tmp_path / "p"),
                "--quiet",
            ]
        )
        == 1
    )  # broken.png failed, in a pool
    # --size names the built-in materials' size: with height map files only it changes nothing, and says so
    assert cli.main(["suite", str(d), "--size", "24", "--out", str(tmp_path / "s"), "--quiet"]) == 2
    assert "--size: 24 applies to built-in materials only" in capsys.readouterr().err
    assert not (tmp_path / "s").exists()
    assert cli.main(["suite", str(tmp_path / "missing"), "--out", str(tmp_path / "q")]) == 2
    assert not (tmp_path / "q").exists()


def test_suite_json_has_no_nan(in_process):
    _, out, _ = in_process
    text = (out / "suite.json").read_text()
    assert "NaN" not in text and "Infinity" not in text
    json.loads(text)
    assert not math.isnan(json.loads(text)["suite"]["seconds"])


def test_default_workers_follow_cores_materials_and_memory():
    items = suite.entries(["planks", "gravel", "fabric", "panels"], size=512)
    gib = 2**30
    assert suite.default_workers(items, cores=2, available=64 * gib) == 2
    assert suite.default_workers(items, cores=1, available=64 * gib) == 1
    assert suite.default_workers(items, cores=16, available=64 * gib) == 4  # four materials
    assert suite.default_workers(items[:4], cores=64, available=64 * gib) == 4
    big = suite.entries(["planks", "gravel", "fabric", "panels"], size=2048)
    per = suite.estimate_peak_bytes(big[0])
    assert 7 * gib < per < 10 * gib  # about the 8.5 GiB measured (benchmarks/README.md)
    assert suite.default_workers(big, cores=16, available=24 * gib) == 2
    assert suite.default_workers(big, cores=16, available=16 * gib) == 1


def test_a_worker_that_cannot_see_the_folder_says_so(tmp_path):
    """On a cluster, a worker must see DIR: the task checks the token the caller left there."""
    e = suite.entries(["planks"], **SMALL)[0]
    task = suite.Task(e, str(tmp_path / "planks"), sweep.Options(), None, "", None, token="abc")
    row = suite.sweep_material(task)
    assert row["status"] == "failed" and "cannot see the suite's folder" in row["error"]


class _KillsItsWorker:
    """Touched in any process but the test's, it ends that process: a material that crashes its worker."""

    def __init__(self):
        import os

        self.pid = os.getpid()

    def __getattr__(self, name):
        import os

        pid = self.__dict__.get("pid")  # absent while being unpickled
        if pid is not None and os.getpid() != pid:
            os._exit(3)
        raise AttributeError(name)


@pytest.mark.slow(
    reason="starts a Dask cluster and kills a worker; test_faults.py classifies the failure fast"
)
def test_a_worker_that_dies_is_one_failed_material(tmp_path):
    pytest.importorskip("distributed")
    good = suite.entries(["planks"], **SMALL)[0]
    bad = suite.entries(["gravel"], **SMALL)[0]
    tasks = [
        suite.Task(good, str(tmp_path / "planks"), sweep.Options(), None, "", 1),
        suite.Task(bad, str(tmp_path / "gravel"), _KillsItsWorker(), None, "", 1),
    ]
    rows, engine = [None, None], {}
    suite._run_dask(tasks, rows, engine, 2, None, progress=False)
    assert "dask" in engine["name"]
    assert rows[0]["status"] == "ok" and rows[0]["name"] == "planks"
    assert rows[1]["status"] == "failed" and "worker" in rows[1]["error"] and rows[1]["name"] == "gravel"


def test_a_sidecar_scene_serves_sweep_as_it_serves_suite(tmp_path, capsys, variant):
    d = _folder(tmp_path)
    # the sidecar alone (`--scene stones.toml`) finds the height map beside it
    s = scene_files.load_scene(d / "stones.toml")
    assert s.material.height == str((d / "stones.png").resolve()) and s.material.depth == 0.3
    # `hzval sweep stones.png` reads stones.toml and says so
    out = tmp_path / "o"
    assert (
        cli.main(
            [
                "sweep",
                str(d / "stones.png"),
                "--azimuths",
                "0",
                "--spp",
                "4",
                "--techniques",
                "horizon",
                "--out",
                str(out),
                "--quiet",
            ]
        )
        == 0
    )
    assert "sidecar scene" in capsys.readouterr().err
    m = json.loads((out / "metrics.json").read_text())
    assert (m["parameters"]["depth"], m["parameters"]["boundary"], m["parameters"]["elevation_deg"]) == (
        0.3,
        "open",
        40,
    )


@pytest.mark.browser
def test_the_overview_sorts_in_a_browser(in_process):
    """Chromium: every thumbnail loads, no console errors, and a click on a column sorts the rows."""
    import os

    from tests.helpers import CHROMIUM, CHROMIUM_ARGS

    if not os.path.exists(CHROMIUM):
        pytest.skip(f"{CHROMIUM} is missing (apt-get install chromium)")
    sync_playwright = pytest.importorskip("playwright.sync_api").sync_playwright
    _, out, result = in_process
    problems: list[str] = []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 900})
            page.on("console", lambda m: problems.append(m.text) if m.type in ("error", "warning") else None)
            page.on("pageerror", lambda e: problems.append(str(e)))
            page.goto((out / "index.html").as_uri(), wait_until="load")
            # thumbnails load lazily: ask for all of them, then wait until each has decoded
            page.evaluate("document.querySelectorAll('img').forEach(i => { i.loading = 'eager'; })")
            page.wait_for_function("[...document.images].every(i => i.complete)", timeout=10000)
            images = page.eval_on_selector_all("img", "els => els.map(e => [e.complete, e.naturalWidth])")
            ok = [r for r in result["materials"] if r["status"] == "ok"]
            assert len(images) == sum(len(r["thumbs"]) * (1 + len(r["techniques"])) for r in ok)
            assert all(c and w > 0 for c, w in images)

            def names():
                return page.eval_on_selector_all(
                    "#scores tbody tr", "rs => rs.map(r => r.cells[0].textContent.trim())"
                )

            assert names()[0] == "broken"  # worst first: the failure leads
            material = page.locator("#scores thead tr:nth-child(2) th").nth(0)
            material.click()  # descending by name
            assert names() == sorted(names(), reverse=True)
            material.click()  # and ascending
            assert names() == sorted(names())
            flip = page.locator("#scores thead tr:nth-child(2) th", has_text="FLIP").first
            flip.click()
            values = page.eval_on_selector_all(
                "#scores tbody tr.ok", "rs => rs.map(r => parseFloat(r.cells[6].dataset.v))"
            )
            assert values == sorted(values, reverse=True) and len(values) == len(ok)
        finally:
            browser.close()
    assert problems == []


def test_a_second_suite_into_a_busy_folder_is_refused(tmp_path):
    out = tmp_path / "o"
    with staging.folder_lock(out, "hzval suite (first)"):
        with pytest.raises(InputError, match="in use by another hzval run"):
            suite.run(suite.entries(["planks"], **SMALL), out, workers=0, progress=False)


def test_names_are_safe_folders_and_unique(tmp_path):
    for stem in ("a", "a-2"):
        np.save(tmp_path / f"{stem}.npy", materials.generate("gravel", 16).height)
    (tmp_path / "odd.toml").write_text('name = "../escape me#"\n[material]\nheight = "planks"\nsize = 16\n')
    (tmp_path / "num.toml").write_text('name = 5\n[material]\nheight = "planks"\nsize = 16\n')
    (tmp_path / "thumbs.toml").write_text('[material]\nheight = "planks"\nsize = 16\n')
    names = [
        e.name
        for e in suite.entries(
            [
                tmp_path / "a.npy",
                tmp_path / "a.npy",
                tmp_path / "a-2.npy",
                tmp_path / "odd.toml",
                tmp_path / "num.toml",
                tmp_path / "thumbs.toml",
            ]
        )
    ]
    assert names == ["a", "a-2", "a-2-2", "_escape_me_", "5", "thumbs-2"]
    assert len(set(names)) == len(names)


def test_a_sidecar_that_names_another_material_is_refused(tmp_path):
    np.save(tmp_path / "x.npy", materials.generate("gravel", 16).height)
    (tmp_path / "x.toml").write_text('[material]\nheight = "spikes"\n')
    (entry,) = suite.entries([tmp_path])  # a broken sidecar is that material's failed row
    assert "sidecar scene of x.npy" in entry.error
    row = suite.sweep_material(suite.Task(entry, str(tmp_path / "o"), sweep.Options(), None, "", None))
    assert row["status"] == "failed" and "sidecar scene of x.npy" in row["error"]
    assert cli.main(["sweep", str(tmp_path / "x.npy"), "--out", str(tmp_path / "o")]) == 2


def test_ctrl_c_writes_the_overview_of_what_finished(tmp_path, monkeypatch, variant):
    items = suite.entries(["planks", "gravel", "fabric"], **SMALL)
    interrupt_material(monkeypatch, "gravel")
    with pytest.raises(KeyboardInterrupt):
        suite.run(items, tmp_path, workers=0, progress=False)
    result = json.loads((tmp_path / "suite.json").read_text())
    assert result["suite"]["interrupted"] and result["suite"]["not_run"] == 2
    status = {r["name"]: r["status"] for r in result["materials"]}
    assert status == {"planks": "ok", "gravel": "not run", "fabric": "not run"}
    assert (tmp_path / "planks" / "index.html").is_file() and not (tmp_path / "gravel").exists()
    assert "Interrupted" in (tmp_path / "index.html").read_text()


def test_each_sweep_reports_its_own_peak_memory():
    """In one process, a small sweep after a larger one reports its own peak, not the process's."""
    from hzval.pipeline.sweep import peak_rss_bytes, reset_peak_rss

    reset_peak_rss()
    base = peak_rss_bytes()
    big = np.ones(300 * 2**20, np.uint8)  # 300 MiB, touched
    assert peak_rss_bytes() > base + 0.9 * big.nbytes
    del big
    reset_peak_rss()
    assert peak_rss_bytes() < base + 0.5 * 300 * 2**20  # forgotten after the reset


def test_a_stop_inside_dr_jit_tracing_stops_an_in_process_suite(tmp_path, monkeypatch, variant):
    """A SIGTERM's interrupt raised inside a Dr.Jit loop while the second material is compared: Dr.Jit
    passes it on as a RuntimeError's cause, and the sweep raises it again as the interrupt
    (:func:`hzval.core.interrupts.unwrapped`), so the suite stops with an interrupted overview
    instead of recording the material as failed and going on to the next."""
    import signal

    import drjit as dr
    import mitsuba as mi

    from hzval.core import errors
    from hzval.metrics import compare

    real_flip, real_sweep = compare.flip_error, suite.sweep_material
    current: list[str] = []

    def sweep_material(task):
        current.append(task.entry.name)
        return real_sweep(task)

    def flip_error(*a, **kw):
        if current[-1] == "gravel":

            def body(i):
                raise errors.Interrupted(signal.SIGTERM)

            dr.while_loop((dr.arange(mi.UInt32, 4),), lambda i: i < 2, body)
        return real_flip(*a, **kw)

    monkeypatch.setattr(suite, "sweep_material", sweep_material)
    monkeypatch.setattr(compare, "flip_error", flip_error)
    items = suite.entries(["planks", "gravel", "fabric"], **SMALL)
    with pytest.raises(KeyboardInterrupt):
        suite.run(items, tmp_path / "s", workers=0, progress=False)
    assert current == ["planks", "gravel"]  # fabric never started
    result = json.loads((tmp_path / "s" / "suite.json").read_text())
    assert result["suite"]["interrupted"]
    assert "failed" not in {r.get("status") for r in result["materials"] if r["name"] == "gravel"}
