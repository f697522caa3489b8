"""Fault injection: the audit's twelve reliability defects (issue 33), one test (or a few) each.
The second audit's cases are in test_audit2.py, and the fuzz-style test of every JSON and TOML
reader in test_faults_fuzz.py.

Small maps and bounded times; where memory matters the command runs in a
process of its own under an address-space limit (``prlimit --as``, via
:func:`resource.setrlimit` in the child), as a new user's would.
"""

from __future__ import annotations

import errno
import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from hzval import materials
from hzval.cli import main as cli
from hzval.core import conventions as cv
from hzval.core.errors import InputError
from hzval.io import atomic, codecs, documents, staging
from hzval.scene import files as scene_files
from hzval.scene import spec as sc
from hzval.truth import memory
from tests.helpers import ROOT, hzval, one_line

SMALL = ["--size", "24", "--azimuths", "0", "--spp", "4", "--techniques", "horizon", "--quiet"]


# 1. a bound on the number of lights, counted before any list is made ------------------------


def test_a_billion_lights_is_refused_in_seconds_under_a_memory_limit(tmp_path):
    rc, err, seconds = hzval("sweep", "--size", "64", "--azimuths=0:1e9:1e-9", "--out", tmp_path / "o")
    assert rc == 2 and seconds < 10
    one_line(err, "--azimuths", str(sc.MAX_LIGHTS))
    assert not (tmp_path / "o").exists()


def test_the_light_count_is_computed_not_listed():
    with pytest.raises(InputError, match="360001 lights"):
        sc.parse_azimuths("0:360:0.001")
    assert len(sc.parse_azimuths("-180:180:1")) == sc.MAX_LIGHTS  # the bound itself is allowed
    for bad in ("0:inf:1", "nan,1", "0:10:0"):
        with pytest.raises(InputError, match="--azimuths"):
            sc.parse_azimuths(bad)


def test_frames_times_pixels_is_bounded_before_anything_is_allocated():

    scene = sc.override(sc.Scene(), size=4096, azimuths="0:360:2")  # 181 lights of 16.8M pixels
    with pytest.raises(InputError, match="frame pixels"):
        memory.check_frame_pixels(scene, 4096, 4096)
    assert memory.check_frame_pixels(sc.override(sc.Scene(), size=4096), 4096, 4096) == 9 * 4096**2


# 2. the local cluster listens on loopback only -----------------------------------------------


def _listening(pids: set[int]) -> set[str]:
    import psutil

    found = set()
    for c in psutil.net_connections(kind="inet"):
        if c.status == psutil.CONN_LISTEN and c.pid in pids:
            found.add(c.laddr.ip)
    return found


@pytest.mark.slow
def test_a_local_cluster_listens_on_loopback_only(tmp_path, variant):
    psutil = pytest.importorskip("psutil")
    pytest.importorskip("distributed")
    from hzval.commands import suite

    items = suite.entries(["planks", "gravel"], size=24, azimuths="-30,0,30", spp=4)
    seen: set[str] = set()
    done = threading.Event()

    def watch():
        me = psutil.Process()
        while not done.is_set():
            pids = {me.pid} | {c.pid for c in me.children(recursive=True)}
            seen.update(_listening(pids))
            time.sleep(0.2)

    t = threading.Thread(target=watch, daemon=True)
    t.start()
    try:
        result = suite.run(items, tmp_path / "o", workers=2, progress=False)
    finally:
        done.set()
        t.join()
    assert result["suite"]["failed"] == 0
    assert seen, "no listening socket seen while the cluster ran"
    assert seen <= {"127.0.0.1", "::1"}, seen


def test_the_local_cluster_is_asked_for_loopback_and_no_dashboard(monkeypatch):
    """Without starting one: what :func:`hzval.commands.suite._run_dask` asks of ``LocalCluster``."""
    distributed = pytest.importorskip("distributed")
    from hzval.commands import suite

    asked = {}

    class Stop(Exception):
        pass

    def fake(**kw):
        asked.update(kw)
        raise Stop

    monkeypatch.setattr(distributed, "LocalCluster", fake)
    with pytest.raises(Stop):
        suite._run_dask([], [], {}, 1, None, progress=False)
    assert asked["host"] == "127.0.0.1" and asked["dashboard_address"] is None
    assert asked["worker_dashboard_address"] is None


