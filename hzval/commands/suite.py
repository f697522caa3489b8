"""The suite: many materials swept with one set of options, side by side, on one machine or a cluster.

:func:`entries` turns the command line's inputs into one :class:`Entry` per
material - every built-in material (:mod:`hzval.materials`) by default; a
scene TOML; a height map, with a sidecar scene of the same stem beside it
(``gravel.png`` + ``gravel.toml``, whose ``[material]`` table gives depth and
boundary); a folder of height maps (each with its optional sidecar); or a
built-in material's name; a folder's scene files that are no height map's
sidecar are materials too (``hzval suite scenes/`` runs the shipped scenes).
:func:`run` sweeps each one (:func:`hzval.pipeline.sweep.run`,
unchanged: a material's ``DIR/<name>/`` has the very scores ``hzval sweep``
gives it with the same settings) and, once all are in, writes the overview::

The design in full: docs/internals.md, "hzval.commands.suite".
"""

from __future__ import annotations

import dataclasses
import difflib
import json
import logging
import math
import os
import re
import shutil
import socket
import sys
import tempfile
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from hzval import materials
from hzval.commands import gates as gates_module
from hzval.core import backend, errors, interrupts, resources
from hzval.core.errors import InputError
from hzval.io import documents, heightmap, paths, staging
from hzval.metrics.results import FrameRecord, SweepResult
from hzval.pipeline import sweep
from hzval.report import overview as overview_page
from hzval.report import ranking
from hzval.scene import files as scene_files
from hzval.scene import spec as sc
from hzval.truth import memory

__all__ = [
    "Entry",
    "Task",
    "entries",
    "run",
    "sweep_material",
    "summarise",
    "gate_failures",
    "material_baseline",
    "HEIGHT_SUFFIXES",
    "LIGHTS_SHOWN",
]

#: File suffixes a folder's height maps have (:mod:`hzval.io.heightmap` reads them by content).
HEIGHT_SUFFIXES = heightmap.SUFFIXES
#: Thumbnails per material and technique: the sweep's first, middle and last lights.
LIGHTS_SHOWN = 3
#: Names under DIR that are the overview's own, never a material's folder.
RESERVED = ("thumbs",)
#: The file in DIR by which a cluster's worker proves it sees the caller's DIR.
TOKEN_FILE = ".hzval-suite"
#: How long to keep trying a ``--cluster`` scheduler that does not answer, in seconds.
CONNECT_TIMEOUT_S = 15
#: The per-frame metrics a material's row averages over its sweep.
MEANS = (
    "visibility_mae",
    "leak_fraction",
    "false_shadow_fraction",
    "flip_mean",
    "delta_e2000_mean",
    "rmse",
    "seconds",
)


@dataclass(frozen=True)
class Entry:
    """One material of the suite: its unique name, the scene to sweep and where it came from.

    The ``name`` is its folder under ``DIR``; ``origin`` is "built-in", a scene file, or a height map [+
    sidecar].
    """

    name: str
    scene: sc.Scene
    origin: str
    error: str | None = None  # why it cannot be swept (a broken sidecar): its failed row, one line


@dataclass(frozen=True)
class Task:
    """What a worker needs to sweep one material (picklable: it travels to other processes)."""

    entry: Entry
    out: str  # the material's folder, DIR/<name>
    options: object  # hzval.pipeline.sweep.Options
    variant: str | None
    command: str
    threads: int | None  # Dr.Jit threads in the worker; None leaves them alone
    token: str = ""  # what DIR/.hzval-suite holds: a worker that reads it sees the caller's DIR
    force: bool = False  # write beside files hzval did not write (hzval.io.staging.output_folder)
    topic: str = ""  # the Dask event topic of started tasks (_log_start); "" in this process


# --------------------------------------------------------------------------
# Inputs
# --------------------------------------------------------------------------


