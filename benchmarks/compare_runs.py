"""Whether two versions of hzval give the same scores: run the same commands with each, then compare.

``run`` sweeps the default material, a model, a photo-like map with ambient light on an open
boundary, a small suite and the regression check, with the hzval of ``--source`` (a checkout or
``git archive`` of any commit, imported through ``PYTHONPATH``), into ``--out``. ``compare`` then
holds two such folders side by side: every value of every JSON file except timings, memory,
versions, paths and command lines, and every EXR and PNG pixel, bit for bit. It prints each
difference and exits 1 if there is one.

    git archive 080ad67 | (mkdir -p /tmp/base && tar -x -C /tmp/base)
    python benchmarks/compare_runs.py run --source /tmp/base --out /tmp/runs-base
    python benchmarks/compare_runs.py run --source . --out /tmp/runs-new
    python benchmarks/compare_runs.py compare /tmp/runs-base /tmp/runs-new
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import subprocess
import sys
from pathlib import Path

#: The commands ``run`` runs, each into ``OUT/<name>``.
RUNS = {
    "sweep": ["sweep"],
    "sphere": ["sweep", "--mesh", "sphere", "--size", "128"],
    "gravel-open": [
        "sweep", "--material", "gravel", "--boundary", "open", "--effects", "shadow,diffuse,ambient",
        "--size", "128",
    ],
    "suite": ["suite", "bricks", "gravel", "--size", "64", "--workers", "0"],
    "check": ["check"],
}  # fmt: skip

#: JSON keys whose values are allowed to differ: time, memory, the machine and where things were.
VOLATILE = re.compile(
    r"(_s$|^seconds$|time|timings|memory|peak|rss|versions?$|command|engine|address|machine|"
    r"host|date|path|origin|source_dir|started|llvm|variant|dask|estimate_bytes)",
    re.IGNORECASE,
)


def run(source: Path, out: Path, only: list[str] | None) -> None:
    """Run :data:`RUNS` (or ``only`` of them) with the hzval of ``source``."""
    env = {**os.environ, "PYTHONPATH": str(source.resolve())}
    for name, argv in RUNS.items():
        if only and name not in only:
            continue
        cmd = [sys.executable, "-m", "hzval", *argv, "--out", str(out / name), "--quiet"]
        if argv[0] == "check":
            cmd = [sys.executable, "-m", "hzval", "check", "--out", str(out / name), "--quiet"]
        print(" ".join(cmd[2:]), flush=True)
        done = subprocess.run(cmd, env=env, cwd=source, capture_output=True, text=True)
        if done.returncode not in (0, 1):
            sys.exit(f"{name}: exit {done.returncode}: {done.stderr.strip()[-400:]}")


def _png_digest(key, a, b) -> bool:
    """Whether ``a`` and ``b`` are digests of a PNG file (a bake's record of its files): its bytes
    depend on the encoder (its filters, zlib's level), its pixels are compared as an image."""
    return str(key).endswith(".png") and all(isinstance(v, str) and v.startswith("sha256:") for v in (a, b))


def _json_differences(a, b, where: str) -> list[str]:
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            if VOLATILE.search(str(k)) or _png_digest(k, a.get(k), b.get(k)):
                continue
            if k not in a or k not in b:
                out.append(f"{where}.{k}: only in {'the second' if k not in a else 'the first'}")
            else:
                out += _json_differences(a[k], b[k], f"{where}.{k}")
        return out
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{where}: {len(a)} items against {len(b)}"]
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in _json_differences(x, y, f"{where}[{i}]")]
    same = a == b or (isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b))
    return [] if same else [f"{where}: {a!r} against {b!r}"]


def _pixels(path: Path):
    import numpy as np

    if path.suffix == ".exr":
        from hzval.io import codecs

        return {k: np.asarray(v) for k, v in codecs.read_exr(path).items()}
    from PIL import Image

    with Image.open(path) as img:
        return {"": np.asarray(img)}


def compare(first: Path, second: Path) -> list[str]:
    """Every difference between the runs in ``first`` and ``second`` (module docstring)."""
    import numpy as np

    def listed(root: Path) -> set[str]:
        return {
            p.relative_to(root).as_posix()
            for p in root.rglob("*")
            if p.is_file() and not any(part.startswith(".") for part in p.relative_to(root).parts)
        }

    a, b = listed(first), listed(second)
    out = [f"{n}: only in {first if n in a else second}" for n in sorted(a ^ b)]
    for name in sorted(a & b):
        pa, pb = first / name, second / name
        if name.endswith(".json"):
            out += _json_differences(json.loads(pa.read_text()), json.loads(pb.read_text()), name)
        elif name.endswith((".exr", ".png")) and "/plots/" not in f"/{name}":
            x, y = _pixels(pa), _pixels(pb)
            for c in sorted(set(x) | set(y)):
                if c not in x or c not in y or x[c].shape != y[c].shape:
                    out.append(f"{name} {c}: channels or shapes differ")
                elif not np.array_equal(x[c], y[c], equal_nan=x[c].dtype.kind == "f"):
                    d = np.abs(x[c].astype(np.float64) - y[c].astype(np.float64))
                    out.append(
                        f"{name} {c}: {int(np.count_nonzero(d))} pixels differ, at most {np.nanmax(d):.3g}"
                    )
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="what", required=True)
    r = sub.add_parser("run", help="run the commands with one version of hzval")
    r.add_argument("--source", type=Path, required=True, help="a checkout or archive of hzval")
    r.add_argument("--out", type=Path, required=True, help="where the runs go")
    r.add_argument("--only", default=None, help=f"comma-separated runs of {', '.join(RUNS)}")
    c = sub.add_parser("compare", help="compare two folders that run wrote")
    c.add_argument("first", type=Path)
    c.add_argument("second", type=Path)
    args = parser.parse_args(argv)
    if args.what == "run":
        run(args.source, args.out, args.only.split(",") if args.only else None)
        return 0
    found = compare(args.first, args.second)
    for line in found:
        print(line)
    print(f"{len(found)} differences" if found else "the same: every score and every image, bit for bit")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
