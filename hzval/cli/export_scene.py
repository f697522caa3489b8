"""``hzval export-scene``: the truth of one light as a Mitsuba 3 scene file.

See :mod:`hzval.commands.export_scene`.
"""

from __future__ import annotations

import math
import os
import shutil
import sys
from pathlib import Path

from hzval.cli import flags, scenes
from hzval.core import errors


def add_parser(sub) -> None:
    """Add the ``export-scene`` command's parser to ``sub``."""
    p = sub.add_parser(
        "export-scene",
        help="write the truth of one light as a Mitsuba 3 scene file",
        description="Write DIR/scene.xml and DIR/mesh.ply: the displaced mesh with its vertex "
        "normals, a diffuse BSDF with the albedo, a directional emitter and an "
        "orthographic sensor over the tile, as hzval's truth traces them. "
        "Render it with `mitsuba DIR/scene.xml -o out.exr`.",
    )
    flags.add_material_args(p)
    p.add_argument("--scene", type=Path, default=None, help="scene description (TOML)")
    p.add_argument(
        "--elevation",
        type=float,
        default=None,
        help=f"light elevation in degrees (default {flags.light_default().elevation_deg:g})",
    )
    p.add_argument(
        "--azimuth", type=float, default=0.0, help="light azimuth in degrees (default %(default)g)"
    )
    p.add_argument("--effects", default=None, help="shadow and/or diffuse (default shadow,diffuse)")
    p.add_argument(
        "--spp",
        type=int,
        default=None,
        help=f"samples per pixel (default {flags.scene_module().Scene().spp})",
    )
    p.add_argument(
        "--shading",
        choices=["smooth", "faceted"],
        default=None,
        help="vertex normals in the PLY (smooth, default) or none (faceted)",
    )
    flags.add_truth_tolerance_flag(p)
    flags.add_mesh_flags(p)
    p.add_argument("--out", required=True, type=Path, help="output folder")
    p.set_defaults(run=run)


def run(args) -> int:
    """Write the scene of ``args``'s light ``--azimuth`` into ``--out``."""
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.commands import export_scene
    from hzval.scene import spec as sc

    scene = scenes.scene_from_args(args, quiet=True)
    if not math.isfinite(args.azimuth):
        raise errors.InputError("--azimuth", f"must be a finite number of degrees, got {args.azimuth}")
    export_scene.check_fits(scene)  # before the map is generated or decoded
    hm = sc.load_material_height(scene.material)
    written = export_scene.write_scene(scene, hm.height, args.out, azimuth_deg=args.azimuth, force=args.force)
    print(
        f"wrote {', '.join(str(p) for p in written)}; render it with: {_mitsuba()} {args.out / 'scene.xml'} "
        f"-o {args.out / 'mitsuba.exr'}"
    )
    return errors.EXIT_OK


def _mitsuba() -> str:
    """Return Mitsuba's command as this hzval can run it.

    It is the one beside this Python (a virtualenv's ``bin/``, which need not be on PATH), relative to the
    working folder where it is below it.
    """
    beside = Path(sys.executable).parent / "mitsuba"
    if not beside.is_file():
        return shutil.which("mitsuba") or "mitsuba"
    rel = os.path.relpath(beside)
    return rel if not rel.startswith("..") else str(beside)
