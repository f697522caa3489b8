"""``hzval tradeoff``: what accuracy costs on one material (:mod:`hzval.commands.tradeoff`)."""

from __future__ import annotations

from pathlib import Path

from hzval.cli import flags, scenes
from hzval.core import errors


def _truth_spp() -> int:

    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.commands import tradeoff

    return tradeoff.DEFAULT_TRUTH_SPP


def _default_size() -> int:

    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.commands import tradeoff

    return tradeoff.DEFAULT_SIZE


def add_parser(sub) -> None:
    """Add the ``tradeoff`` command's parser to ``sub``."""
    p = sub.add_parser(
        "tradeoff",
        help="measure what accuracy costs in time and memory on one material",
        description="Measure bake, approximation and truth settings against a converged truth "
        "over the sweep: time, texture memory, visibility error and FLIP; write "
        "tradeoff.json, a Pareto plot and a page that recommends a setting.",
    )
    flags.add_material_args(p, default_size=_default_size())
    p.add_argument(
        "--elevation",
        default=None,
        metavar="DEG",
        help="light elevations in degrees, in (0, 90]: one, START:STOP:STEP or a list "
        f"(default {flags.light_default().elevation_deg:g})",
    )
    p.add_argument(
        "--azimuths",
        default=None,
        help=f"light azimuths in degrees (default {flags.scene_module().DEFAULT_AZIMUTHS_TEXT})",
    )
    p.add_argument(
        "--truth-spp",
        type=int,
        default=None,
        metavar="N",
        help=f"shadow rays per pixel of the converged truth (default {_truth_spp()})",
    )
    p.add_argument(
        "--spp",
        type=int,
        default=None,
        help=f"samples per pixel of the settings (default {flags.scene_module().Scene().spp})",
    )
    p.add_argument(
        "--only",
        action="append",
        default=None,
        metavar="TEXT",
        help="measure only the settings whose names contain TEXT (repeatable)",
    )
    p.add_argument(
        "--fits",
        action="store_true",
        help="also fit each per-pixel technique's textures to the truth at each of its storages "
        "(NAME-fit; a fit a setting): the floors beside the shipped points in the error per byte",
    )
    p.add_argument("--out", type=Path, default=None, help="output folder (default reports/tradeoff-<name>)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=run)


def run(args) -> int:
    """Measure every setting on the scene of ``args`` (HEIGHT's sidecar included).

    Print the table and the recommendation.
    """
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.commands import tradeoff
    from hzval.scene import spec as sc

    scene = scenes.scene_from_args(args, {"size": tradeoff.DEFAULT_SIZE})
    name = scene.name
    truth_spp = tradeoff.DEFAULT_TRUTH_SPP if args.truth_spp is None else args.truth_spp
    if truth_spp < 1:
        raise errors.InputError("--truth-spp", f"must be at least 1, got {truth_spp}")
    tradeoff.check_fits(scene, truth_spp)  # before the map is generated or decoded
    hm = sc.load_material_height(scene.material)
    points, info = tradeoff.measure(
        scene, hm.height, truth_spp=truth_spp, only=args.only, fits=args.fits, progress=not args.quiet
    )
    if not points:
        raise errors.InputError("--only", "no setting matches")
    out = args.out or Path("reports") / f"tradeoff-{name}"
    command = flags.command_line(args)
    material = {
        "name": name,
        "source": hm.source,
        "digest": hm.digest,
        "depth": scene.material.depth,
        "boundary": scene.material.boundary,
    }
    index = tradeoff.write_tradeoff(out, points, info, material=material, command=command, force=args.force)
    print(tradeoff.table(points))
    for line in tradeoff.floor_lines(points):
        print(line)
    _print_recommendation(tradeoff.recommend(points))
    print(f"report: {index}")
    return errors.EXIT_OK


def _print_recommendation(rec: dict | None) -> None:
    """Print the recommended setting, and the best of the lead technique's own settings."""
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.techniques import registry as technique

    if not rec:
        return
    print(
        f"\nrecommended: {rec['setting']} (|F-V| {rec['error']:.4f}; "
        f"best {rec['best']} {rec['best_error']:.4f})"
    )
    if "own" in rec:
        h = rec["own"]
        default = "" if rec["default"] is None else f"; default {rec['default']} {rec['default_error']:.4f}"
        print(
            f"for the {technique.get(h['technique']).label}'s own settings: {h['setting']} "
            f"(|F-V| {h['error']:.4f}{default})"
        )
