"""Benchmark: a frame's image comparisons, flip-evaluator + colour-science against hzval.metrics.flip + the
Dr.Jit CIEDE2000.

One truth and ``--tests`` test images per size, as a sweep's frame compares
them (:class:`hzval.metrics.compare.Reference` once, then every test image): the
built-in bricks (:func:`hzval.materials.generate`) Lambert-shaded in a brick
colour, the truth with 5% noise as a path tracer's, the tests under lights
2-8 degrees away, one with a darkened patch (a shadow), all as display values
(:func:`hzval.metrics.compare.display`, not timed: both paths take the same display
values). Timed, side by side in one process, alternating old and new:

* old: flip-evaluator (``compare.flip_evaluator_flip``) per test; colour-science's
  Lab of the truth once, and per test its Lab and ``delta_E(method="CIE 2000")``
  (in row blocks on a thread per core, as ``compare`` did);
* new: ``hzval.metrics.flip.FlipReference`` and ``compare.LabImage`` of the truth once,
  and per test ``hzval.metrics.flip.flip_error`` and ``compare.delta_e2000``.

It prints the seconds of each (FLIP's and CIEDE2000's, the truth's part and
the tests', the total), old over new (the total, and FLIP's and CIEDE2000's), and the largest and mean
differences of the values (FLIP map and
mean, CIEDE2000 map) between old and new. The Dr.Jit kernels are compiled (or
loaded from Dr.Jit's cache) before timing.

Usage::

    .venv/bin/python benchmarks/bench_compare.py [--sizes 512,1024,2048] [--tests 4] [--repeat 1]
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np


def _images(size: int, tests: int, seed: int = 0):
    from hzval import materials
    from hzval.metrics import compare

    h = materials.generate("bricks", size, 0).height.astype(np.float64)
    gy, gx = np.gradient(h * 0.05 * size)
    n = np.stack([-gx, gy, np.ones_like(gx)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    colour = np.array([0.62, 0.36, 0.27])

    def shade(az, el=30.0):
        az, el = np.radians(az), np.radians(el)
        light = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
        return np.clip(n @ light, 0, None)[..., None] * colour + 0.03

    rng = np.random.default_rng(seed)
    truth = shade(0.0) * (1 + 0.05 * rng.standard_normal((size, size, 3)))
    out = []
    for i in range(tests):
        img = shade(2.0 * (i + 1))
        if i == 1:
            img[size // 4 : size // 2, size // 5 : size // 2] *= 0.3
        out.append(compare.display(img, 1.5))
    return compare.display(truth, 1.5), out


def _old(ref, tests):
    import colour

    from hzval.metrics import compare

    def lab_of(rgb):
        return colour.XYZ_to_Lab(colour.sRGB_to_XYZ(rgb, apply_cctf_decoding=True))

    clock = dict.fromkeys(("flip_ref", "de_ref", "flip", "de"), 0.0)
    t0 = time.perf_counter()
    ref_lab = compare.by_rows(lab_of, ref)
    clock["de_ref"] = time.perf_counter() - t0
    res = []
    for t in tests:
        t0 = time.perf_counter()
        fmap, fmean = compare.flip_evaluator_flip(ref, t)
        t1 = time.perf_counter()
        de = compare.by_rows(
            lambda a, b: colour.delta_E(a, b, method="CIE 2000"), ref_lab, compare.by_rows(lab_of, t)
        )
        clock["flip"] += t1 - t0
        clock["de"] += time.perf_counter() - t1
        res.append((fmap, fmean, de))
    return clock, res


def _new(ref, tests):
    from hzval.metrics import compare
    from hzval.metrics import flip as hzflip

    clock = dict.fromkeys(("flip_ref", "de_ref", "flip", "de"), 0.0)
    t0 = time.perf_counter()
    fref = hzflip.FlipReference(ref, compare.FLIP_PPD)
    t1 = time.perf_counter()
    lab = compare.LabImage(ref)
    clock["flip_ref"], clock["de_ref"] = t1 - t0, time.perf_counter() - t1
    res = []
    for t in tests:
        t0 = time.perf_counter()
        fmap, fmean = hzflip.flip_error(fref, t)
        t1 = time.perf_counter()
        de = compare.delta_e2000(ref, t, reference_lab=lab)
        clock["flip"] += t1 - t0
        clock["de"] += time.perf_counter() - t1
        res.append((fmap, fmean, de))
    return clock, res


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="512,1024,2048")
    ap.add_argument("--tests", type=int, default=4, help="test images per truth")
    ap.add_argument("--repeat", type=int, default=1, help="runs of each path per size; the best is shown")
    args = ap.parse_args(argv)

    from hzval.core import backend

    variant = backend.variant()
    t0 = time.perf_counter()
    small_ref, small = _images(64, 1)
    _new(small_ref, small)  # compile or load the Dr.Jit kernels
    warm = time.perf_counter() - t0
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(
        f"{platform.processor() or platform.machine()}, {backend.host_cores()} cores, variant {variant}, "
        f"load average {load:.2f}; kernels ready in {warm:.2f} s"
    )
    print(f"1 truth + {args.tests} test images per size; seconds (best of {args.repeat})")
    print(
        f"{'size':>9} {'path':>4} {'FLIP':>7} {'CIEDE2000':>9} {'truth':>7} {'tests':>7} {'total':>7} "
        f"{'old/new':>8}"
    )
    diffs = []
    for size in (int(s) for s in args.sizes.split(",")):
        ref, tests = _images(size, args.tests)
        best = {}
        for _ in range(args.repeat):
            for name, fn in (("old", _old), ("new", _new)):
                clock, res = fn(ref, tests)
                if name not in best or sum(clock.values()) < sum(best[name][0].values()):
                    best[name] = (clock, res)
        for name in ("old", "new"):
            c = best[name][0]
            total = sum(c.values())
            ratio = f" {sum(best['old'][0].values()) / total:8.2f}" if name == "new" else ""
            print(
                f"{size:>4}x{size:<4} {name:>4} {c['flip_ref'] + c['flip']:7.3f} "
                f"{c['de_ref'] + c['de']:9.3f} "
                f"{c['flip_ref'] + c['de_ref']:7.3f} {c['flip'] + c['de']:7.3f} {total:7.3f}{ratio}"
            )
        c_old, c_new = best["old"][0], best["new"][0]
        print(
            f"{'':>9} {'':>4} "
            f"{(c_old['flip_ref'] + c_old['flip']) / (c_new['flip_ref'] + c_new['flip']):6.1f}x "
            f"{(c_old['de_ref'] + c_old['de']) / (c_new['de_ref'] + c_new['de']):8.1f}x"
        )
        old, new = best["old"][1], best["new"][1]
        d_map = max(float(np.max(np.abs(o[0] - n[0]))) for o, n in zip(old, new))
        d_pix = float(np.mean([np.mean(np.abs(o[0] - n[0])) for o, n in zip(old, new)]))
        d_mean = max(abs(o[1] - n[1]) for o, n in zip(old, new))
        d_de = max(float(np.max(np.abs(o[2] - n[2]))) for o, n in zip(old, new))
        d_de_mean = float(np.mean([np.mean(np.abs(o[2] - n[2])) for o, n in zip(old, new)]))
        means = ", ".join(f"{o[1]:.5f}" for o in old)
        diffs.append(
            f"{size:>5}: FLIP mean |d| <= {d_mean:.1e} (old means {means}); FLIP map max |d| {d_map:.1e}, "
            f"mean |d| {d_pix:.1e}; CIEDE2000 max |d| {d_de:.1e}, mean |d| {d_de_mean:.1e}"
        )
    print("differences, new - old:")
    for line in diffs:
        print("  " + line)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