# 3. --out: new, empty or hzval's; a user's file is kept ------------------------------------


def test_a_folder_with_a_file_of_the_users_keeps_it(tmp_path, variant, capsys):
    out = tmp_path / "o"
    (out / "plots").mkdir(parents=True)
    (out / "plots" / "mine.txt").write_text("mine")
    (out / "index.html").write_text("my page")
    assert cli.main(["sweep", *SMALL, "--out", str(out)]) == 2
    one_line(capsys.readouterr().err, str(out), "plots/mine.txt", "--force")
    assert sorted(p.relative_to(out).as_posix() for p in out.rglob("*")) == [
        "index.html",
        "plots",
        "plots/mine.txt",
    ]
    # --force writes beside them: hzval's own files only are replaced, the user's page is overwritten
    # only because the user asked; the user's plot survives the swap of plots/
    assert cli.main(["sweep", *SMALL, "--out", str(out), "--force"]) == 0
    assert (out / "plots" / "mine.txt").read_text() == "mine" and (out / "plots" / "metrics.png").is_file()
    assert "plots/mine.txt" in staging.foreign_files(out)  # still the user's


@pytest.mark.slow
def test_a_report_folder_is_hzvals_and_can_be_swept_again(tmp_path, variant):
    out = tmp_path / "o"
    assert cli.main(["sweep", *SMALL, "--out", str(out)]) == 0
    assert staging.foreign_files(out) == []
    marker = json.loads((out / staging.MARKER_NAME).read_text())
    assert "metrics.json" in marker["files"] and "bake/bake.json" in marker["files"]
    assert cli.main(["sweep", *SMALL, "--out", str(out)]) == 0
    assert not (out / staging.LOCK_NAME).exists()  # the lock is removed at exit


def test_an_empty_folder_is_accepted_and_bake_refuses_foreign_files(tmp_path, height_npy, capsys):
    empty = tmp_path / "empty"
    empty.mkdir()
    assert cli.main(["bake", str(height_npy), "--radius", "3", "--angles", "16", "--out", str(empty)]) == 0
    busy = tmp_path / "busy"
    busy.mkdir()
    (busy / "notes.txt").write_text("x")
    assert cli.main(["bake", str(height_npy), "--radius", "3", "--angles", "16", "--out", str(busy)]) == 2
    one_line(capsys.readouterr().err, "notes.txt")
    assert [p.name for p in busy.iterdir()] == ["notes.txt"]


@pytest.fixture
def height_npy(tmp_path):
    path = tmp_path / "maps" / "h.npy"
    path.parent.mkdir()
    np.save(path, materials.generate("gravel", 24).height)
    return path


# 4. depth: bounded, with a reason --------------------------------------------------------------


@pytest.mark.parametrize("depth", ["1e8", "1e30"])
def test_an_unbounded_depth_is_one_line_in_seconds(tmp_path, depth, capsys):
    rc, err, seconds = hzval("sweep", *SMALL, f"--depth={depth}", "--out", tmp_path / "o", timeout=30)
    assert rc == 2 and seconds < 30, err
    one_line(err, "--depth")
    for argv in (["bake", "--size", "24"], ["export-scene", "--size", "24"]):  # in this process: faster
        assert cli.main([*argv, f"--depth={depth}", "--out", str(tmp_path / "o")]) == 2
        one_line(capsys.readouterr().err, "--depth")
    assert not (tmp_path / "o").exists()


def test_the_depth_bound_and_its_reason():
    assert cv.check_depth(cv.MAX_DEPTH) == cv.MAX_DEPTH
    with pytest.raises(InputError, match=r"\(0, 10\] image widths .*hops"):
        cv.check_depth(10.5)
    for bad in (float("inf"), float("nan"), -1.0, 0.0):
        with pytest.raises(InputError, match="--depth"):
            cv.check_depth(bad)
    with pytest.raises(InputError, match="number"):
        cv.check_depth("0.1")
    # an open tile has no hops: only float32's precision bounds it (a 1000-texel spike on 16 texels)
    assert cv.check_depth(62.5, boundary="open") == 62.5
    with pytest.raises(InputError, match=r"\(0, 1000\] image widths for an open tile"):
        cv.check_depth(1e8, boundary="open")