def entries(inputs: list[str | Path] | None = None, **overrides) -> list[Entry]:
    """Return the suite's materials, one :class:`Entry` per input, with ``overrides`` applied to every one.

    With no input, there is one for each built-in material. ``overrides`` are the sweep flags
    (:func:`hzval.scene.spec.override`'s keywords). A name is the folder of its report under DIR and a part of
    URLs: characters other than letters, digits, ``.``, ``_`` and ``-`` become ``_``, and names are made
    unique with ``-2``, ``-3``. An input that is no file, folder or built-in material, or a folder without
    height maps or scenes, is an :class:`InputError` before anything runs; a height map that cannot be read is
    not: it becomes that material's failure.
    """
    found: list[Entry] = []
    for item in inputs or materials.names():
        found.extend(_entries_of(item))
    out, taken = [], set(RESERVED)
    for e in found:
        base = _safe_name(e.name)
        name, n = base, 1
        while name in taken:
            n += 1
            name = f"{base}-{n}"
        taken.add(name)
        scene = sc.override(e.scene, **overrides)
        out.append(Entry(name, dataclasses.replace(scene, name=name), e.origin, e.error))
    return out


def _safe_name(name) -> str:
    """``name`` as a folder and URL part: only ``[A-Za-z0-9._-]``, no leading dot."""
    safe = re.sub(r"[^A-Za-z0-9._-]", "_", str(name)).lstrip(".")
    return safe or "material"


def _entries_of(item) -> list[Entry]:
    path = Path(item)
    if path.is_dir():
        maps = [p for p in path.iterdir() if p.is_file() and p.suffix.lower() in HEIGHT_SUFFIXES]
        stems = {p.stem for p in maps}
        scenes = [
            p
            for p in path.iterdir()  # scene files that are no map's sidecar
            if p.is_file() and p.suffix.lower() == ".toml" and p.stem not in stems
        ]
        if not maps and not scenes:
            raise InputError(
                path, f"no height maps ({', '.join(HEIGHT_SUFFIXES)}) or scene files in this folder"
            )
        return [
            _height_entry(p) if p.suffix.lower() != ".toml" else _scene_entry(p)
            for p in sorted(maps + scenes, key=lambda p: (p.stem, p.suffix))
        ]
    if path.is_file():
        return [_scene_entry(path) if path.suffix.lower() == ".toml" else _height_entry(path)]
    if materials.is_builtin(str(item)):
        scene = sc.override(sc.Scene(), height=str(item))
        return [Entry(str(item), dataclasses.replace(scene, name=str(item)), "built-in")]

    near = difflib.get_close_matches(str(item), materials.names(), n=1, cutoff=0.6)
    hint = f"; did you mean {' or '.join(near)}?" if near else ""
    raise InputError(
        item, f"no such file, folder or built-in material{hint} ({', '.join(materials.names())})"
    )


def _scene_entry(path: Path) -> Entry:
    scene = scene_files.load_scene(path)
    return Entry(scene.name, scene, str(path))


def _height_entry(path: Path) -> Entry:
    """Return a height map with its sidecar scene (``<stem>.toml`` beside it), if there is one.

    A sidecar that cannot be used is that material's failed row, as a map that cannot be read is.
    """
    sidecar = scene_files.sidecar_of(path)
    if sidecar is not None:
        try:
            return Entry(path.stem, scene_files.load_sidecar(sidecar, path), f"{path} + {sidecar.name}")
        except InputError as exc:
            return Entry(
                path.stem,
                sc.override(sc.Scene(), height=str(paths.resolved(path))),
                f"{path} + {sidecar.name}",
                error=str(exc),
            )
    return Entry(path.stem, sc.override(sc.Scene(), height=str(paths.resolved(path))), str(path))


def estimate_peak_bytes(entry: Entry) -> int:
    """Return ``entry``'s sweep's estimated peak from its size alone.

    The estimate is :func:`hzval.truth.memory.estimate_peak_bytes`'s; the size is a height map's header or a
    built-in material's ``size``. A map that cannot be read counts as tiny (it will fail on its own).
    """
    try:
        rows, cols = memory.material_shape(entry.scene)
    except InputError:
        rows = cols = 1
    return memory.estimate_peak_bytes(entry.scene, rows, cols)


