"""Benchmark: the distributed engines hzval suite could run on, side by side.

For Dask distributed (hzval's dependency) and Ray (measured if it is
installed: ``pip install ray``): the time to import it, to start a local
cluster of ``--workers`` worker processes, and to run ``--tasks`` small tasks
(a NumPy sum each) through it, then the size its packages take on disk.
One run, one table, the ratios Ray / Dask in the last column. Usage::

    .venv/bin/python benchmarks/bench_suite_engines.py [--workers 2] [--tasks 16]
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import subprocess
import sys
import time
from pathlib import Path


def work(n: int) -> float:
    import numpy as np

    return float(np.sum(np.arange(n)))


def _dask(workers: int, tasks: int) -> dict:
    t0 = time.perf_counter()
    import distributed

    t_import = time.perf_counter() - t0
    cluster = distributed.LocalCluster(
        n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0"
    )
    client = distributed.Client(cluster)
    t_up = time.perf_counter() - t0 - t_import
    t1 = time.perf_counter()
    client.gather([client.submit(work, 1000 + i, pure=False) for i in range(tasks)])
    t_tasks = time.perf_counter() - t1
    client.close()
    cluster.close()
    return {"import": t_import, "up": t_up, "tasks": t_tasks, "package": ("distributed", "dask")}


def _ray(workers: int, tasks: int) -> dict:
    t0 = time.perf_counter()
    import ray

    t_import = time.perf_counter() - t0
    ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
    t_up = time.perf_counter() - t0 - t_import
    remote = ray.remote(work)
    t1 = time.perf_counter()
    ray.get([remote.remote(1000 + i) for i in range(tasks)])
    t_tasks = time.perf_counter() - t1
    ray.shutdown()
    return {"import": t_import, "up": t_up, "tasks": t_tasks, "package": ("ray",)}


def _installed_mb(packages: tuple[str, ...]) -> float:
    """Size on disk of the packages' own folders (not of their dependencies), MiB."""
    total = 0
    for package in packages:
        root = Path(importlib.util.find_spec(package).origin).parent
        total += sum(p.stat().st_size for p in root.rglob("*") if p.is_file())
    return total / 2**20


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--tasks", type=int, default=16)
    p.add_argument("--engine", choices=["dask", "ray"], help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.engine:  # one engine in a fresh process: imports are cold
        r = {"dask": _dask, "ray": _ray}[args.engine](args.workers, args.tasks)
        print(r["import"], r["up"], r["tasks"], _installed_mb(r["package"]))
        return 0
    rows = {}
    for engine, package in (("dask", "distributed"), ("ray", "ray")):
        if importlib.util.find_spec(package) is None:
            continue
        out = subprocess.run(
            [
                sys.executable,
                __file__,
                "--engine",
                engine,
                "--workers",
                str(args.workers),
                "--tasks",
                str(args.tasks),
            ],
            capture_output=True,
            text=True,
            check=True,
            env={**os.environ, "PYTHONWARNINGS": "ignore"},
        )
        rows[engine] = [float(v) for v in out.stdout.split()[-4:]]
    labels = (
        "import, s",
        f"local cluster of {args.workers} up, s",
        f"{args.tasks} tasks, s",
        "installed, MB",
    )
    print(f"{os.cpu_count()} CPUs; {args.workers} workers, {args.tasks} tasks")
    print(f"{'':28s} {'dask':>8s} {'ray':>8s} {'ray/dask':>9s}")
    for i, label in enumerate(labels):
        d = rows.get("dask", [float("nan")] * 4)[i]
        r = rows.get("ray", [float("nan")] * 4)[i]
        print(f"{label:28s} {d:8.2f} {r:8.2f} {r / d:9.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