# 5. external horizon maps validated; metrics.json strict JSON ----------------------------------


def _layers(tmp_path, values: np.ndarray, name="h") -> list[Path]:
    paths = []
    for i in range(values.shape[-1] // 4):
        p = tmp_path / f"{name}{i}.exr"
        codecs.write_exr(p, {"RGBA": values[..., 4 * i : 4 * i + 4]})
        paths.append(p)
    return paths


def test_a_nan_horizon_map_is_refused(tmp_path, capsys, variant):
    height = materials.generate("gravel", 24).height
    np.save(tmp_path / "g.npy", height)
    v = np.full((24, 24, 8), 0.2, np.float32)
    v[3, 4, 5] = np.nan
    paths = _layers(tmp_path, v)
    out = tmp_path / "o"
    assert (
        cli.main(
            [
                "sweep",
                str(tmp_path / "g.npy"),
                *SMALL[2:],
                "--horizon-map",
                ",".join(map(str, paths)),
                "--out",
                str(out),
            ]
        )
        == 2
    )
    one_line(capsys.readouterr().err, "h0.exr", "not finite", "(3, 4), channel 5")
    assert not out.exists()


def test_external_layers_must_be_rgba_of_the_declared_count_and_range(tmp_path):
    from PIL import Image

    from hzval.io import external

    grey = tmp_path / "grey.png"
    Image.fromarray(np.zeros((8, 8), np.uint8)).save(grey)
    with pytest.raises(InputError, match="RGBA.*mode L"):
        external.read_layers([grey])
    three = _layers(tmp_path, np.full((8, 8, 12), 0.5, np.float32))
    with pytest.raises(InputError, match="2 RGBA layers, got 3"):
        external.load(three, external.Encoding())
    high = _layers(tmp_path, np.full((8, 8, 8), 1.5, np.float32), "high")
    with pytest.raises(InputError, match=r"sine values lie in \[-1, 1\]"):
        external.load(high, external.Encoding())
    assert external.load(high, external.Encoding(values="tangent")).shape == (8, 8, 8)  # any finite tangent


def test_json_is_strict_at_the_writer(tmp_path):
    with pytest.raises(InputError, match=r"frames\[1\]\.flip_mean is not a finite number"):
        documents.write_json(
            tmp_path / "m.json", {"frames": [{"flip_mean": 0.1}, {"flip_mean": float("nan")}]}
        )
    assert not list(tmp_path.iterdir())


def test_a_sweeps_metrics_parse_as_strict_json(tmp_path, variant):
    out = tmp_path / "o"
    assert cli.main(["sweep", *SMALL, "--out", str(out)]) == 0

    def refuse(constant):
        raise ValueError(constant)

    for name in ("metrics.json", "frames.json"):
        json.loads((out / name).read_text(), parse_constant=refuse)


# 6. export-scene and tradeoff memory, the sweep's estimate reused -------------------------------


@pytest.mark.parametrize("command", ["export-scene", "tradeoff"])
def test_a_huge_size_is_refused_before_it_allocates(tmp_path, command):
    rc, err, seconds = hzval(command, "--size", "100000", "--out", tmp_path / "o")
    assert rc == 2 and seconds < 10
    one_line(err, "--size", "GiB")
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_a_small_file_of_a_huge_map_is_refused_before_it_is_decoded(tmp_path):
    from PIL import Image

    big = tmp_path / "big.png"
    Image.new("L", (12000, 12000)).save(big)  # 144M texels in a file of 140 KB
    assert big.stat().st_size < 2**20
    for command in ("export-scene", "tradeoff"):
        rc, err, seconds = hzval(command, big, "--out", tmp_path / "o")
        assert rc == 2 and seconds < 10, err
        one_line(err, "big.png", "GiB")


# 7. OS errors as one line ------------------------------------------------------------------------


def test_an_out_that_is_a_file_is_one_line(tmp_path, capsys):
    f = tmp_path / "f"
    f.write_text("x")
    rc, err, _ = hzval("sweep", *SMALL, "--out", f)  # as a user runs it
    assert rc == 2
    one_line(err, str(f), "is a file, not a folder")
    for argv in (["sweep", *SMALL], ["bake", "--size", "16"], ["views", "--size", "16", "--views", "top"]):
        assert cli.main([*argv, "--out", str(f / "sub")]) == 2
        one_line(capsys.readouterr().err, str(f / "sub"), f"{f} is a file")
    assert f.read_text() == "x"


@pytest.mark.parametrize("code", [errno.EROFS, errno.ENOSPC, errno.EACCES])
def test_a_read_only_full_or_forbidden_out_is_one_line(tmp_path, capsys, monkeypatch, code, variant):
    """The error injected where hzval's files are written (root ignores permissions, and a read-only
    mount needs privileges this test does not have)."""
    real = atomic.atomic_path

    def failing(path):
        raise OSError(code, os.strerror(code), str(path))

    out = tmp_path / "o"
    for module in (atomic, codecs, documents):  # every place hzval opens a file to write
        monkeypatch.setattr(module, "atomic_path", failing)
    assert cli.main(["sweep", *SMALL, "--out", str(out)]) == 2
    one_line(capsys.readouterr().err, os.strerror(code), str(out))
    assert not out.exists()  # nothing left behind
    for module in (atomic, codecs, documents):
        monkeypatch.setattr(module, "atomic_path", real)


def test_a_mesh_on_a_full_disk_is_one_line(tmp_path):
    """Mitsuba's PLY writer raises a RuntimeError of its own text on a full disk."""
    from hzval.geometry import tile as mesh

    class Full:
        def write_ply(self, path):
            raise RuntimeError(
                f'[FileStream] "{path}": I/O error while attempting to write 12 bytes: '
                "No space left on device"
            )

    with pytest.raises(InputError, match="mesh.ply: No space left on device"):
        mesh.write_ply(Full(), tmp_path / "mesh.ply")
    assert list(tmp_path.iterdir()) == []


def test_a_folder_that_cannot_be_made_is_one_line(tmp_path, capsys, monkeypatch):
    def failing(self, *a, **kw):
        raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(self))

    monkeypatch.setattr(Path, "mkdir", failing)
    assert cli.main(["export-scene", "--size", "16", "--out", str(tmp_path / "o")]) == 2
    one_line(capsys.readouterr().err, "Read-only file system", str(tmp_path / "o"))


