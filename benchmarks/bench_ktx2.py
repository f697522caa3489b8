"""Benchmark: what the KTX2 export's block formats keep of a bake's horizon map, and what they cost.

For each built-in material and block format, the horizon map's first texture as ``hzval
export-textures`` writes it (:func:`hzval.io.ktx2.encode_level`, etcpak's encoder), decoded by
Pillow's DDS decoder (tests/oracles/ktx2_parser.py, not hzval's texture2ddecoder), against the
bake's sines: the mean and largest absolute error of level 0, its bytes, and the encoding time.

Usage::

    python benchmarks/bench_ktx2.py [--size 256] [--materials gravel,bricks,cobblestones,ridges]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

#: The block formats, by storage name, with the channels of the horizon map one texture holds.
FORMATS = {
    "bc7": ("BC7_UNORM_BLOCK", 4),
    "bc3": ("BC3_UNORM_BLOCK", 4),
    "bc1": ("BC1_RGB_UNORM_BLOCK", 3),
    "bc4": ("BC4_UNORM_BLOCK", 1),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--materials", default="gravel,bricks,cobblestones,ridges")
    args = ap.parse_args()

    import hzval

    hzval.init()
    from hzval import materials
    from hzval.bake import maps as bake
    from hzval.io import ktx2
    from tests.oracles import ktx2_parser as oracle

    print(f"{'material':14} {'format':6} {'mean |err|':>10} {'max |err|':>10} {'bytes':>8} {'encode ms':>10}")
    for name in args.materials.split(","):
        h = materials.generate(name, args.size).height
        sines = bake.bake(h, bake.BakeParams()).horizon
        for storage, (fmt_name, per) in FORMATS.items():
            fmt = ktx2.FORMATS[fmt_name]
            values = sines[..., :per]
            t0 = time.perf_counter()
            level = ktx2.encode_level(values, fmt)
            ms = 1000 * (time.perf_counter() - t0)
            with tempfile.TemporaryDirectory() as tmp:
                ktx2.write(Path(tmp) / "t.ktx2", ktx2.Texture(fmt, args.size, args.size, [level]))
                parsed = oracle.parse((Path(tmp) / "t.ktx2").read_bytes())
            decoded = oracle.bc_level(parsed, 0, args.size, args.size)[..., :per].astype(np.float32) / 255.0
            err = np.abs(decoded - values)
            print(f"{name:14} {storage:6} {err.mean():10.4f} {err.max():10.4f} {len(level):8d} {ms:10.1f}")


if __name__ == "__main__":
    main()
