"""The ``hzval`` command: a thin layer over the stage modules.

Exit status (docs/ARCHITECTURE.md): 0 done, 1 check failed, 2 bad input or usage,
3 a machine that cannot run hzval (e.g. a broken LLVM). Errors that the user
can act on are one line on stderr, ``hzval: error: <what>: <problem>``.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from pathlib import Path

from hzval.core import errors

__all__ = [
    "typed_flags",
    "cmd_models",
    "cmd_views",
    "load_material",
    "cmd_bake",
    "cmd_sweep",
    "sweep_options",
    "cmd_suite",
    "cmd_materials",
    "cmd_check",
    "cmd_tradeoff",
    "cmd_export_scene",
    "cmd_score",
    "cmd_fit",
    "main",
]


def _add_material_args(p: argparse.ArgumentParser, default_size: int | None = None) -> None:
    from hzval import materials

    if default_size is None:
        default_size = materials.DEFAULT_SIZE
    p.add_argument(
        "height",
        nargs="?",
        metavar="HEIGHT",
        help="height map: PNG (8/16-bit), EXR or .npy; default: the built-in brick wall",
    )
    p.add_argument(
        "--material",
        default=None,
        metavar="NAME",
        help=f"a built-in material instead of HEIGHT: {', '.join(materials.names())} "
        "(`hzval materials` describes them)",
    )
    p.add_argument(
        "--depth",
        type=float,
        default=None,
        help="world height of H = 1 in image widths (default: the material's, 0.05 for a file)",
    )
    p.add_argument(
        "--boundary",
        choices=["wrap", "open"],
        default=None,
        help="wrap: the texture tiles; open: a terrain with nothing outside (default: the "
        "material's, wrap for a file)",
    )
    p.add_argument(
        "--size",
        type=int,
        default=None,
        metavar="N",
        help=f"size in texels of a built-in material (default {default_size}); an error with HEIGHT, "
        "which has its own size",
    )


def _builtin(name: str) -> bool:
    from hzval import materials

    return materials.is_builtin(name)


def _scene_module():
    from hzval.scene import spec as scene

    return scene


def _light_default():
    """The default light (:class:`hzval.scene.spec.Light`), whose values the help texts show."""
    return _scene_module().Light()


def _material_of(args) -> str | None:
    """The material the command line names: HEIGHT's path, ``--material``'s name, or ``None``; one line
    for an unknown material (the nearest names) and for ``--size`` with HEIGHT (a file has its own size)."""
    if args.height is not None and args.material is not None:
        raise errors.InputError("--material", f"give HEIGHT ({args.height}) or --material, not both")
    if args.material is not None:
        _check_material_name(args.material)
    if args.height is not None and getattr(args, "size", None) is not None:
        _refuse_size(args.size, str(args.height))
    return str(args.height) if args.height is not None else args.material


def _check_material_name(name: str) -> None:
    """Refuse an unknown built-in material's name in one line, with the nearest names."""
    import difflib

    from hzval import materials

    if materials.is_builtin(name):
        return
    near = difflib.get_close_matches(name, materials.names(), n=1, cutoff=0.6)
    hint = f"did you mean {' or '.join(near)}? " if near else ""
    raise errors.InputError(
        "--material",
        f"unknown material {name!r}; {hint}(known: {', '.join(materials.names())}; "
        "`hzval materials` describes them)",
    )


def _refuse_size(size: int, height: str) -> None:
    """``--size`` names a built-in material's size; a height map file has its own (nothing resamples it)."""
    from hzval.io import heightmap

    try:
        rows, cols = heightmap.probe_shape(height)
        own = f" ({cols}x{rows})"
    except errors.HzvalError:
        own = ""
    raise errors.InputError(
        "--size",
        f"{size} applies to built-in materials only; {height} has its own size{own}: "
        "resize the file, or leave --size out",
    )


def _scene_name(args, scene) -> str:
    """A sweep's name: HEIGHT's stem, else the scene's (a built-in material's name unless a scene file
    names it)."""
    if args.height is not None:
        return Path(args.height).stem
    if getattr(args, "material", None) is not None and not getattr(args, "scene", None):
        return args.material
    return scene.name


def _tradeoff_truth_spp() -> int:
    from hzval.commands import tradeoff

    return tradeoff.DEFAULT_TRUTH_SPP


def _tradeoff_default_size() -> int:
    from hzval.commands import tradeoff

    return tradeoff.DEFAULT_SIZE


def _add_technique_args(p: argparse.ArgumentParser) -> None:
    """``--techniques``, a ``--no-NAME`` for each technique, and each technique's
    own options (:meth:`hzval.techniques.registry.Technique.add_arguments`), from the registry."""
    from hzval.techniques import registry as technique

    names = technique.names()
    opt_in = [n for n in names if not technique.get(n).by_default]
    p.add_argument(
        "--techniques",
        default=None,
        metavar="NAMES",
        help=f"comma-separated techniques to score: {', '.join(names)} (default: every one that "
        "applies to the declared effects" + (f", except {', '.join(opt_in)}" if opt_in else "") + ")",
    )
    for name in names:
        t = technique.get(name)
        p.add_argument(
            f"--no-{name}",
            dest="exclude",
            action="append_const",
            const=name,
            default=[],
            help=f"leave out {t.label} ({t.summary})",
        )
    for name in names:
        technique.get(name).add_arguments(p)


def _technique_options(args) -> dict:
    """``sweep.Options`` keywords of the technique options, each checked, an error naming the flag
    as typed (:func:`hzval.techniques.registry.flag_errors`)."""
    from hzval.bake import maps as bake
    from hzval.techniques import registry as technique

    requested = None
    if args.techniques is not None:
        requested = tuple(n.strip() for n in args.techniques.split(",") if n.strip())
    params = bake.BakeParams(
        radius=args.radius, angles=args.angles, method=args.method, directions=args.directions
    ).validate()
    settings = {}
    for n in technique.names():
        t = technique.get(n)
        with technique.flag_errors(t, getattr(args, "typed", {})):
            settings[n] = t.settings_from_args(args)
            if n in (requested or technique.defaults()):  # the others' settings are never used
                t.check_settings(params, settings[n])
    return {"techniques": requested, "exclude": tuple(args.exclude), "settings": settings}


def typed_flags(parser: argparse.ArgumentParser, argv: list[str]) -> dict[str, str]:
    """``{canonical flag: the spelling in argv}`` for the flags of ``parser`` that ``argv`` uses under
    another name (a hidden alias such as ``--k`` for ``--horizon-k``): errors name what was typed."""
    canonical: dict[str, str] = {}
    for a in parser._actions:
        if a.option_strings and a.help != argparse.SUPPRESS:
            canonical.setdefault(a.dest, a.option_strings[-1])
    out = {}
    for a in parser._actions:
        for opt in a.option_strings:
            if (
                any(t == opt or t.startswith(opt + "=") for t in argv)
                and a.dest in canonical
                and opt != canonical[a.dest]
            ):
                out[canonical[a.dest]] = opt
    return out