@pytest.mark.parametrize("address", ["notanaddress", "http://localhost:8786", "tcp://host:99999"])
def test_a_malformed_cluster_address_is_one_line_and_leaves_nothing(tmp_path, capsys, address):
    out = tmp_path / "o"
    assert cli.main(["suite", "planks", "--size", "24", "--cluster", address, "--out", str(out)]) == 2
    one_line(capsys.readouterr().err, "--cluster", repr(address))
    assert not out.exists()


def test_an_unreachable_scheduler_leaves_no_folder_and_no_lock(tmp_path, capsys, monkeypatch):
    pytest.importorskip("distributed")
    from hzval.commands import suite

    monkeypatch.setattr(suite, "CONNECT_TIMEOUT_S", 1)
    new, old = tmp_path / "new", tmp_path / "old"
    old.mkdir()
    for out in (new, old):
        assert (
            cli.main(["suite", "planks", "--size", "24", "--cluster", "tcp://127.0.0.1:9", "--out", str(out)])
            == 2
        )
        one_line(capsys.readouterr().err, "--cluster", "no Dask scheduler at tcp://127.0.0.1:9")
    assert not new.exists() and list(old.iterdir()) == []


@pytest.mark.parametrize(
    "toml, needle",
    [
        ('azimuth0 = "x"', "azimuth0 must be a number"),
        ("channels = 8.0", "channels must be an integer"),
        ("chanels = 8", "did you mean 'channels'"),
    ],
)
def test_a_bad_horizon_encoding_is_one_line(tmp_path, toml, needle):
    from hzval.io import external

    p = tmp_path / "enc.toml"
    p.write_text(toml + "\n")
    with pytest.raises(InputError, match=needle):
        external.Encoding.from_toml(p)


