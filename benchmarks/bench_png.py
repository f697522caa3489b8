"""The frames' PNGs encoded with zlib's default strategy and with its run-length one (``Z_RLE``),
side by side in one process: the encoding's CPU time and the bytes, per kind of file, on the pixels of
a sweep's own files (read back from them), at the sweep's level (``hzval.pipeline.writing.PNG_LEVEL``).

    .venv/bin/python benchmarks/bench_png.py [--sweep reports/bricks] [--repeat 5]

Without ``--sweep``, a sweep (``--size``, default the default 512) is run first into a temporary
folder (about 15 s at 512).
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

#: A file's kind: its name with the technique's stem taken out (``horizon_flip.png`` -> ``flip``).
_KIND = re.compile(r"^(?:.*?_)?(flip|visdiff)\.png$")


def kind(path: Path) -> str:
    """``flip``, ``visdiff``, ``truth`` or ``render`` (a technique's or the unshadowed preview)."""
    m = _KIND.match(path.name)
    return m.group(1) if m else ("truth" if path.stem == "truth" else "render")


def pixels(path: Path):
    """What the sweep's writer encodes: an :class:`hzval.io.codecs.Indexed` image for a palette PNG,
    else the uint8 values."""
    from PIL import Image

    from hzval.io import codecs

    with Image.open(path) as im:
        if im.mode == "P":
            palette = np.asarray(im.getpalette(), np.uint8).reshape(-1, 3)
            return codecs.Indexed(np.asarray(im), palette)
        return np.asarray(im)


def cpu_ms(fn, repeat: int) -> float:
    """The best CPU time of ``fn`` over ``repeat`` calls, in ms."""
    fn()
    best = float("inf")
    for _ in range(repeat):
        t0 = time.thread_time()
        fn()
        best = min(best, time.thread_time() - t0)
    return 1e3 * best


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sweep", type=Path, help="a sweep's folder (default: run the default sweep)")
    parser.add_argument("--repeat", type=int, default=5, help="timed encodings, best kept (default 5)")
    parser.add_argument("--frames", type=int, default=2, help="frames of the sweep to read (default 2)")
    parser.add_argument("--size", type=int, default=512, help="without --sweep: its size (default 512)")
    args = parser.parse_args(argv)
    from hzval.io import codecs
    from hzval.pipeline import writing

    folder = args.sweep
    if folder is None:
        folder = Path(tempfile.mkdtemp()) / "sweep"
        sweep = [sys.executable, "-m", "hzval", "sweep", "--quiet", "--size", str(args.size)]
        subprocess.run([*sweep, "--out", str(folder)], check=True, stdout=subprocess.DEVNULL)
    frames = sorted(p for p in (folder / "frames").iterdir() if p.is_dir())[: args.frames]
    rows: dict[str, list] = {}
    with tempfile.TemporaryDirectory() as tmp:
        target = Path(tmp) / "p.png"
        for frame in frames:
            for path in sorted(frame.glob("*.png")):
                image = pixels(path)
                row = rows.setdefault(kind(path), [0, 0.0, 0.0, 0, 0])
                row[0] += 1
                for i, runs in ((1, False), (2, True)):

                    def encode(runs=runs, image=image):
                        codecs.write_png(
                            target, image, compress_level=writing.PNG_LEVEL, grey=True, runs=runs
                        )

                    row[i] += cpu_ms(encode, args.repeat)
                    row[i + 2] += target.stat().st_size
    print(f"PNG level {writing.PNG_LEVEL}, {len(frames)} frames of {folder}: CPU ms and kB a file")
    heads = ("files", "default", "runs", "ratio", "kB def", "kB runs")
    print(f"  {'kind':8s} " + " ".join(f"{h:>8s}" for h in heads))
    for name, (n, t_def, t_rle, b_def, b_rle) in sorted(rows.items()):
        print(
            f"  {name:8s} {n:8d} {t_def / n:8.2f} {t_rle / n:8.2f} {t_rle / t_def:8.2f}"
            f" {b_def / n / 1e3:8.1f} {b_rle / n / 1e3:8.1f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