def _common() -> argparse.ArgumentParser:
    """The flags every command takes, before or after its name (argparse ``parents=``)."""
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument(
        "--variant",
        default=argparse.SUPPRESS,
        help="Mitsuba variant (default: cuda_ad_rgb with a GPU, else llvm_ad_rgb; or $HZVAL_VARIANT)",
    )
    return common


class _Subcommands(argparse._SubParsersAction):
    """Every command's parser gets the common flags (:func:`_common`)."""

    def add_parser(self, name, **kwargs):
        p = super().add_parser(name, parents=[_common()], **kwargs)
        p.set_defaults(parser=p)
        return p


def _parser() -> argparse.ArgumentParser:
    import hzval

    parser = argparse.ArgumentParser(
        prog="hzval",
        parents=[_common()],
        description="Validate horizon mapping and the self-shadowing techniques it competes with "
        "against ray-traced ground truth.",
    )
    parser.add_argument("--version", action="version", version=f"hzval {hzval.__version__}")
    parser.register("action", "parsers", _Subcommands)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    _add_bake(sub)
    _add_sweep(sub)
    _add_check(sub)
    _add_tradeoff(sub)
    _add_views(sub)
    _add_models(sub)
    _add_export_scene(sub)
    _add_score(sub)
    _add_suite(sub)
    _add_materials(sub)
    _add_fit(sub)
    for p in sub.choices.values():  # every command that writes a folder (hzval.io.files.output_folder)
        if "--out" in p._option_string_actions or "--report" in p._option_string_actions:
            p.add_argument(
                "--force",
                action="store_true",
                help="write into an --out that holds files hzval did not write (they are kept)",
            )
    return parser


def _add_bake_flags(p: argparse.ArgumentParser) -> None:
    """The horizon bake's flags (:class:`hzval.bake.maps.BakeParams`, whose defaults they show)."""
    from hzval.bake import maps as bake

    d = bake.BakeParams()
    p.add_argument(
        "--radius", type=int, default=d.radius, help=f"bake search radius in texels (default {d.radius})"
    )
    p.add_argument(
        "--angles",
        type=int,
        default=d.angles,
        help=f"bake angular bins, a multiple of 2 x --directions (default {d.angles})",
    )
    p.add_argument(
        "--directions",
        type=int,
        default=d.directions,
        help=f"stored horizon directions: 8 (Lengyel's, two RGBA layers) or 16 (22.5 degrees apart, "
        f"four layers; seed method, --angles a multiple of 32) (default {d.directions})",
    )
    p.add_argument(
        "--method",
        choices=bake.METHODS,
        default=d.method,
        help="horizon bake: seed (Lengyel's bins within --radius) or exact (exact horizons toward "
        f"the 8 channel directions, unlimited radius; ignores --radius and --angles) "
        f"(default {d.method})",
    )


def _add_bake(sub) -> None:
    p = sub.add_parser(
        "bake",
        help="bake normal, horizon and ambient maps from a height map",
        description="Bake the horizon-mapping textures of a height map (docs/ARCHITECTURE.md).",
    )
    _add_material_args(p)
    _add_bake_flags(p)
    p.add_argument("--mesh", action="store_true", help="also write the displaced triangle mesh as mesh.ply")
    p.add_argument("--out", required=True, type=Path, help="output folder")
    p.set_defaults(run=cmd_bake)