def test_score_against_a_folder_of_the_wrong_shape_is_one_line(tmp_path, capsys):
    sweep_dir, frames_dir = tmp_path / "s", tmp_path / "f"
    sweep_dir.mkdir()
    frames_dir.mkdir()
    (sweep_dir / "metrics.json").write_text('{"frames": 3}')
    (sweep_dir / "frames.json").write_text(
        '{"exposure": 1, "image_size": [4, 4], "frames": '
        '[{"name": "az+0", "azimuth_deg": 0, "elevation_deg": 30}]}'
    )
    assert (
        cli.main(["score", str(frames_dir), "--against", str(sweep_dir), "--out", str(tmp_path / "o")]) == 2
    )
    one_line(capsys.readouterr().err, "metrics.json", "frames")


# 8. every writing command takes the folder lock -------------------------------------------------


@pytest.mark.parametrize(
    "argv",
    [
        ["bake", "--size", "16"],
        ["export-scene", "--size", "16"],
        ["views", "--size", "16", "--views", "top", "--azimuths", "0"],
    ],
)
def test_a_held_folder_is_refused_by_every_command(tmp_path, capsys, argv):
    out = tmp_path / "o"
    with staging.folder_lock(out):
        assert cli.main([*argv, "--out", str(out)]) == 2
        one_line(capsys.readouterr().err, "in use by another hzval run")
        holder = (out / staging.LOCK_NAME).read_text()
        assert "pid" in holder and "hzval" not in holder  # no command line in the lock
    assert not out.exists()


# 9. cluster failures told apart -----------------------------------------------------------------


def test_cluster_failures_are_told_apart(tmp_path, variant):
    distributed = pytest.importorskip("distributed")
    from hzval.commands import suite
    from hzval.pipeline import sweep

    (entry,) = suite.entries(["planks"], size=24, azimuths="0", spp=4)
    task = suite.Task(entry, str(tmp_path / "planks"), sweep.Options(), None, "", None, topic="t")
    killed = distributed.KilledWorker("k", "tcp://127.0.0.1:1", 0)
    never = suite._classify(task, killed, set(), time.time())
    assert never["status"] == "not run" and "before it started" in never["error"]
    died = suite._classify(task, killed, {"planks"}, time.time())
    assert died["status"] == "failed" and "worker died while sweeping it" in died["error"]
    lost = suite._classify(task, distributed.CancelledError("lost"), {"planks"}, time.time())
    assert lost["status"] == "failed" and "scheduler was lost while it ran" in lost["error"]
    # a material whose report completed is not failed, whatever became of its task
    t0 = time.time() - 1
    sweep.run(entry.scene, task.out, progress=False)
    done = suite._classify(task, distributed.CancelledError("lost"), None, t0)
    assert done["status"] == "ok" and done["name"] == "planks"
    assert suite._classify(task, killed, {"planks"}, time.time() + 60)["status"] == "failed"  # an old report


# 10. the folder left as it was ------------------------------------------------------------------


def test_an_error_after_the_bake_leaves_no_new_folder(tmp_path, capsys, monkeypatch, variant):
    from hzval.truth import plane as truth

    def broken(*a, **kw):
        raise InputError("truth", "injected failure after the bake")

    monkeypatch.setattr(truth, "Truth", broken)
    out = tmp_path / "new" / "o"
    assert cli.main(["sweep", *SMALL, "--out", str(out)]) == 2
    assert not (tmp_path / "new").exists()


