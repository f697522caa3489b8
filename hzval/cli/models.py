"""``hzval models``: what curvature costs, one material on caps, bowls, a ring and the cube.

See :mod:`hzval.commands.models`.
"""

from __future__ import annotations

from pathlib import Path

from hzval.cli import flags, scenes

#: The command's own scene defaults (:func:`hzval.cli.scenes.scene_from_args`); every case is seen
#: by an orthographic camera of this resolution.
DEFAULTS = {
    "size": 128,
    "azimuths": "0,72,144,216,288",
    "spp": 2,
    "camera": "orthographic",
    "resolution": (128, 128),
    "effects": "shadow,diffuse,reflection_occlusion",
}


def add_parser(sub) -> None:
    """Add the ``models`` command's parser to ``sub``."""
    p = sub.add_parser(
        "models",
        help="what curvature costs: the light sweep on spheres, bowls and the cube",
        description="Sweep one material on convex caps of spheres of radius 0.5, 1, 2, 4 and 8 "
        "texture widths, concave bowls of radius 1 and 2, the inside of a torus's ring, "
        "a flat patch and the cube; measure each in a band of local light elevations "
        "against the flat patch on the same texels, with standard errors; write "
        "DIR/<case>/ (sweep reports), DIR/models.json and DIR/index.html, which plots "
        "each technique's error against the signed curvature 1/R (docs/models.md).",
    )
    flags.add_material_args(p, default_size=DEFAULTS["size"])
    p.add_argument(
        "--azimuths", default=None, help=f"light azimuths in degrees (default {DEFAULTS['azimuths']})"
    )
    p.add_argument("--elevation", type=float, default=None, help="light elevation in degrees (default 30)")
    p.add_argument("--spp", type=int, default=None, help=f"samples per pixel (default {DEFAULTS['spp']})")
    p.add_argument("--resolution", default=None, help="pixels WxH of every case (default 128x128)")
    p.add_argument(
        "--effects",
        default=None,
        help="effects of every case: reflection_occlusion scores Toolbag's fade against the traced "
        f"glossy lobe (default {DEFAULTS['effects']})",
    )
    p.add_argument("--out", type=Path, default=None, help="output folder (default reports/models-<name>)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(run=run)


def run(args) -> int:
    """Sweep every case of ``args``'s material; print the table."""
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.commands import models as models_command

    scene = scenes.scene_from_args(args, DEFAULTS)
    out = args.out or Path("reports") / f"models-{scene.name}"
    command = flags.command_line(args)
    data = models_command.run(scene, out, progress=not args.quiet, command=command, force=args.force)
    print(models_command.summary_table(data))
    print(f"report: {out / 'index.html'}")
    return 0
