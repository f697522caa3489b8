"""Where a sweep's resident memory goes: ``hzval sweep`` in this process, its RSS sampled every
50 ms, each sample charged to the stage running then (the bake, the truth's mesh and its BVH, the
truth's camera rays, each technique's set-up, each frame's truth, techniques, comparison and files).

``tracemalloc`` sees none of Dr.Jit's or Embree's memory; ``/proc/self/status`` VmRSS does.

    python benchmarks/memory_timeline.py [--keep-samples N] -- SWEEP ARGS

``--keep-samples``: override :data:`hzval.truth.samples.KEEP_SAMPLES` (e.g. 0, so that a 2048 sweep works in
bands as a 4096 one does, to scale its figures by 4). Prints one line a stage: its start and end
RSS and the highest RSS seen during it (GiB), and its seconds.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import sys
import threading
import time

from hzval.truth import samples as truth_samples


def rss_bytes() -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    return 0


class Timeline:
    """Stages (a stack of names) and the RSS seen in each, sampled by a thread."""

    def __init__(self, period: float = 0.05):
        self.stack: list[str] = []
        self.rows: list[list] = []  # [name, start rss, peak rss, end rss, start t, end t]
        self.open: list[list] = []
        self.period, self.stop = period, False
        self.thread = threading.Thread(target=self._sample, daemon=True)
        self.thread.start()

    def _sample(self):
        while not self.stop:
            r = rss_bytes()
            for row in self.open:
                row[2] = max(row[2], r)
            time.sleep(self.period)

    @contextlib.contextmanager
    def stage(self, name: str):
        r = rss_bytes()
        row = [("  " * len(self.open)) + name, r, r, r, time.perf_counter(), 0.0]
        self.rows.append(row)
        self.open.append(row)
        try:
            yield
        finally:
            row[3] = rss_bytes()
            row[2] = max(row[2], row[3])
            row[5] = time.perf_counter()
            self.open.remove(row)

    def wrap(self, owner, attr: str, name: str | None = None):
        fn = getattr(owner, attr)

        @functools.wraps(fn)
        def inner(*a, **k):
            label = name or attr
            if attr == "render" and a and len(a) > 1:
                label = f"{owner.__name__}.render({a[1]:g})"
            with self.stage(label):
                return fn(*a, **k)

        setattr(owner, attr, inner)

    def print(self):
        g = 2**30
        print(f"{'stage':48s} {'start':>7s} {'peak':>7s} {'end':>7s} {'s':>7s}")
        for name, r0, rp, r1, t0, t1 in self.rows:
            print(f"{name:48s} {r0 / g:7.2f} {rp / g:7.2f} {r1 / g:7.2f} {t1 - t0:7.1f}")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--keep-samples", type=int, default=None)
    ap.add_argument(
        "--peak-target",
        type=float,
        default=None,
        help="GiB: override hzval.core.budget.PEAK_TARGET_BYTES (a smaller map's mesh in bands)",
    )
    ap.add_argument("sweep", nargs=argparse.REMAINDER)
    args = ap.parse_args(argv)
    sweep_args = [a for a in args.sweep if a != "--"]

    import mitsuba as mi

    from hzval.bake import maps as bake
    from hzval.cli import main as cli
    from hzval.geometry import tile as mesh
    from hzval.pipeline import sweep
    from hzval.techniques import surface
    from hzval.truth import plane as truth

    if args.peak_target is not None:
        from hzval.core import budget

        budget.PEAK_TARGET_BYTES = int(args.peak_target * 2**30)
    if args.keep_samples is not None:
        truth_samples.KEEP_SAMPLES = args.keep_samples
    tl = Timeline()
    tl.wrap(bake, "cached_bake")
    tl.wrap(sweep, "check_fits")
    tl.wrap(truth.Truth, "__init__", "Truth.__init__")
    tl.wrap(mesh, "tessellate")
    tl.wrap(mesh, "displaced_mesh")
    tl.wrap(mi, "load_dict", "mi.load_dict (Embree BVH)")
    from hzval.truth import bands as truth_bands

    tl.wrap(truth_bands, "band_pass")
    tl.wrap(truth.Truth, "_trace_camera_rays")
    tl.wrap(truth.Truth, "render")
    tl.wrap(surface, "unshadowed")
    tl.wrap(sweep, "_build_techniques")
    tl.wrap(sweep, "_render")
    tl.wrap(sweep, "_finish")
    tl.wrap(sweep, "set_up")
    t0 = time.perf_counter()
    try:
        cli.main(["sweep", *sweep_args])
    except SystemExit as exc:
        if exc.code not in (0, None):
            raise
    finally:
        tl.stop = True
        tl.print()
        print(f"wall {time.perf_counter() - t0:.1f} s")
        import resource

        print(f"maxrss {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20:.2f} GiB")


if __name__ == "__main__":
    main(sys.argv[1:])