@pytest.mark.parametrize("fault", [KeyboardInterrupt, signal.SIGTERM])
def test_an_interrupted_sweep_of_another_map_keeps_the_old_report_bake_included(
    tmp_path, monkeypatch, fault, variant
):
    from hzval.truth import plane as truth

    out = tmp_path / "o"
    assert cli.main(["sweep", *SMALL, "--out", str(out)]) == 0
    before = {p.relative_to(out).as_posix(): p.read_bytes() for p in out.rglob("*") if p.is_file()}

    def stop(*a, **kw):
        if fault is KeyboardInterrupt:
            raise KeyboardInterrupt
        os.kill(os.getpid(), fault)  # cli.main made SIGTERM an interrupt
        time.sleep(1)

    monkeypatch.setattr(truth, "Truth", stop)
    rc = cli.main(["sweep", "--material", "spikes", *SMALL, "--out", str(out)])
    assert rc == (130 if fault is KeyboardInterrupt else 128 + signal.SIGTERM)
    after = {p.relative_to(out).as_posix(): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert after == before  # byte for byte: bake/, the marker, no lock, no staging
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL  # put back as it was


def test_a_signal_that_lands_inside_dr_jit_tracing_stops_the_run_as_a_signal(
    tmp_path, monkeypatch, capsys, variant
):
    """SIGTERM while Dr.Jit traces a loop (as FLIP's recording or pom's march are traced): Dr.Jit
    passes the interrupt on as the cause of a RuntimeError, and the run still exits 143, with one
    line and no traceback, and leaves nothing behind."""
    import drjit as dr
    import mitsuba as mi

    from hzval.metrics import compare

    def traced_when_the_signal_comes(*a, **kw):
        def body(i):
            os.kill(os.getpid(), signal.SIGTERM)  # cli.main made SIGTERM an interrupt: raised here
            time.sleep(1)
            return (i + 1,)

        i = dr.arange(mi.UInt32, 4)
        dr.while_loop((i,), lambda i: i < 2, body)

    monkeypatch.setattr(compare, "flip_error", traced_when_the_signal_comes)
    out = tmp_path / "o"
    assert cli.main(["sweep", *SMALL, "--out", str(out)]) == 128 + signal.SIGTERM
    assert not out.exists()
    err = capsys.readouterr().err
    assert "hzval: interrupted" in err and "Traceback" not in err


def test_a_late_signal_does_not_undo_a_finished_run(tmp_path, monkeypatch, capsys, variant):
    """SIGINT during the swap: the run had passed its last signal check, so it completes (exit 0)
    with the new report in place, and says that the signal came too late."""
    real = staging.Staging.swap

    def swap_with_a_signal(self):
        os.kill(os.getpid(), signal.SIGINT)
        real(self)

    monkeypatch.setattr(staging.Staging, "swap", swap_with_a_signal)
    out = tmp_path / "o"
    assert cli.main(["sweep", *SMALL, "--out", str(out)]) == 0
    assert (out / "metrics.json").is_file() and not (out / staging.LOCK_NAME).exists()
    assert "SIGINT came after the output was complete" in capsys.readouterr().err


def test_sigterm_in_a_real_process_leaves_no_staging(tmp_path):
    """A sweep in its own process, stopped by SIGTERM while it renders: exit 143, no new folder."""
    out = tmp_path / "o"
    env = {**os.environ, "PYTHONPATH": str(ROOT), "HZVAL_VARIANT": "llvm_ad_rgb"}
    p = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "hzval",
            "sweep",
            "--size",
            "96",
            "--azimuths",
            "0:90:1",
            "--spp",
            "4",
            "--techniques",
            "horizon",
            "--quiet",
            "--out",
            str(out),
        ],
        env=env,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.time() + 60
    while time.time() < deadline and not list(out.glob(".hzval-staging-*/frames/*")):
        time.sleep(0.1)
    assert list(out.glob(".hzval-staging-*/frames/*")), "the sweep never reached its frames"
    p.send_signal(signal.SIGTERM)
    assert p.wait(timeout=60) == 128 + signal.SIGTERM
    assert not out.exists()


def test_views_leaves_no_empty_view_folder(tmp_path, monkeypatch, variant):
    from hzval.commands import views
    from hzval.pipeline import sweep

    out = tmp_path / "v"
    out.mkdir()

    def broken(*a, **kw):
        raise InputError("sweep", "injected")

    monkeypatch.setattr(sweep, "_run", broken)
    scene = sc.override(sc.Scene(), size=16, azimuths="0", spp=1)
    with pytest.raises(InputError):
        views.run(scene, out, views=["top"], progress=False)
    assert list(out.iterdir()) == []


# 11. strict scene files ------------------------------------------------------------------------


