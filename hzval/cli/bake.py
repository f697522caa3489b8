"""``hzval bake``'s flags (:mod:`hzval.commands.bake`)."""

from __future__ import annotations

from pathlib import Path

from hzval.cli import flags, scenes
from hzval.core import errors


def add_parser(sub) -> None:
    """Add the ``bake`` command's parser to ``sub``."""
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
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.commands import bake as bake_command

    scene = scenes.scene_from_args(args, quiet=True)  # HEIGHT's sidecar gives depth and boundary
    params = flags.bake_params(args, scene)
    done = bake_command.run(
        scene, params, args.out, what=args.height or "--size", mesh_too=args.write_mesh, force=args.force
    )
    how = (
        f"radius {params.radius}, {params.angles} bins, {params.directions} directions"
        if params.method == "seed"
        else "exact horizons, unlimited radius"
    )
    print(
        f"baked {scenes.input_name(args, done.info)} ({done.info['cols']}x{done.info['rows']}, depth "
        f"{params.depth:g}, {how}, {params.boundary}) in {done.seconds:.2f} s -> {args.out} "
        f"({len(done.written)} files)"
    )
    return errors.EXIT_OK
