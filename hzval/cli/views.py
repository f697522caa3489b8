"""``hzval views``: one material swept from a set of views with a set of lookups.

See :mod:`hzval.commands.views`.
"""

from __future__ import annotations

from pathlib import Path

from hzval.cli import flags, scenes
from hzval.core import errors

#: The command's own scene defaults (:func:`hzval.cli.scenes.scene_from_args`).
DEFAULTS = {"size": 128, "azimuths": "-60:60:30", "spp": 4}


def add_parser(sub) -> None:
    """Add the ``views`` command's parser to ``sub``."""
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.commands import views

    p = sub.add_parser(
        "views",
        help="the light sweep from a set of views, and where each technique breaks",
        description="Sweep one material from the top, orthographically at 60, 45, 30 and 15 "
        "degrees and in perspective near and far, each with bilinear reads, "
        "mip-maps, parallax occlusion mapping and both; write DIR/<view>/<lookup>/ "
        "(sweep reports), DIR/views.json and DIR/index.html, which plots each "
        "technique's error against view elevation and pixel footprint.",
    )
    flags.add_material_args(p, default_size=DEFAULTS["size"])
    p.add_argument(
        "--azimuths", default=None, help=f"light azimuths in degrees (default {DEFAULTS['azimuths']})"
    )
    p.add_argument(
        "--elevation",
        type=float,
        default=None,
        help=f"light elevation in degrees (default {flags.light_default().elevation_deg:g})",
    )
    p.add_argument("--spp", type=int, default=None, help=f"samples per pixel (default {DEFAULTS['spp']})")
    p.add_argument(
        "--views", default=None, help=f"comma-separated views (default all: {', '.join(views.VIEWS)})"
    )
    p.add_argument(
        "--lookups", default=None, help=f"comma-separated lookups (default all: {', '.join(views.LOOKUPS)})"
    )
    p.add_argument("--out", type=Path, default=None, help="output folder (default reports/views-<name>)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(run=run)


def run(args) -> int:
    """Sweep every view and lookup of ``args``; print a row each."""
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.commands import views
    from hzval.metrics.results import techniques_of

    scene = scenes.scene_from_args(args, DEFAULTS)
    out = args.out or Path("reports") / f"views-{scene.name}"
    command = flags.command_line(args)
    data = views.run(
        scene,
        out,
        views=flags.names(args.views),
        lookups=flags.names(args.lookups),
        progress=not args.quiet,
        command=command,
        force=args.force,
    )
    names = sorted({n for r in data["rows"] for n in techniques_of(r)})
    print(
        f"{'view':10} {'lookup':14} {'footprint':>9} {'parallax':>9}  " + "  ".join(f"{n:>9}" for n in names)
    )
    for r in data["rows"]:
        fp, pe = r["footprint_texels"].get("p50"), r["parallax_error_texels"].get("mean")
        vals = "  ".join(f"{views.headline(techniques_of(r)[n]):9.4f}" for n in names)
        print(
            f"{r['view']:10} {r['lookup']:14} {fp if fp is not None else float('nan'):9.2f} "
            f"{pe if pe is not None else float('nan'):9.3f}  {vals}"
        )
    print(
        "|F-V|: over the pixels facing the light in the top view (as hzval sweep), the whole image elsewhere"
    )
    print(f"report: {out / 'index.html'}")
    return errors.EXIT_OK
