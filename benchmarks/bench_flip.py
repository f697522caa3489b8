"""hzval's FLIP against another version of itself: the time of one test image's ``flip_error`` against
a kept reference, side by side in one process, and whether the two give the same map bit for bit.

``--baseline`` is a tree of hzval (a checkout, or ``git archive REV | tar -x -C DIR``) whose
``hzval/metrics/flip.py`` is loaded beside this one's:

    git archive 0a0cebd | (mkdir -p /tmp/base && tar -x -C /tmp/base)
    .venv/bin/python benchmarks/bench_flip.py --baseline /tmp/base [--sizes 512,2048] [--repeat 7]
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from functools import partial
from pathlib import Path

import numpy as np


def load(tree: Path, name: str):
    """``hzval/metrics/flip.py`` of ``tree`` as module ``name``."""
    spec = importlib.util.spec_from_file_location(name, tree / "hzval" / "metrics" / "flip.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def best_ms(fn, repeat: int) -> float:
    fn()  # compiles, or loads the kernel cache
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * min(times)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--baseline", type=Path, required=True, help="a tree of another hzval version")
    parser.add_argument("--sizes", default="512,2048", help="image sizes (default 512,2048)")
    parser.add_argument("--repeat", type=int, default=7, help="timed calls of each, best kept (default 7)")
    args = parser.parse_args(argv)
    from hzval.core import backend

    backend.variant()
    new, old = load(Path(__file__).resolve().parents[1], "flip_new"), load(args.baseline, "flip_base")
    rng = np.random.default_rng(0)
    print(f"flip_error of one test image, best of {args.repeat} ms (this machine, {backend.variant()})")
    print(f"  {'size':>6s} {'baseline':>9s} {'this':>9s} {'this/base':>9s}  same bits")
    for n in (int(s) for s in args.sizes.split(",")):
        ref = rng.random((n, n, 3))
        test = np.clip(ref + 0.1 * rng.standard_normal(ref.shape), 0.0, 1.0)
        r_new, r_old = new.FlipReference(ref), old.FlipReference(ref)
        t_old = best_ms(partial(old.flip_error, r_old, test), args.repeat)
        t_new = best_ms(partial(new.flip_error, r_new, test), args.repeat)
        (m_new, mean_new), (m_old, mean_old) = new.flip_error(r_new, test), old.flip_error(r_old, test)
        same = np.array_equal(m_new.view(np.uint32), m_old.view(np.uint32)) and mean_new == mean_old
        print(f"  {n:6d} {t_old:9.1f} {t_new:9.1f} {t_new / t_old:9.2f}  {same}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