@pytest.mark.parametrize(
    "text, needle",
    [
        ('[materail]\nheight = "planks"\n', "unknown table [materail]; did you mean [material]?"),
        ("[material]\ndpeth = 0.2\n", "unknown key 'dpeth' in [material]; did you mean 'depth'?"),
        ("[samples]\nspp = 2.7\n", "samples.spp must be an integer, got 2.7"),
        ('[light]\nelevation_deg = "high"\n', "light.elevation_deg must be a number"),
        ("[camera]\nresolution = [64]\n", "camera.resolution must be a list of 2 integers"),
        ('nmae = "x"\n', "unknown key 'nmae'; did you mean 'name'?"),
    ],
)
def test_a_scene_file_is_strict(tmp_path, text, needle, capsys):
    p = tmp_path / "gravel.toml"
    p.write_text(text)
    with pytest.raises(InputError, match=None) as e:
        scene_files.load_scene(p)
    assert needle in str(e.value) and str(p) in str(e.value)
    assert cli.main(["sweep", "--scene", str(p), "--out", str(tmp_path / "o")]) == 2
    one_line(capsys.readouterr().err, needle)


def test_bake_and_export_read_the_sidecar_as_the_sweep_does(tmp_path, height_npy, variant):
    (height_npy.with_suffix(".toml")).write_text('[material]\ndepth = 0.2\nboundary = "open"\n')
    assert (
        cli.main(["bake", str(height_npy), "--radius", "3", "--angles", "16", "--out", str(tmp_path / "b")])
        == 0
    )
    record = json.loads((tmp_path / "b" / "bake.json").read_text())
    assert record["parameters"]["depth"] == 0.2 and record["parameters"]["boundary"] == "open"
    assert record["input"]["path"] == "../maps/h.npy"  # relative to the folder, not absolute
    assert cli.main(["export-scene", str(height_npy), "--out", str(tmp_path / "e")]) == 0
    assert "depth 0.2, open" in (tmp_path / "e" / "scene.xml").read_text()


def test_a_broken_sidecar_is_one_failed_row(tmp_path, variant):
    from hzval.commands import suite

    maps = tmp_path / "maps"
    maps.mkdir()
    for stem in ("good", "bad"):
        np.save(maps / f"{stem}.npy", materials.generate("gravel", 24).height)
    (maps / "bad.toml").write_text("[material]\ndpeth = 0.2\n")
    result = suite.run(
        suite.entries([maps], size=24, azimuths="0", spp=4), tmp_path / "o", workers=0, progress=False
    )
    rows = {r["name"]: r for r in result["materials"]}
    assert rows["good"]["status"] == "ok"
    assert rows["bad"]["status"] == "failed" and "did you mean 'depth'" in rows["bad"]["error"]


# 12. privacy: no absolute paths in reports, no command line in the lock ------------------------


@pytest.mark.slow
def test_reports_hold_paths_relative_to_their_folder(tmp_path, height_npy, variant, monkeypatch):
    monkeypatch.chdir(tmp_path)  # where the user works: command lines are shown relative to it
    out = tmp_path / "reports" / "r"
    assert cli.main(["sweep", str(height_npy), *SMALL[2:], "--out", str(out)]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["material"]["path"] == "../../maps/h.npy"
    page = (out / "index.html").read_text()
    assert str(tmp_path) not in page and "../../maps/h.npy" in page
    from hzval.commands import suite

    result = suite.run(
        suite.entries([height_npy.parent], size=24, azimuths="0", spp=4),
        tmp_path / "s",
        workers=0,
        progress=False,
        command=f"hzval suite {height_npy.parent}",
    )
    text = (tmp_path / "s" / "suite.json").read_text() + (tmp_path / "s" / "index.html").read_text()
    assert str(tmp_path) not in text
    assert result["materials"][0]["origin"] == "../maps/h.npy"


def test_portable_command_rewrites_absolute_paths_only(tmp_path, monkeypatch):
    """Absolute paths become relative to where the command ran (no home folder in a report, and the
    line still runs from there); relative ones stay as typed."""
    monkeypatch.chdir(tmp_path / "..")
    here = tmp_path.name
    cmd = f"hzval sweep {tmp_path}/maps/x.png --out={tmp_path}/r --depth 0.1 rel/y.png"
    assert (
        staging.portable_command(cmd) == f"hzval sweep {here}/maps/x.png --out={here}/r --depth 0.1 rel/y.png"
    )