def _add_sweep(sub) -> None:
    from hzval.techniques import registry as technique

    labels = ", ".join(technique.get(n).label for n in technique.names())
    p = sub.add_parser(
        "sweep",
        help="render the truth and every technique over a light sweep and report",
        description=f"Render the ground truth and every self-shadowing technique ({labels}: "
        "--techniques) for every light of the sweep (Lengyel's Figure 5.3 by "
        "default), compare them, and write metrics.json and an HTML report.",
    )
    _add_material_args(p)
    p.add_argument(
        "--scene",
        type=Path,
        default=None,
        help="scene description (TOML); the flags below override it (default: built-in bricks)",
    )
    _add_sweep_flags(p)
    p.add_argument("--out", type=Path, default=None, help="output folder (default reports/<scene name>)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    _add_gate_flags(p)
    p.set_defaults(run=cmd_sweep)


def _add_gate_flags(p: argparse.ArgumentParser, strict: bool = True) -> None:
    """``--fail-if`` and ``--baseline`` (:mod:`hzval.commands.gates`, docs/ci.md)."""
    g = p.add_argument_group("gates", "fail the run (exit 1) on a threshold or a regression (docs/ci.md)")
    g.add_argument(
        "--fail-if",
        dest="fail_if",
        action="append",
        default=None,
        metavar="EXPR",
        help="exit 1 when EXPR holds, e.g. 'horizon.flip_mean>0.1' (every frame), "
        "'mean(pom.visibility_mae)>mean(horizon.visibility_mae)' (the sweep's means; max(...) "
        "too); any metric name of metrics.json's frames; repeatable",
    )
    g.add_argument(
        "--baseline",
        type=Path,
        default=None,
        metavar="DIR",
        help="an earlier run of the same settings: exit 1 on a significant regression of any "
        "technique's metric (the noise-aware test of hzval check)",
    )
    if strict:
        g.add_argument(
            "--strict",
            action="store_true",
            help="exit 1 on any warning about an external horizon map (--horizon-map): a convention "
            "that fits better, a map that does not describe the height map",
        )


def _gates(args):
    """The :class:`hzval.commands.gates.Gates` of ``--fail-if`` and ``--baseline``, checked before the run."""
    from hzval.commands import gates

    return gates.Gates(
        getattr(args, "fail_if", None), getattr(args, "baseline", None), strict=getattr(args, "strict", False)
    )


def _gate_exit(failed: list[str]) -> int:
    """Print each gate failure on one line; exit 1 if there is any."""
    for line in failed:
        print(f"hzval: gate failed: {line}", file=sys.stderr)
    return errors.EXIT_CHECK_FAILED if failed else errors.EXIT_OK


def _add_sweep_flags(p: argparse.ArgumentParser) -> None:
    """The light, samples, shading, bake and technique flags of ``sweep`` (and ``suite``), their
    defaults those of :class:`hzval.scene.spec.Scene`."""
    from hzval.scene import spec as sc

    d, light = sc.Scene(), sc.Light()
    p.add_argument(
        "--elevation",
        type=float,
        default=None,
        help=f"light elevation in degrees (default {light.elevation_deg:g})",
    )
    p.add_argument(
        "--azimuths",
        default=None,
        help=f"light azimuths in degrees, START:STOP:STEP or a list (default {sc.DEFAULT_AZIMUTHS_TEXT})",
    )
    p.add_argument("--light", choices=["hard", "soft"], default=None, help="directional or disk light")
    p.add_argument(
        "--light-radius",
        type=float,
        default=None,
        metavar="DEG",
        help="angular radius of a soft light in degrees",
    )
    p.add_argument(
        "--effects",
        default=None,
        help="comma-separated effects: shadow, diffuse, specular, ambient, "
        f"reflection_occlusion, interreflection (default {','.join(d.effects)})",
    )
    p.add_argument("--spp", type=int, default=None, help=f"samples per pixel (default {d.spp})")
    p.add_argument("--seed", type=int, default=None, help=f"random seed of the samples (default {d.seed})")
    p.add_argument(
        "--supersampling",
        type=int,
        default=None,
        help="pixels per texel along each axis: a magnification, not anti-aliasing (--spp samples "
        f"each pixel); FLIP and the other image scores depend on it "
        f"(default {_scene_module().Camera().supersampling})",
    )
    p.add_argument(
        "--shading",
        choices=["smooth", "faceted"],
        default=None,
        help="the truth's shading normal: smooth (interpolated vertex normals, as the normal map) "
        "or faceted (each triangle's own) (default smooth)",
    )
    _add_truth_tolerance_flag(p)
    _add_mesh_flags(p)
    _add_view_flags(p)
    _add_bake_flags(p)
    p.add_argument(
        "--all-files",
        action="store_true",
        help="also write each frame's files that the others determine: the unshadowed render and "
        "each technique's image as EXR, V and F as PNG (about 1.6x the bytes)",
    )
    _add_technique_args(p)


def _add_mesh_flags(p: argparse.ArgumentParser) -> None:
    """The surface the material is on (:mod:`hzval.geometry.model`)."""
    g = p.add_argument_group("mesh", "the surface the material is on (docs/meshes.md)")
    g.add_argument(
        "--mesh",
        default=None,
        metavar="SHAPE",
        help="plane (the tile, the default), cube, sphere, cylinder, torus, or a .obj, .ply, .gltf "
        "or .glb file with texture coordinates",
    )
    g.add_argument(
        "--uv-scale",
        type=float,
        default=None,
        metavar="N",
        help="how often the texture repeats across the mesh's UVs (default 1)",
    )
    g.add_argument(
        "--up",
        choices=("y", "z"),
        default=None,
        help="the mesh file's up axis (default: y for glTF, as its spec says; see docs/meshes.md)",
    )
    g.add_argument(
        "--tangent-bug",
        default=None,
        metavar="BUG",
        help="render the techniques with an engine's tangent-frame bug: none (default), "
        "ignore-handedness, swap-uv, flip-green, per-face; the truth never changes "
        "(docs/meshes.md, 'Tangent bugs')",
    )


def _add_truth_tolerance_flag(p: argparse.ArgumentParser) -> None:
    """``--truth-tolerance``: how closely the truth's triangles follow the bilinear surface."""
    from hzval.geometry import tile as mesh

    p.add_argument(
        "--truth-tolerance",
        type=float,
        default=None,
        metavar="TEXELS",
        help="the truth's surface: the largest height difference, in texels, between its "
        "triangles and the bilinear interpolation of the height map (docs/truth-surface.md) "
        f"(default {mesh.DEFAULT_TOLERANCE:g})",
    )


def _add_views(sub) -> None:
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
    _add_material_args(p, default_size=128)
    p.add_argument("--azimuths", default="-60:60:30", help="light azimuths in degrees (default %(default)s)")
    p.add_argument(
        "--elevation",
        type=float,
        default=None,
        help=f"light elevation in degrees (default {_light_default().elevation_deg:g})",
    )
    p.add_argument("--spp", type=int, default=4, help="samples per pixel (default %(default)s)")
    p.add_argument(
        "--views", default=None, help=f"comma-separated views (default all: {', '.join(views.VIEWS)})"
    )
    p.add_argument(
        "--lookups", default=None, help=f"comma-separated lookups (default all: {', '.join(views.LOOKUPS)})"
    )
    p.add_argument("--out", type=Path, default=None, help="output folder (default reports/views-<name>)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(run=cmd_views)


def _add_models(sub) -> None:
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
    _add_material_args(p, default_size=128)
    p.add_argument(
        "--azimuths", default="0,72,144,216,288", help="light azimuths in degrees (default %(default)s)"
    )
    p.add_argument("--elevation", type=float, default=None, help="light elevation in degrees (default 30)")
    p.add_argument("--spp", type=int, default=2, help="samples per pixel (default %(default)s)")
    p.add_argument("--resolution", default="128x128", help="pixels WxH of every case (default %(default)s)")
    p.add_argument(
        "--effects",
        default="shadow,diffuse,reflection_occlusion",
        help="effects of every case: reflection_occlusion scores Toolbag's fade against the traced "
        "glossy lobe (default %(default)s)",
    )
    p.add_argument("--out", type=Path, default=None, help="output folder (default reports/models-<name>)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(run=cmd_models)


def cmd_models(args) -> int:
    import shlex

    from hzval.scene import spec as sc
    from hzval.studies import models as models_study

    size = args.size if args.size is not None else (None if args.height else 128)
    scene = sc.override(
        sc.Scene(),
        height=_material_of(args),
        size=size,
        depth=args.depth,
        boundary=args.boundary,
        elevation=args.elevation,
        azimuths=args.azimuths,
        spp=args.spp,
        camera="orthographic",
        resolution=_resolution(args.resolution),
        effects=args.effects,
    )
    scene = dataclasses.replace(scene, name=_scene_name(args, scene))
    out = args.out or Path("reports") / f"models-{scene.name}"
    command = "hzval " + " ".join(shlex.quote(a) for a in (args.argv or []))
    data = models_study.run(scene, out, progress=not args.quiet, command=command, force=args.force)
    print(models_study.summary_table(data))
    print(f"report: {out / 'index.html'}")
    return 0


def cmd_views(args) -> int:
    import shlex

    from hzval.commands import views
    from hzval.scene import spec as sc

    base = sc.Scene()
    if args.height is not None and sc.sidecar_of(args.height) is not None:
        base = sc.load_sidecar(sc.sidecar_of(args.height), args.height)
    size = args.size if args.size is not None else (None if args.height else 128)
    scene = sc.override(
        base,
        height=_material_of(args),
        size=size,
        depth=args.depth,
        boundary=args.boundary,
        elevation=args.elevation,
        azimuths=args.azimuths,
        spp=args.spp,
    )
    scene = dataclasses.replace(scene, name=_scene_name(args, scene))
    out = args.out or Path("reports") / f"views-{scene.name}"
    command = "hzval " + " ".join(shlex.quote(a) for a in (args.argv or []))
    split = lambda t: None if t is None else [v.strip() for v in t.split(",") if v.strip()]
    data = views.run(
        scene,
        out,
        views=split(args.views),
        lookups=split(args.lookups),
        progress=not args.quiet,
        command=command,
        force=args.force,
    )
    names = sorted({n for r in data["rows"] for n in r["techniques"]})
    print(
        f"{'view':10} {'lookup':14} {'footprint':>9} {'parallax':>9}  " + "  ".join(f"{n:>9}" for n in names)
    )
    for r in data["rows"]:
        fp, pe = r["footprint_texels"].get("p50"), r["parallax_error_texels"].get("mean")
        vals = "  ".join(f"{r['techniques'][n]['visibility_mae']:9.4f}" for n in names)
        print(
            f"{r['view']:10} {r['lookup']:14} {fp if fp is not None else float('nan'):9.2f} "
            f"{pe if pe is not None else float('nan'):9.3f}  {vals}"
        )
    print(f"report: {out / 'index.html'}")
    return errors.EXIT_OK


def _add_view_flags(p: argparse.ArgumentParser) -> None:
    """The camera's and the techniques' lookup flags (:mod:`hzval.scene.camera`, :mod:`hzval.scene.lookup`)."""
    from hzval.scene import camera, lookup

    c, lk = camera.Camera(), lookup.Lookup()
    g = p.add_argument_group("view", "where the camera is, and how the techniques read their textures")
    g.add_argument(
        "--camera",
        choices=camera.KINDS,
        default=None,
        help=f"top (straight down, one pixel per texel), orthographic or perspective (default {c.kind})",
    )
    g.add_argument(
        "--view-elevation",
        type=float,
        default=None,
        metavar="DEG",
        help=f"the camera's elevation above the surface (default {c.elevation_deg:g})",
    )
    g.add_argument(
        "--view-azimuth",
        type=float,
        default=None,
        metavar="DEG",
        help=f"the direction from the surface toward the camera, as the light's azimuth "
        f"(default {c.azimuth_deg:g})",
    )
    g.add_argument(
        "--fov",
        type=float,
        default=None,
        metavar="DEG",
        help=f"perspective: horizontal field of view (default {c.fov_deg:g})",
    )
    g.add_argument(
        "--distance",
        type=float,
        default=None,
        metavar="D",
        help=f"perspective: the eye's distance from the tile's centre in tile widths (default {c.distance:g})",
    )
    g.add_argument("--resolution", default=None, metavar="WxH", help="image size (default the top view's)")
    g.add_argument(
        "--plane",
        choices=lookup.PLANES,
        default=None,
        help=f"the techniques' flat surface at the bottom, mean or top of the relief (default {lk.plane})",
    )
    g.add_argument(
        "--filter",
        choices=lookup.FILTERS,
        default=None,
        help=f"texture filtering: nearest, bilinear, trilinear from mip-maps, anisotropic (default {lk.filter})",
    )
    g.add_argument(
        "--mips",
        choices=lookup.MIPS,
        default=None,
        help=f"the horizon map's mip-maps by averaging or by the maximum (conservative) (default {lk.mips})",
    )
    g.add_argument(
        "--parallax",
        choices=lookup.PARALLAX,
        default=None,
        help="parallax mapping of the lookup: none, offset (with offset limiting) or occlusion (linear "
        f"search and refinement) (default {lk.parallax})",
    )


def _resolution(text: str | None):
    """``"WxH"`` as ``(W, H)``."""
    if text is None:
        return None
    try:
        w, h = (int(v) for v in text.lower().split("x"))
        if w < 1 or h < 1:
            raise ValueError
    except ValueError:
        raise errors.InputError(
            "--resolution", f"expected WIDTHxHEIGHT in pixels, e.g. 512x384, got {text!r}"
        ) from None
    return (w, h)


def _add_suite(sub) -> None:
    from hzval import materials

    p = sub.add_parser(
        "suite",
        help="sweep many materials (the built-in ones by default) and write an overview",
        description="Sweep every material (the built-in ones, or scene TOMLs, height maps - each "
        "with an optional sidecar <stem>.toml - folders of them, or built-in names) "
        "with the same options, on a pool of worker processes or a Dask cluster; "
        "write each material's report under DIR, and DIR/index.html and "
        "DIR/suite.json with every material's mean errors and times.",
    )
    p.add_argument(
        "inputs",
        nargs="*",
        metavar="SCENE.toml|HEIGHT|FOLDER|NAME",
        help="materials to sweep (default: every built-in material)",
    )
    p.add_argument("--depth", type=float, default=None, help="override every material's depth")
    p.add_argument(
        "--boundary", choices=["wrap", "open"], default=None, help="override every material's boundary"
    )
    p.add_argument(
        "--size",
        type=int,
        default=None,
        metavar="N",
        help=f"size of the built-in materials (default {materials.DEFAULT_SIZE})",
    )
    _add_sweep_flags(p)
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="worker processes on this machine, each sweeping one material at a time (default: "
        "1 per core, as many as fit in memory, at most the number of materials, at least 1); "
        "0 sweeps them in this process, where a crash ends the suite",
    )
    p.add_argument(
        "--cluster",
        default=None,
        metavar="ADDRESS",
        help="run on the Dask scheduler at ADDRESS (tcp://host:8786) instead; its workers need "
        "hzval and DIR and the inputs at the same paths",
    )
    p.add_argument(
        "--out",
        type=Path,
        default=Path("reports") / "suite",
        metavar="DIR",
        help="output folder (default reports/suite)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    _add_gate_flags(p)
    p.set_defaults(run=cmd_suite)


def _add_materials(sub) -> None:
    p = sub.add_parser(
        "materials",
        help="list the built-in materials",
        description='List the built-in materials (--material NAME, [material] height = "NAME", '
        "hzval suite) with their default depth and boundary.",
    )
    p.set_defaults(run=cmd_materials)


def _add_check(sub) -> None:
    p = sub.add_parser(
        "check",
        help="render the shipped scenes and compare them with reference/ (CI)",
        description="Render every scene of scenes/ at its small [check] size and compare the "
        "truth (statistically) and the approximation (tightly) with the references. "
        "Exit 0 when all pass, 1 when any fails; a failure writes an HTML report.",
    )
    p.add_argument("--references", type=Path, default=None, help="reference folder (default: reference/)")
    p.add_argument("--scenes", type=Path, default=None, help="scene folder (default: scenes/)")
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        help="write the HTML report here (default: reports/check, and only on failure)",
    )
    p.add_argument("--report", dest="out", type=Path, default=argparse.SUPPRESS, help=argparse.SUPPRESS)
    p.add_argument(
        "--update",
        action="store_true",
        help="rewrite the references that are missing or failing, and say which",
    )
    p.add_argument(
        "--seed", type=int, default=None, help="render the truth with this seed instead of the scene's"
    )
    p.add_argument(
        "--only",
        dest="only",
        action="append",
        default=None,
        metavar="NAME",
        help="check only the scene of this name (repeatable)",
    )
    p.add_argument("--scene", dest="only", action="append", help=argparse.SUPPRESS)
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=cmd_check)


def _add_tradeoff(sub) -> None:
    p = sub.add_parser(
        "tradeoff",
        help="measure what accuracy costs in time and memory on one material",
        description="Measure bake, approximation and truth settings against a converged truth "
        "over the sweep: time, texture memory, visibility error and FLIP; write "
        "tradeoff.json, a Pareto plot and a page that recommends a setting.",
    )
    _add_material_args(p, default_size=_tradeoff_default_size())
    p.add_argument(
        "--elevation",
        type=float,
        default=None,
        help=f"light elevation in degrees (default {_light_default().elevation_deg:g})",
    )
    p.add_argument(
        "--azimuths",
        default=None,
        help=f"light azimuths in degrees (default {_scene_module().DEFAULT_AZIMUTHS_TEXT})",
    )
    p.add_argument(
        "--truth-spp",
        type=int,
        default=None,
        metavar="N",
        help=f"shadow rays per pixel of the converged truth (default {_tradeoff_truth_spp()})",
    )
    p.add_argument(
        "--spp",
        type=int,
        default=None,
        help=f"samples per pixel of the settings (default {_scene_module().Scene().spp})",
    )
    p.add_argument(
        "--only",
        action="append",
        default=None,
        metavar="TEXT",
        help="measure only the settings whose names contain TEXT (repeatable)",
    )
    p.add_argument("--out", type=Path, default=None, help="output folder (default reports/tradeoff-<name>)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=cmd_tradeoff)


def _add_export_scene(sub) -> None:
    p = sub.add_parser(
        "export-scene",
        help="write the truth of one light as a Mitsuba 3 scene file",
        description="Write DIR/scene.xml and DIR/mesh.ply: the displaced mesh with its vertex "
        "normals, a diffuse BSDF with the albedo, a directional emitter and an "
        "orthographic sensor over the tile, as hzval's truth traces them. "
        "Render it with `mitsuba DIR/scene.xml -o out.exr`.",
    )
    _add_material_args(p)
    p.add_argument("--scene", type=Path, default=None, help="scene description (TOML)")
    p.add_argument(
        "--elevation",
        type=float,
        default=None,
        help=f"light elevation in degrees (default {_light_default().elevation_deg:g})",
    )
    p.add_argument(
        "--azimuth", type=float, default=0.0, help="light azimuth in degrees (default %(default)g)"
    )
    p.add_argument("--effects", default=None, help="shadow and/or diffuse (default shadow,diffuse)")
    p.add_argument(
        "--spp", type=int, default=None, help=f"samples per pixel (default {_scene_module().Scene().spp})"
    )
    p.add_argument(
        "--shading",
        choices=["smooth", "faceted"],
        default=None,
        help="vertex normals in the PLY (smooth, default) or none (faceted)",
    )
    _add_truth_tolerance_flag(p)
    p.add_argument("--out", required=True, type=Path, help="output folder")
    p.set_defaults(run=cmd_export_scene)


def _add_score(sub) -> None:
    p = sub.add_parser(
        "score",
        help="score your engine's frames of a sweep against its truth",
        description="Read one image per light of SWEEP_DIR (named after its frame folders: "
        "az+0.exr linear, or az+0.png sRGB; SWEEP_DIR/frames.json says how to render "
        "them; f_az+0.exr, the shadow factor F, optional), score each against the "
        "sweep's truth with every metric of the sweep, beside the sweep's own "
        "techniques, and write metrics.json and a report (FRAMES_DIR/engine.toml: "
        "your engine's label and parameters).",
    )
    p.add_argument("frames", type=Path, metavar="FRAMES_DIR", help="folder of your renderer's frames")
    p.add_argument(
        "--against", required=True, type=Path, metavar="SWEEP_DIR", help="a folder hzval sweep wrote"
    )
    p.add_argument("--out", type=Path, default=None, help="output folder (default FRAMES_DIR/score)")
    _add_gate_flags(p, strict=False)
    p.set_defaults(run=cmd_score)


def load_material(args) -> tuple["np.ndarray", dict]:  # noqa: F821
    """The height map named on the command line, or a built-in one, with its description."""
    from hzval import materials
    from hzval.io import heightmap
    from hzval.scene import spec as sc

    if args.height is None:
        name = args.material or materials.DEFAULT
        m = materials.get(name)
        size = materials.DEFAULT_SIZE if args.size is None else args.size
        if size < m.min_size:
            raise errors.InputError(
                "--size", f"the built-in {name} needs at least {m.min_size} texels, got {size}"
            )
        hm = sc.load_material_height(sc.MaterialSpec(height=name, size=size))
        info = {"path": None, "builtin": name, "size": size}
    else:
        hm = heightmap.load_height(args.height)
        info = {"path": str(args.height)}
    rows, cols = hm.height.shape
    info.update(source=hm.source, digest=hm.digest, rows=rows, cols=cols)
    return hm.height, info


def _sidecar_scene(args):
    """The sidecar scene of HEIGHT (``gravel.toml`` beside ``gravel.png``), as the sweep reads it,
    or ``None``."""
    from hzval.scene import spec as sc

    if args.height is None or getattr(args, "scene", None) or sc.sidecar_of(args.height) is None:
        return None
    return sc.load_sidecar(sc.sidecar_of(args.height), args.height)


def cmd_bake(args) -> int:
    from hzval import materials
    from hzval.bake import maps as bake
    from hzval.geometry import tile as mesh
    from hzval.io import files, heightmap
    from hzval.scene.spec import material_defaults

    side = _sidecar_scene(args)
    defaults = (
        material_defaults(_material_of(args) or materials.DEFAULT)
        if side is None
        else {"depth": side.material.depth, "boundary": side.material.boundary}
    )
    params = bake.BakeParams(
        depth=defaults["depth"] if args.depth is None else args.depth,
        radius=args.radius,
        angles=args.angles,
        boundary=args.boundary or defaults["boundary"],
        method=args.method,
        directions=args.directions,
    ).validate()
    if args.height is not None:
        rows, cols = heightmap.probe_shape(args.height)
        bake.check_fits(args.height, rows, cols, params)
    else:  # estimate before generating the built-in map too
        size = materials.DEFAULT_SIZE if args.size is None else args.size
        bake.check_fits("--size", size, size, params)
    t0 = time.perf_counter()
    with files.output_folder(args.out, force=args.force):
        height, info = load_material(args)
        info["path"] = files.report_path(info["path"], args.out)  # bake.json carries no absolute folders
        t_load = time.perf_counter() - t0
        result = bake.bake(height, params)
        result.timings = {"load_s": t_load, **result.timings}
        written = bake.write_bake(result, args.out, input_info=info)
        if args.mesh:
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
        f"baked {info['source']} ({cols}x{rows}, depth {params.depth:g}, {how}, "
        f"{params.boundary}) in {total:.2f} s -> {args.out} ({len(written)} files)"
    )
    return errors.EXIT_OK


def cmd_sweep(args) -> int:
    import shlex

    from hzval.pipeline import sweep
    from hzval.scene import spec as sc

    base = sc.Scene()
    if args.scene:
        base = sc.load_scene(args.scene)
    elif args.height is not None and sc.sidecar_of(args.height) is not None:
        base = sc.load_sidecar(sc.sidecar_of(args.height), args.height)
        print(f"hzval: using the sidecar scene {sc.sidecar_of(args.height)}", file=sys.stderr)
    scene = sc.override(base, **_model_view(base, _scene_overrides(args)), height=_material_of(args))
    if args.size is not None and not _builtin(scene.material.height):  # a --scene's own height map
        _refuse_size(args.size, scene.material.height)
    scene = dataclasses.replace(scene, name=_scene_name(args, scene))
    options = sweep_options(args)
    out = args.out or Path("reports") / scene.name
    command = "hzval " + " ".join(shlex.quote(a) for a in (args.argv or []))
    gates = _gates(args)
    result = sweep.run(
        scene, out, options=options, command=command, progress=not args.quiet, force=args.force, gates=gates
    )
    for w in result.get("warnings", []):
        print(f"hzval: warning: {w}", file=sys.stderr)
    print(sweep.summary_table(result))
    t = result["timings"]
    parts = [
        f"bake {t['bake_s']:.2f} s{', cached' if t['bake_cached'] else ''}",
        f"truth {t['truth_setup_s'] + t['truth_s']:.2f} s",
    ]
    parts += [
        f"{name} {t.get(info['file_stem'] + '_setup_s', 0) + t[info['file_stem'] + '_s']:.2f} s"
        for name, info in result["techniques"].items()
    ]
    print(
        f"\n{len(result['frames'])} frames in {t['total_s']:.1f} s ({', '.join(parts)}; peak memory "
        f"{result['memory']['peak_rss_bytes'] / 2**30:.2f} GiB); report: {out / 'index.html'}"
    )
    return _gate_exit(result.get("gates", {}).get("failed", []))


def _model_view(base, overrides: dict) -> dict:
    """``overrides`` with :data:`hzval.scene.spec.MODEL_CAMERA`'s view where the sweep is on a model and
    neither the scene nor the flags place a camera: a model seen from straight above shows one face."""
    from hzval.scene import spec as sc

    shape = overrides.get("mesh") or base.mesh.shape
    uv_scale = overrides.get("uv_scale") or base.mesh.uv_scale
    if sc.MeshSpec(shape, uv_scale).is_plane or base.camera != sc.Camera() or overrides.get("camera"):
        return overrides
    cam = sc.MODEL_CAMERA
    return {
        **overrides,
        "camera": cam.kind,
        "view_elevation": overrides.get("view_elevation") or cam.elevation_deg,
        "view_azimuth": overrides.get("view_azimuth") or cam.azimuth_deg,
    }


def _truth_tolerance(args):
    """``--truth-tolerance`` checked: a positive, finite number of texels, or None."""
    t = getattr(args, "truth_tolerance", None)
    if t is not None and not (math.isfinite(t) and t > 0):
        raise errors.InputError("--truth-tolerance", f"must be a positive number of texels, got {t}")
    return t


def _scene_overrides(args) -> dict:
    """The sweep flags that change a scene (:func:`hzval.scene.spec.override`'s keywords), material aside."""
    return dict(
        size=args.size,
        depth=args.depth,
        boundary=args.boundary,
        elevation=args.elevation,
        azimuths=args.azimuths,
        light=args.light,
        light_radius=args.light_radius,
        effects=args.effects,
        spp=args.spp,
        seed=args.seed,
        supersampling=args.supersampling,
        shading=args.shading,
        truth_tolerance=_truth_tolerance(args),
        camera=args.camera,
        view_elevation=args.view_elevation,
        view_azimuth=args.view_azimuth,
        fov=args.fov,
        distance=args.distance,
        resolution=_resolution(args.resolution),
        plane=args.plane,
        filter=args.filter,
        mips=args.mips,
        parallax=args.parallax,
        mesh=getattr(args, "mesh", None),
        uv_scale=getattr(args, "uv_scale", None),
        up=getattr(args, "up", None),
        tangent_bug=getattr(args, "tangent_bug", None),
    )


def sweep_options(args):
    """The :class:`hzval.pipeline.sweep.Options` of the sweep flags."""
    from hzval.pipeline import sweep

    return sweep.Options(
        radius=args.radius,
        angles=args.angles,
        method=args.method,
        directions=args.directions,
        all_files=args.all_files,
        **_technique_options(args),
    )


def cmd_suite(args) -> int:
    import shlex

    from hzval.commands import suite

    items = suite.entries(args.inputs, **_scene_overrides(args))
    if args.size is not None:
        files_ = [e for e in items if not _builtin(e.scene.material.height)]
        if files_ and len(files_) == len(items):
            _refuse_size(args.size, files_[0].scene.material.height)
        if files_:
            print(
                f"hzval: note: --size {args.size} applies to the built-in materials only; "
                f"{', '.join(e.name for e in files_[:4])}{' ...' if len(files_) > 4 else ''} keep their own size",
                file=sys.stderr,
            )
    workers = args.workers if args.workers is not None else suite.default_workers(items)
    command = "hzval " + " ".join(shlex.quote(a) for a in (args.argv or []))
    gates = _gates(args)
    result = suite.run(
        items,
        args.out,
        options=sweep_options(args),
        workers=workers,
        cluster=args.cluster,
        variant=args.variant,
        command=command,
        progress=not args.quiet,
        force=args.force,
        gates=gates,
    )
    print(suite.summary_table(result))
    s = result["suite"]
    print(
        f"\n{s['materials']} materials ({s['failed']} failed) in {s['seconds']:.1f} s on {s['engine']}; "
        f"overview: {args.out / 'index.html'}"
    )
    gated = _gate_exit(result.get("gates", {}).get("failed", []))
    return errors.EXIT_OK if not s["failed"] and not gated else errors.EXIT_CHECK_FAILED


def cmd_materials(args) -> int:
    from hzval import materials

    print(f"{'name':13s} {'depth':>6s}  {'boundary':8s}  what it is")
    for name in materials.names():
        m = materials.get(name)
        print(f"{name:13s} {m.depth:6g}  {m.boundary:8s}  {m.label}: {m.summary}")
    return errors.EXIT_OK


def cmd_check(args) -> int:
    import shlex

    from hzval.commands import check

    result = check.run(
        scenes_dir=args.scenes,
        references=args.references,
        update=args.update,
        seed=args.seed,
        progress=not args.quiet,
        only=args.only,
    )
    print(check.summary(result))
    for path in result.updated:
        print(f"updated {path}")
    failed = not result.passed and not args.update
    if failed or args.out:
        out = args.out or Path("reports") / "check"
        command = "hzval " + " ".join(shlex.quote(a) for a in (args.argv or []))
        index = check.write_report(result, out, command=command, force=args.force)
        print(f"report: {index}")
    return errors.EXIT_CHECK_FAILED if failed else errors.EXIT_OK


def cmd_tradeoff(args) -> int:
    import shlex

    from hzval.commands import tradeoff
    from hzval.scene import spec as sc
    from hzval.techniques import registry as technique

    size = args.size if args.size is not None else (None if args.height else tradeoff.DEFAULT_SIZE)
    scene = sc.override(
        sc.Scene(),
        height=_material_of(args),
        size=size,
        depth=args.depth,
        boundary=args.boundary,
        elevation=args.elevation,
        azimuths=args.azimuths,
        spp=args.spp,
    )
    name = _scene_name(args, scene)
    truth_spp = tradeoff.DEFAULT_TRUTH_SPP if args.truth_spp is None else args.truth_spp
    if truth_spp < 1:
        raise errors.InputError("--truth-spp", f"must be at least 1, got {truth_spp}")
    tradeoff.check_fits(scene, truth_spp)  # before the map is generated or decoded
    hm = sc.load_material_height(scene.material)
    points, info = tradeoff.measure(
        scene, hm.height, truth_spp=truth_spp, only=args.only, progress=not args.quiet
    )
    if not points:
        raise errors.InputError("--only", "no setting matches")
    out = args.out or Path("reports") / f"tradeoff-{name}"
    command = "hzval " + " ".join(shlex.quote(a) for a in (args.argv or []))
    material = {
        "name": name,
        "source": hm.source,
        "digest": hm.digest,
        "depth": scene.material.depth,
        "boundary": scene.material.boundary,
    }
    index = tradeoff.write_tradeoff(out, points, info, material=material, command=command, force=args.force)
    print(tradeoff.table(points))
    rec = tradeoff.recommend(points)
    if rec:
        print(
            f"\nrecommended: {rec['setting']} (|F-V| {rec['visibility_mae']:.4f}; "
            f"best {rec['best']} {rec['best_visibility_mae']:.4f})"
        )
        if "own" in rec:
            h = rec["own"]
            default = (
                ""
                if rec["default"] is None
                else f"; default {rec['default']} {rec['default_visibility_mae']:.4f}"
            )
            print(
                f"for the {technique.get(h['technique']).label}'s own settings: {h['setting']} "
                f"(|F-V| {h['visibility_mae']:.4f}{default})"
            )
    print(f"report: {index}")
    return errors.EXIT_OK


def cmd_export_scene(args) -> int:
    from hzval.commands import export
    from hzval.scene import spec as sc

    base = sc.load_scene(args.scene) if args.scene else (_sidecar_scene(args) or sc.Scene())
    scene = sc.override(
        base,
        height=_material_of(args),
        size=args.size,
        depth=args.depth,
        boundary=args.boundary,
        elevation=args.elevation,
        effects=args.effects,
        spp=args.spp,
        shading=args.shading,
        truth_tolerance=_truth_tolerance(args),
    )
    if not math.isfinite(args.azimuth):
        raise errors.InputError("--azimuth", f"must be a finite number of degrees, got {args.azimuth}")
    export.check_fits(scene)  # before the map is generated or decoded
    hm = sc.load_material_height(scene.material)
    written = export.write_scene(scene, hm.height, args.out, azimuth_deg=args.azimuth, force=args.force)
    print(
        f"wrote {', '.join(str(p) for p in written)}; render it with: mitsuba {args.out / 'scene.xml'} "
        f"-o {args.out / 'mitsuba.exr'}"
    )
    return errors.EXIT_OK


def cmd_score(args) -> int:
    import shlex

    from hzval.commands import score
    from hzval.pipeline import sweep

    gates = _gates(args)
    result, maps = score.score(args.frames, args.against)
    out = args.out or args.frames / "score"
    command = "hzval " + " ".join(shlex.quote(a) for a in (args.argv or []))
    index = score.write(result, maps, out, command=command, force=args.force, gates=gates)
    for w in result.get("warnings", []):
        print(f"hzval: warning: {w}", file=sys.stderr)
    print(sweep.summary_table(result))
    print(f"report: {index}")
    return _gate_exit(result.get("gates", {}).get("failed", []))


def _add_fit(sub) -> None:
    """``hzval fit``: the best horizon map (:mod:`hzval.techniques.fitted.fit`)."""
    from hzval.bake import maps as bake
    from hzval.io import storage
    from hzval.techniques.fitted import fit
    from hzval.techniques.fitted import guard as fit_guard
    from hzval.techniques.horizon import DEFAULT_K

    d = bake.BakeParams()

    p = sub.add_parser(
        "fit",
        help="fit the horizon map to the truth (the representation's floor)",
        description="Fit the 8 horizon channels of a material to the truth's visibility with "
        "Dr.Jit's automatic differentiation through the horizon technique's own "
        "lookup and factor (docs/fit.md); writes horizon0/1.exr and .png in the "
        "bake's layout and fit.json.",
    )
    _add_material_args(p)
    p.add_argument(
        "--lights",
        default=fit.TRAINING_LIGHTS,
        metavar="SPEC",
        help=f"training lights, ELEVATIONS@AZIMUTHS[;...] in degrees (default {fit.TRAINING_LIGHTS})",
    )
    p.add_argument(
        "--held-out",
        default=fit.HELD_OUT_LIGHTS,
        metavar="SPEC",
        help=f"lights scored but not trained on (default {fit.HELD_OUT_LIGHTS}; '' for none)",
    )
    p.add_argument("--fit-k", action="store_true", help="fit the shadow hardness k too")
    p.add_argument(
        "--k",
        type=float,
        default=DEFAULT_K,
        help=f"shadow hardness k (the start with --fit-k) (default {DEFAULT_K:g})",
    )
    p.add_argument(
        "--storage",
        choices=storage.names(),
        default="float",
        help="how the map is stored; the fit is quantisation-aware for all but float (default float)",
    )
    p.add_argument(
        "--guard",
        type=float,
        default=None,
        metavar="TOL",
        help="give a texel back its baked sines where its neighbourhood does worse than the bake on "
        "some training light by more than TOL pixels' |F-V| (hzval.techniques.fitted.guard; e.g. "
        f"{fit_guard.TOLERANCE:g}; default: no guard)",
    )
    p.add_argument(
        "--spp",
        type=int,
        default=None,
        help=f"samples per pixel, as the sweep's (default {_scene_module().Scene().spp})",
    )
    p.add_argument(
        "--seed",
        type=int,
        default=None,
        help=f"random seed of the samples (default {_scene_module().Scene().seed})",
    )
    p.add_argument(
        "--radius", type=int, default=d.radius, help=f"bake search radius in texels (default {d.radius})"
    )
    p.add_argument("--angles", type=int, default=d.angles, help=f"bake angular bins (default {d.angles})")
    p.add_argument(
        "--method",
        choices=bake.METHODS,
        default=d.method,
        help=f"the bake the fit starts from and is compared with (default {d.method})",
    )
    p.add_argument("--out", required=True, type=Path, help="output folder")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(run=cmd_fit)


def cmd_fit(args) -> int:
    """Bake, fit, write; one line of figures."""
    import math

    from hzval.bake import maps as bake
    from hzval.io import files
    from hzval.pipeline import sweep
    from hzval.scene import spec as sc
    from hzval.techniques.fitted import fit

    if not (math.isfinite(args.k) and args.k > 0):
        raise errors.InputError("--k", f"must be a positive number, got {args.k}")
    if args.guard is not None and not (math.isfinite(args.guard) and args.guard >= 0):
        raise errors.InputError("--guard", f"must be a number >= 0, got {args.guard}")
    lights = fit.parse_lights(args.lights, "--lights")
    held_out = fit.parse_lights(args.held_out, "--held-out") if args.held_out.strip() else ()
    scene = sc.override(
        sc.Scene(),
        size=args.size,
        depth=args.depth,
        boundary=args.boundary,
        spp=args.spp,
        seed=args.seed,
        height=_material_of(args),
    )
    params = bake.BakeParams(
        depth=scene.material.depth,
        radius=args.radius,
        angles=args.angles,
        boundary=scene.material.boundary,
        method=args.method,
    ).validate()
    rows, cols = sweep.material_shape(scene)
    what = args.height or "--size"
    bake.check_fits(what, rows, cols, params)
    fit.check_fits(
        what, rows, cols, scene.spp, len(lights) * (1 if args.guard is None else 2) + len(held_out), scene
    )
    with files.output_folder(args.out, force=args.force):
        height, info = load_material(args)
        baked = bake.bake(height, params)
        result = _fitted(args, fit, height, baked, scene, params, info, lights, held_out)
    _print_fit(args, info, rows, cols, result)
    return errors.EXIT_OK


def _fitted(args, fit, height, baked, scene, params, info, lights, held_out):
    """The fit of ``baked`` to the truth, written to ``args.out`` with the sweep's cache key."""
    result = fit.fit(
        height,
        baked,
        scene,
        lights=lights,
        held_out=held_out,
        fit_k=args.fit_k,
        storage=args.storage,
        k=args.k,
        guard=args.guard,
        progress=not args.quiet,
    )
    # the key of the sweep's cache (hzval.techniques.fitted.horizon_fit): a fit written into a sweep's out/fit is reused there
    key = fit.cache_key(
        height,
        baked,
        scene,
        {
            "k": float(args.k),
            "storage": args.storage,
            "fit_k": bool(args.fit_k),
            "lights": args.lights,
            "held_out": args.held_out,
            **({"guard": args.guard} if args.guard is not None else {}),
        },
    )
    fit.write_fit(
        result,
        args.out,
        input_info={
            **info,
            "depth": params.depth,
            "boundary": params.boundary,
            "bake": params.record(),
            "key": key,
        },
    )
    return result


def _print_fit(args, info, rows, cols, result) -> None:
    parts = [f"{w} |F-V| {m['baked']:.4f} baked -> {m['fitted']:.4f} fitted" for w, m in result.mae.items()]
    print(
        f"fitted {info['source']} ({cols}x{rows}, {args.storage}, k {result.k:.3g}) in {result.epochs} epochs, "
        f"{result.seconds['fit']:.1f} s ({'converged' if result.converged else 'not converged'}): "
        f"{'; '.join(parts)} -> {args.out}"
    )


def _join_negative_values(argv: list[str]) -> list[str]:
    """``--azimuths -60:60:15`` as ``--azimuths=-60:60:15``.

    argparse takes a value that starts with ``-`` for an option unless it
    looks like a plain negative number, and the sweep's own default,
    ``-60:60:15``, does not.
    """
    out, it = [], iter(argv)
    for a in it:
        if a in ("--azimuths", "--elevation", "--azimuth"):
            nxt = next(it, None)
            out.append(a if nxt is None else f"{a}={nxt}")
        else:
            out.append(a)
    return out


def main(argv: list[str] | None = None) -> int:
    import signal

    from hzval.core import backend, interrupts
    from hzval.io import files

    argv = list(sys.argv[1:] if argv is None else argv)
    backend.prefer_working_llvm()  # before the parser imports the techniques, and so Dr.Jit
    args = _parser().parse_args(_join_negative_values(argv))
    args.argv = argv
    args.typed = typed_flags(args.parser, argv)
    args.variant = getattr(args, "variant", None)
    # the LLVM is chosen above; the variant when the first renderer asks for it (hzval.core.backend.variant)
    backend.request(args.variant)
    try:
        with interrupts.terminate_as_interrupt():  # SIGTERM unwinds as Ctrl-C does: nothing left behind
            return args.run(args)
    except errors.HzvalError as exc:
        print(f"hzval: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except OSError as exc:  # a read-only or full disk, no permission: one line, its path
        print(f"hzval: error: {files.os_error(exc, '--out')}", file=sys.stderr)
        return errors.EXIT_BAD_INPUT
    except KeyboardInterrupt as exc:
        print("hzval: interrupted", file=sys.stderr)
        return 128 + getattr(exc, "signum", signal.SIGINT)