def default_workers(items: list[Entry], cores: int | None = None, available: int | None = None) -> int:
    """Return the number of workers for this machine.

    That is one per core (each then runs Dr.Jit and FLIP on one thread, which swept the built-in suite faster
    than one worker on every core: docs/internals.md), no more than there are materials, and no more than fit
    in 80% of the available memory beside each other at the largest material's estimated peak
    (:func:`estimate_peak_bytes`).
    """
    cores = (os.cpu_count() or 1) if cores is None else cores
    available = resources.available_bytes() if available is None else available
    largest = max((estimate_peak_bytes(e) for e in items), default=1)
    return max(1, min(len(items), cores, int(0.8 * available // largest)))


# --------------------------------------------------------------------------
# One material, in a worker
# --------------------------------------------------------------------------


def sweep_material(task: Task) -> dict:
    """Sweep one material into ``task.out`` and return its row of ``suite.json``.

    The row is :func:`summarise`'s, or ``{"status": "failed", "error": <one line>}``. Runs in a worker
    process; never raises for a material's own failure, so one bad material cannot take the others down.
    """
    entry, out = task.entry, Path(task.out)
    t0 = time.perf_counter()
    if entry.error:
        return _failed(entry, entry.error, 0.0)
    _log_start(task)
    try:
        if task.token and _read(out.parent / TOKEN_FILE) != task.token:
            raise InputError(
                out.parent,
                f"this worker ({socket.gethostname()}) cannot see the suite's folder: "
                "--cluster needs it on a filesystem the workers share",
            )
        backend.variant(task.variant)
        if task.threads:
            # in the worker, once its variant is set
            import drjit as dr

            dr.set_thread_count(task.threads)
        result = sweep.run(
            entry.scene, out, options=task.options, command=task.command, progress=False, force=task.force
        )
        return summarise(entry, result)
    except errors.HzvalError as exc:
        return _failed(entry, str(exc), time.perf_counter() - t0)
    except Exception as exc:  # a material's crash is its own row, not the suite's end
        return _failed(
            entry,
            f"{type(exc).__name__}: {errors.first_line(exc)}",
            time.perf_counter() - t0,
            traceback.format_exc(),
        )


def _earlier_rows(out: Path) -> dict[str, dict]:
    """Return the finished materials of an earlier suite in ``out`` whose reports are still there, by name.

    They come from its ``suite.json``, their origins as given (:func:`hzval.report.overview.write_overview`
    makes them portable again); none where there is no readable overview.
    """
    try:
        rows = documents.read_json(out / "suite.json").get("materials") or []
    except (InputError, AttributeError):
        return {}
    kept = {}
    for row in rows:
        if not isinstance(row, dict) or row.get("status") != "ok" or not isinstance(row.get("name"), str):
            continue
        if (out / row["name"] / "metrics.json").is_file():
            kept[row["name"]] = {**row, "origin": _given_origin(row.get("origin"), out)}
    return kept


def _given_origin(origin, out: Path):
    """Return a row's origin with its path resolved against ``out``.

    This is the inverse of :func:`_portable_origin`.
    """
    if not isinstance(origin, str) or origin == "built-in":
        return origin
    path, plus, rest = origin.partition(" + ")
    return str((out / path).resolve()) + (plus + rest if plus else "")


def _facing_mean(records: list[dict]) -> dict:
    """Return the mean ``visibility_mae_facing`` over the records that have one.

    The result is ``{"visibility_mae_facing": mean}``; ``{}`` where none has (a view without a facing mask),
    so that the row's |F - V| is its whole image's.
    """
    mean = _mean(r.get("visibility_mae_facing") for r in records)
    return {} if mean is None else {"visibility_mae_facing": mean}


def _not_run(entry: Entry, why: str = "the suite was interrupted first") -> dict:
    return {
        "name": entry.name,
        "origin": entry.origin,
        "status": "not run",
        "error": f"not run: {why}",
        "seconds": None,
    }


#: The Dask event topic on which a task says it has started (:func:`_log_start`), by the suite's pid.
START_TOPIC = "hzval-suite-started-{pid}"


def _log_start(task: Task) -> None:
    """Tell the scheduler, on a Dask worker, that this material has started.

    A worker's death is then told apart from the loss of workers before a material ran (:func:`_classify`).
    """
    if not task.topic:
        return
    try:
        # Dask: 0.5 s to import, paid only by a suite on workers
        import distributed

        distributed.get_worker().log_event(task.topic, {"name": task.entry.name})
    except Exception:  # not on a worker, or the scheduler is gone: nothing to tell
        pass


def _read(path: Path) -> str | None:
    try:
        return path.read_text(encoding="utf-8")
    except OSError:
        return None


def _failed(entry: Entry, error: str, seconds: float | None, trace: str | None = None) -> dict:
    row = {"name": entry.name, "origin": entry.origin, "status": "failed", "error": error, "seconds": seconds}
    if trace:
        row["traceback"] = trace
    return row


def _mean(values) -> float | None:
    vals = [float(v) for v in values if isinstance(v, (int, float)) and math.isfinite(v)]
    return float(np.mean(vals)) if vals else None


def summarise(entry: Entry, metrics: dict) -> dict:
    """Return a material's row of ``suite.json`` from its sweep's ``metrics.json`` content.

    The row holds, per technique, the mean over the sweep of each of :data:`MEANS` (``seconds``: the mean
    frame time), the floor's mean FLIP, the sweep's time and peak memory, and where its report is (relative to
    the suite).
    """
    frames = metrics["frames"]
    run = SweepResult.of(metrics)
    scores = [f.techniques for f in run.frames]
    table = ranking.by_elevation(metrics)
    # |F - V| as the sweep's report and its ranking measure it: over the pixels facing the light, where
    # the sweep has them (ranking.visibility_of reads it, else the whole image's visibility_mae)
    techniques = {
        name: {key: _mean(per[name].get(key) for per in scores) for key in MEANS}
        | _facing_mean([per[name] for per in scores])
        | {"worse_at": ranking.worse_than_none(table, name)}
        for name in run.techniques
    }
    m, p = metrics["material"], metrics["parameters"]
    return {
        "name": entry.name,
        "origin": entry.origin,
        "status": "ok",
        "report": f"{entry.name}/index.html",
        "source": m.get("source"),
        "digest": m.get("digest"),
        "rows": m.get("rows"),
        "cols": m.get("cols"),
        "depth": p["depth"],
        "boundary": p["boundary"],
        "azimuths_deg": list(p.get("azimuths_deg") or dict.fromkeys(f["azimuth_deg"] for f in frames)),
        "elevations_deg": list(p.get("elevations_deg") or [p.get("elevation_deg")]),
        "techniques": techniques,
        "floor": {"flip_mean": _mean((f.get("floor") or {}).get("flip_mean") for f in frames)},
        "no_shadows": {
            "visibility_mae": _mean((f.get("no_shadows") or {}).get("visibility_mae") for f in frames),
            **_facing_mean([f.get("no_shadows") or {} for f in frames]),
            "flip_mean": _mean((f.get("no_shadows") or {}).get("flip_mean") for f in frames),
        },
        "truth_s": _mean(f.get("truth_s") for f in frames),
        "seconds": metrics["timings"]["total_s"],
        "peak_rss_bytes": metrics["memory"]["peak_rss_bytes"],
        "variant": metrics["versions"].get("variant"),  # the Mitsuba variant its worker ran
        "files": _thumbnail_sources(run.frames, run.names),
    }


def _thumbnail_sources(frames: list[FrameRecord], techniques: list[str]) -> dict:
    """Return the thumbnails' PNGs for the sweep's first, middle and last lights.

    The result is ``{light: {"truth": png, <technique>: png}}`` (``light``: ``+15°``, and its elevation in a
    sweep over several), the paths relative to the material's folder.
    """
    n = len(frames)
    picks = sorted({0, n // 2, n - 1})[:LIGHTS_SHOWN]
    out = {}
    for i in picks:
        f = frames[i]
        label = f"{f['azimuth_deg']:+g}°"
        if str(f.get("name", "")).startswith("el"):  # a sweep over several elevations
            label += f" (elevation {f['elevation_deg']:g}°)"
        out[label] = {
            "truth": f["files"]["truth_png"],
            **{name: f.techniques[name].files["png"] for name in techniques},
        }
    return out


# --------------------------------------------------------------------------
# Running them all
# --------------------------------------------------------------------------


def run(
    items: list[Entry],
    out: str | Path,
    *,
    options=None,
    workers: int = 1,
    cluster: str | None = None,
    variant: str | None = None,
    command: str = "",
    progress: bool = True,
    force: bool = False,
    gates=None,
) -> dict:
    """Sweep every entry into ``out/<name>``, then write the overview; return ``suite.json``'s content.

    ``workers``: worker processes on this machine, each sweeping one material at a time (see
    :func:`default_workers`); 0 sweeps them in this process, one after another, with no process
    between a material that crashes and the others;
    ``cluster``: a Dask scheduler's address instead (its workers decide). The overview is written
    once every material is in, failed ones included; the run holds ``out``
    (:func:`hzval.io.staging.output_folder`, ``force`` as there) as each sweep holds its material's
    folder. With more than one
    worker, worker processes are spawned: a script that calls this must do so under
    ``if __name__ == "__main__":``. Ctrl-C stops the run with an overview of what finished (the rest
    marked "not run"), each finished material's report whole. ``gates`` (:class:`hzval.commands.gates.Gates`):
    tested on each finished material's ``metrics.json`` (a ``--baseline`` is an earlier suite's folder,
    whose ``<name>/metrics.json`` each material is compared with), their failures in ``suite.json``'s
    ``gates`` and at the top of the overview (:func:`gate_failures`).
    """
    if workers < 0:
        raise InputError("--workers", f"must be 0 (this process) or more, got {workers}")
    if cluster is not None:
        check_address(cluster)
    out = Path(out).resolve()  # the tasks' paths must mean the same on every worker
    options = options or sweep.Options()
    local = cluster is None
    threads = max(1, (os.cpu_count() or 1) // workers) if local and workers > 0 else None
    token = "" if local else f"{socket.gethostname()}:{os.getpid()}:{time.time_ns()}"
    topic = "" if local and workers == 0 else START_TOPIC.format(pid=os.getpid())
    tasks = [
        Task(
            e,
            str(out / e.name),
            options,
            variant,
            f"{command}  # material {e.name}",
            threads,
            token,
            force,
            topic,
        )
        for e in items
    ]
    t0 = time.perf_counter()
    rows: list[dict | None] = [None] * len(tasks)
    engine = {"name": "in-process", "started": time.time()}

    earlier = _earlier_rows(out)

    def overview(interrupted: bool = False) -> dict:
        # interrupted, a material this run did not finish keeps the earlier run's row where its
        # report is still on disk (an interrupted sweep leaves it as it was)
        done = [
            r if r is not None else earlier.get(t.entry.name) or _not_run(t.entry)
            for t, r in zip(tasks, rows)
        ]
        return overview_page.write_overview(
            out,
            done,
            command=command,
            engine=engine["name"],
            workers=workers if local else None,
            cluster=cluster,
            seconds=time.perf_counter() - t0,
            interrupted=interrupted,
            gates=None if interrupted or not gates else gate_failures(gates, out, done),
        )

    with staging.output_folder(out, force=force, keep_on_interrupt=True):
        try:
            if token:
                (out / TOKEN_FILE).write_text(token, encoding="utf-8")
            if local and workers == 0:
                _run_here(tasks, rows, progress)
            else:
                _run_dask(tasks, rows, engine, workers if local else None, cluster, progress)
        except KeyboardInterrupt:
            overview(interrupted=True)
            raise
        finally:
            (out / TOKEN_FILE).unlink(missing_ok=True)
        return overview()


#: A Dask scheduler's address: ``tcp://HOST:PORT`` (or ``tls://``; ``HOST:PORT`` means tcp).
ADDRESS = re.compile(r"(?:(?:tcp|tls)://)?(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+):(\d{1,5})")


def check_address(address: str) -> str:
    """Return ``address`` if it is a Dask scheduler's, else refuse it in one line.

    A scheduler's address is :data:`ADDRESS`, with a port up to 65535; the line names ``--cluster`` and the
    value.
    """
    m = ADDRESS.fullmatch(str(address))
    if m is None or not 0 < int(m.group(2)) < 65536:
        raise InputError(
            "--cluster",
            f"{address!r} is not a Dask scheduler address: give tcp://HOST:PORT "
            "(e.g. tcp://10.0.0.5:8786, the address dask scheduler prints)",
        )
    return address


def _bar(total: int, progress: bool):

    return tqdm(
        total=total, desc="suite", unit="material", disable=not progress, file=sys.stderr, leave=False
    )


def _run_here(tasks: list[Task], rows: list, progress: bool) -> None:
    """Run each task in this process, one after another, into ``rows`` in the tasks' order.

    A signal held during one material's swap stops the suite once that material is in
    (:func:`hzval.core.interrupts.cases`).
    """
    with interrupts.cases(), _bar(len(tasks), progress) as bar:
        for i, task in enumerate(tasks):
            bar.set_postfix_str(task.entry.name)
            rows[i] = sweep_material(task)
            bar.update()


def _run_dask(
    tasks: list[Task], rows: list, engine: dict, workers: int | None, address: str | None, progress: bool
) -> None:
    """Run each task on a Dask cluster, into ``rows`` (in the tasks' order) as they finish.

    The cluster is a ``LocalCluster`` of ``workers`` processes, or the scheduler at ``address``;
    ``engine["name"]`` says which.
    """
    import dask  # imported here: 0.5 s that a suite in this process does not need
    import distributed

    cluster = None
    # Dask's nanny starts its workers with MALLOC_TRIM_THRESHOLD_=65536, which turns off glibc's
    # adaptive mmap threshold (every large NumPy temporary mapped afresh; benchmarks/README.md, "The
    # built-in suite: workers on this machine"): unset it, and give OpenMP the worker's threads.
    threads = tasks[0].threads if tasks and tasks[0].threads else 1
    environ = {
        f"distributed.nanny.pre-spawn-environ.{k}": threads
        for k in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")
    }
    environ["distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_"] = None
    # a local cluster's scratch space (dask-scratch-space) in a folder of our own, removed at the end
    scratch = tempfile.mkdtemp(prefix="hzval-dask-") if address is None else None
    if scratch:
        environ["temporary-directory"] = scratch
    with dask.config.set({"distributed.scheduler.allowed-failures": 0, **environ}):
        if address is None:
            # on loopback only, and no dashboard: nothing of a local cluster is served to the network
            cluster = distributed.LocalCluster(
                n_workers=workers,
                threads_per_worker=1,
                processes=True,
                host=LOOPBACK,
                dashboard_address=None,
                worker_dashboard_address=None,
                silence_logs=logging.ERROR,
                local_directory=scratch,
            )
            address = cluster.scheduler_address
        try:
            client = distributed.Client(address, timeout=f"{CONNECT_TIMEOUT_S}s")
        except (OSError, ValueError, TypeError) as exc:
            if cluster is not None:
                cluster.close()
            _remove(scratch)
            raise InputError(
                "--cluster", f"no Dask scheduler at {address} ({errors.first_line(exc)})"
            ) from None
    engine["name"] = f"dask.distributed {distributed.__version__} at {address}"
    futures: dict = {}
    try:
        futures = {
            client.submit(
                sweep_material, t, key=f"hzval-suite-{t.entry.name}-{os.getpid()}-{i}", pure=False, retries=0
            ): i
            for i, t in enumerate(tasks)
        }
        with _bar(len(tasks), progress) as bar:
            for future in distributed.as_completed(futures):
                i = futures[future]
                try:
                    rows[i] = future.result()
                except Exception as exc:  # the worker died (KilledWorker), the scheduler was lost, ...
                    started = _started(client, tasks[i].topic) if tasks[i].topic else None
                    rows[i] = _classify(tasks[i], exc, started, engine.get("started", time.time()))
                bar.set_postfix_str(tasks[i].entry.name)
                bar.update()
    finally:
        client.cancel(list(futures))  # an interrupted suite leaves nothing running on the cluster
        client.close()
        if cluster is not None:
            cluster.close()
        _remove(scratch)


def _remove(folder: str | None) -> None:
    if folder:
        shutil.rmtree(folder, ignore_errors=True)


#: Where a local cluster's scheduler, workers and nannies listen.
LOOPBACK = "127.0.0.1"


def _started(client, topic: str) -> set[str] | None:
    """Return the materials whose tasks said they started (:func:`_log_start`).

    ``None`` if the scheduler cannot say (it is gone).
    """
    try:
        return {msg.get("name") for _, msg in client.get_events(topic)}
    except Exception:
        return None


def _classify(task: Task, exc: BaseException, started: set[str] | None, since: float) -> dict:
    """Return a material's row when its task did not return.

    The row is its report if that completed all the same (:func:`_completed`); else, by what failed, "not run"
    (no worker ever started it), failed with "its worker died" (:class:`distributed.KilledWorker` of a started
    task), or failed or "not run" with "the scheduler was lost".
    """
    # Dask: 0.5 s to import, paid only by a suite on workers
    import distributed

    done = _completed(task, since)
    if done is not None:
        return done
    name = task.entry.name
    ran = None if started is None else name in started
    if isinstance(exc, distributed.KilledWorker):
        if ran is False:
            return _not_run(task.entry, "the workers it was given died before it started")
        return _failed(task.entry, "its worker died while sweeping it (killed, or out of memory)", None)
    lost = (
        isinstance(exc, (OSError, distributed.CancelledError, TimeoutError))
        or "cancel" in type(exc).__name__.lower()
    )
    if lost:
        if ran is False or (started is None and not Path(task.out).exists()):
            return _not_run(task.entry, f"the scheduler was lost before it started ({type(exc).__name__})")
        return _failed(task.entry, f"the scheduler was lost while it ran ({type(exc).__name__})", None)
    return _failed(
        task.entry, f"its task could not run: {type(exc).__name__}: {errors.first_line(exc)}", None
    )


def _completed(task: Task, since: float) -> dict | None:
    """Return the row of a material whose sweep wrote its whole report during this suite.

    Its ``metrics.json`` was swapped in after ``since``, a wall-clock time, though its task's result never
    came back.
    """
    path = Path(task.out) / "metrics.json"
    try:
        if path.stat().st_mtime < since:
            return None

        return summarise(task.entry, json.loads(path.read_text(encoding="utf-8")))
    except (OSError, ValueError, KeyError, TypeError):
        return None


# --------------------------------------------------------------------------
# The overview
# --------------------------------------------------------------------------


def gate_failures(gates, out: Path, rows: list[dict]) -> dict:
    """Return ``suite.json``'s ``gates``: each finished material's ``metrics.json`` tested by ``gates``.

    ``gates`` is a :class:`hzval.commands.gates.Gates`; a material's baseline is the same material's in the
    baseline suite's folder, and each failure line names the material. A material whose gates cannot be
    evaluated (no baseline of it, a baseline of another shape or settings) gets a line in ``errors`` (exit 2);
    the others are still tested.
    """
    failed, unevaluated = [], []
    for row in rows:
        if row["status"] != "ok":
            continue
        name = row["name"]
        metrics = documents.read_json(out / name / "metrics.json")
        try:
            baseline = material_baseline(gates, name)
            lines, _ = gates.failures(
                metrics, baseline=baseline, where=name, use_baseline=baseline is not None
            )
        except InputError as exc:  # another material's settings, a metric it lacks: its own line
            unevaluated.append(f"{name}: {exc}")
            continue
        failed += lines
    return {**gates.record(failed, []), **({"errors": unevaluated} if unevaluated else {})}


def material_baseline(gates, name: str) -> dict | None:
    """Return the baseline suite's ``metrics.json`` of material ``name``.

    It is checked by :func:`hzval.commands.gates.read_baseline`; ``None`` without ``--baseline``.
    """
    if gates.baseline_path is None:
        return None
    path = gates.baseline_path / name / "metrics.json"
    if not path.is_file():
        raise InputError("--baseline", f"{path} is missing (no such material in the baseline suite)")
    return gates_module.read_baseline(path)
