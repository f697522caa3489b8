"""The ``hzval`` command: a thin layer over the stage modules.

Exit status (DESIGN.md): 0 done, 1 check failed, 2 bad input or usage,
3 a machine that cannot run hzval (e.g. a broken LLVM). Errors that the user
can act on are one line on stderr, ``hzval: error: <what>: <problem>``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from hzval import errors


def _add_material_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("height", nargs="?", metavar="HEIGHT",
                   help="height map: PNG (8/16-bit), EXR or .npy; default: the built-in brick wall")
    p.add_argument("--depth", type=float, default=None,
                   help="world height of H = 1 in image widths (default 0.05)")
    p.add_argument("--boundary", choices=["wrap", "open"], default="wrap",
                   help="wrap: the texture tiles; open: a terrain with nothing outside (default wrap)")
    p.add_argument("--size", type=int, default=None, metavar="N",
                   help="size in texels of the built-in material (default 512); ignored with HEIGHT")


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="hzval", description="Validate horizon mapping against ray-traced ground truth.")
    parser.add_argument("--variant", default=None,
                        help="Mitsuba variant (default: cuda_ad_rgb with a GPU, else llvm_ad_rgb; "
                             "or $HZVAL_VARIANT)")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("bake", help="bake normal, horizon and ambient maps from a height map",
                       description="Bake the horizon-mapping textures of a height map (DESIGN.md).")
    _add_material_args(p)
    p.add_argument("--radius", type=int, default=16, help="search radius in texels (default 16)")
    p.add_argument("--angles", type=int, default=32, help="angular bins, a multiple of 16 (default 32)")
    p.add_argument("--mesh", action="store_true",
                   help="also write the displaced triangle mesh as mesh.ply")
    p.add_argument("--out", required=True, type=Path, help="output folder")
    p.set_defaults(run=cmd_bake)
    return parser


def load_material(args) -> tuple["np.ndarray", dict]:  # noqa: F821
    """The height map named on the command line, or the built-in one, with its description."""
    from hzval import heightmap, material

    if args.height is None:
        size = material.DEFAULT_SIZE if args.size is None else args.size
        if size < 2:
            raise errors.InputError("--size", f"must be at least 2 texels, got {size}")
        hm = heightmap.from_array(material.bricks(size), source=f"built-in brick wall, {size}x{size}")
        info = {"path": None, "builtin": "bricks", "size": size}
    else:
        hm = heightmap.load_height(args.height)
        info = {"path": str(args.height)}
    rows, cols = hm.height.shape
    info.update(source=hm.source, digest=hm.digest, rows=rows, cols=cols)
    return hm.height, info


def cmd_bake(args) -> int:
    from hzval import backend, bake, heightmap, material, mesh

    depth = material.DEFAULT_DEPTH if args.depth is None else args.depth
    params = bake.BakeParams(depth=depth, radius=args.radius, angles=args.angles,
                             boundary=args.boundary).validate()
    if args.height is not None:
        rows, cols = heightmap.probe_shape(args.height)
        bake.check_fits(args.height, rows, cols, params)
    t0 = time.perf_counter()
    height, info = load_material(args)
    t_load = time.perf_counter() - t0
    backend.variant(args.variant)
    result = bake.bake(height, params)
    result.timings = {"load_s": t_load, **result.timings}
    written = bake.write_bake(result, args.out, input_info=info)
    if args.mesh:
        from hzval import files

        m = mesh.displaced_mesh(height, params.depth, params.boundary)
        with files.atomic_path(args.out / "mesh.ply") as tmp:
            m.write_ply(str(tmp))
        written.append(args.out / "mesh.ply")
    total = time.perf_counter() - t0
    rows, cols = height.shape
    print(f"baked {info['source']} ({cols}x{rows}, depth {params.depth:g}, radius {params.radius}, "
          f"{params.angles} bins, {params.boundary}) in {total:.2f} s -> {args.out} ({len(written)} files)")
    return errors.EXIT_OK


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        return args.run(args)
    except errors.HzvalError as exc:
        print(f"hzval: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print("hzval: interrupted", file=sys.stderr)
        return 130
