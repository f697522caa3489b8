"""``hzval bake``: the textures of a height map (:func:`hzval.bake.maps.bake`), and its mesh."""

from __future__ import annotations

import time
from pathlib import Path

from hzval.cli import flags, scenes
from hzval.core import errors


def add_parser(sub) -> None:
    p = sub.add_parser(
        "bake",
        help="bake normal, horizon and ambient maps from a height map",
        description="Bake the horizon-mapping textures of a height map (docs/ARCHITECTURE.md).",
    )
    flags.add_material_args(p)
    flags.add_bake_flags(p)
    p.add_argument(
        "--mesh",
        dest="write_mesh",
        action="store_true",
        help="also write the displaced triangle mesh as mesh.ply",
    )
    p.add_argument("--out", required=True, type=Path, help="output folder")
    p.set_defaults(run=run)


def run(args) -> int:
    """Bake the material of ``args`` into ``--out``; one line of figures."""
    from hzval.bake import maps as bake
    from hzval.geometry import tile as mesh
    from hzval.io import staging
    from hzval.truth import memory

    scene = scenes.scene_from_args(args, quiet=True)  # HEIGHT's sidecar gives depth and boundary
    params = flags.bake_params(args, scene)
    rows, cols = memory.material_shape(scene)  # estimated before the map is decoded or generated
    bake.check_fits(args.height or "--size", rows, cols, params)
    t0 = time.perf_counter()
    with staging.output_folder(args.out, force=args.force):
        height, info = scenes.load_material(scene)
        info["path"] = staging.report_path(info["path"], args.out)  # bake.json carries no absolute folders
        t_load = time.perf_counter() - t0
        if args.write_mesh:  # before the bake: a mesh that cannot be built leaves nothing written
            need = bake.estimate_bytes(*height.shape, params)
            mesh.check_fits(args.height or "--size", height, params.depth, params.boundary, also=need)
        result = bake.bake(height, params)
        result.timings = {"load_s": t_load, **result.timings}
        written = bake.write_bake(result, args.out, input_info=info)
        if args.write_mesh:
            m = mesh.displaced_mesh(height, params.depth, params.boundary)
            mesh.write_ply(m, args.out / "mesh.ply")
            written.append(args.out / "mesh.ply")
    total = time.perf_counter() - t0
    rows, cols = height.shape
    how = (
        f"radius {params.radius}, {params.angles} bins, {params.directions} directions"
        if params.method == "seed"
        else "exact horizons, unlimited radius"
    )
    print(
        f"baked {scenes.input_name(args, info)} ({cols}x{rows}, depth {params.depth:g}, {how}, "
        f"{params.boundary}) in {total:.2f} s -> {args.out} ({len(written)} files)"
    )
    return errors.EXIT_OK
