"""The flags commands share, and the values they parse to.

Each ``add_*`` function declares a group of flags on a command's parser, with the defaults of
the dataclass it fills (:class:`hzval.scene.spec.Scene`, :class:`hzval.bake.maps.BakeParams`,
the technique registry); the functions below them turn the parsed flags into those values,
each error naming the flag as typed.
"""

from __future__ import annotations

import argparse
import math
import shlex
import sys
from pathlib import Path

from hzval import materials
from hzval.core import errors
from hzval.scene import camera as hz_camera


def add_material_args(p: argparse.ArgumentParser, default_size: int | None = None) -> None:
    """Add the material's flags to ``p``: its height map or ``--material``, depth and the rest."""
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


def add_technique_args(p: argparse.ArgumentParser) -> None:
    """Add ``--techniques``, a ``--no-NAME`` for each technique, and each technique's own options.

    They come from the registry; each technique's options are
    :meth:`hzval.techniques.registry.Technique.add_arguments`'s.
    """
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
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


def add_bake_flags(p: argparse.ArgumentParser) -> None:
    """Add the horizon bake's flags (:class:`hzval.bake.maps.BakeParams`, whose defaults they show)."""
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
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
    p.add_argument(
        "--ssbump-lift",
        type=float,
        default=d.ssbump_lift,
        metavar="TEXELS",
        help="how far above each texel the self-shadowed bump map's rays start, so that lower rises "
        f"do not occlude (Valve's height2ssbump: 0.55; 0: none) (default {d.ssbump_lift:g})",
    )


def add_gate_flags(p: argparse.ArgumentParser, strict: bool = True) -> None:
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


def add_sweep_flags(p: argparse.ArgumentParser) -> None:
    """Add the light, samples, shading, bake and technique flags of ``sweep`` (and ``suite``).

    Their defaults are those of :class:`hzval.scene.spec.Scene`.
    """
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.scene import spec as sc

    d, light = sc.Scene(), sc.Light()
    p.add_argument(
        "--elevation",
        default=None,
        metavar="DEG",
        help="light elevations in degrees, in (0, 90]: one, START:STOP:STEP or a list, each "
        f"swept over every azimuth (default {light.elevation_deg:g})",
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
        f"(default {scene_module().Camera().supersampling})",
    )
    p.add_argument(
        "--shading",
        choices=["smooth", "faceted"],
        default=None,
        help="the truth's shading normal: smooth (interpolated vertex normals, as the normal map) "
        "or faceted (each triangle's own) (default smooth)",
    )
    add_truth_tolerance_flag(p)
    add_mesh_flags(p)
    add_view_flags(p)
    add_bake_flags(p)
    p.add_argument(
        "--all-files",
        action="store_true",
        help="also write each frame's files that the others determine: the unshadowed render and "
        "each technique's image as EXR, V and F as PNG (about 1.6x the bytes)",
    )
    add_technique_args(p)


def add_mesh_flags(p: argparse.ArgumentParser) -> None:
    """Add the flags of the surface the material is on (:mod:`hzval.geometry.model`)."""
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
    g.add_argument(
        "--tangents",
        choices=("auto", "mikktspace", "fged2", "file"),
        default=None,
        help="the mesh's tangent frames: mikktspace (what bakers and engines compute), fged2, the "
        "file's TANGENT, or auto (the file's where it has them, else mikktspace; the built-in "
        "shapes keep fged2) (default auto; docs/meshes.md, 'Tangent frames')",
    )


def add_truth_tolerance_flag(p: argparse.ArgumentParser) -> None:
    """``--truth-tolerance``: how closely the truth's triangles follow the bilinear surface."""
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
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


def add_view_flags(p: argparse.ArgumentParser) -> None:
    """Add the camera's and the techniques' lookup flags.

    See :mod:`hzval.scene.camera` and :mod:`hzval.scene.lookup`.
    """
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.scene import lookup

    c, lk = hz_camera.Camera(), lookup.Lookup()
    g = p.add_argument_group("view", "where the camera is, and how the techniques read their textures")
    g.add_argument(
        "--camera",
        choices=hz_camera.KINDS,
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
        help="perspective: the eye's distance from the tile's centre in tile widths "
        f"(default {c.distance:g})",
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
        help="texture filtering: nearest, bilinear, trilinear from mip-maps, anisotropic "
        f"(default {lk.filter})",
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


def scene_module():
    """Return :mod:`hzval.scene.spec`, imported on first use."""
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.scene import spec as sc

    return sc


def light_default():
    """Return the default light (:class:`hzval.scene.spec.Light`), whose values the help texts show."""
    return scene_module().Light()


def resolution(text: str | None):
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


def truth_tolerance(args):
    """``--truth-tolerance`` checked: a positive, finite number of texels, or None."""
    t = getattr(args, "truth_tolerance", None)
    if t is not None and not (math.isfinite(t) and t > 0):
        raise errors.InputError("--truth-tolerance", f"must be a positive number of texels, got {t}")
    return t


def technique_options(args) -> dict:
    """Return the ``sweep.Options`` keywords of the technique options, each checked.

    An error names the flag as typed (:func:`hzval.techniques.registry.flag_errors`).
    """
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.bake import maps as bake
    from hzval.techniques import registry as technique

    requested = None
    if args.techniques is not None:
        requested = tuple(n.strip() for n in args.techniques.split(",") if n.strip())
    params = bake.BakeParams(
        radius=args.radius,
        angles=args.angles,
        method=args.method,
        directions=args.directions,
        ssbump_lift=args.ssbump_lift,
    ).validate()
    settings = {}
    for n in technique.names():
        t = technique.get(n)
        with technique.flag_errors(t, getattr(args, "typed", {})):
            settings[n] = t.settings_from_args(args)
            if n in (requested or technique.defaults()):  # the others' settings are never used
                t.check_settings(params, settings[n])
    return {"techniques": requested, "exclude": tuple(args.exclude), "settings": settings}


def check_technique_flags(args, names) -> None:
    """Refuse a technique's flag given to a run that leaves out every technique that reads it.

    ``names`` are the run's techniques. ``--horizon-map`` with ``--techniques pom`` was ignored in silence.
    """
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.techniques import registry as technique

    readers: dict[str, list[str]] = {}
    for n in technique.names():
        t = technique.get(n)
        for flag in {*t.flags.values(), *t.input_flags}:
            readers.setdefault(flag, []).append(n)
    argv = getattr(args, "argv", None) or []
    for flag, by in readers.items():
        if not any(a == flag or a.startswith(flag + "=") for a in argv) or set(by) & set(names):
            continue
        raise errors.InputError(
            flag, f"is read by {', '.join(by)}, which this run leaves out (it runs {', '.join(names)})"
        )


def sweep_options(args):
    """Return the :class:`hzval.pipeline.sweep.Options` of the sweep flags."""
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.pipeline import sweep

    return sweep.Options(
        radius=args.radius,
        angles=args.angles,
        method=args.method,
        directions=args.directions,
        ssbump_lift=args.ssbump_lift,
        all_files=args.all_files,
        **technique_options(args),
    )


def gates(args):
    """Return the :class:`hzval.commands.gates.Gates` of ``--fail-if`` and ``--baseline``.

    They are checked before the run.
    """
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.commands import gates

    return gates.Gates(
        getattr(args, "fail_if", None), getattr(args, "baseline", None), strict=getattr(args, "strict", False)
    )


def gate_exit(record: dict | None) -> int:
    """Print a run's failed gates and gate errors, one line each; return the exit code.

    The gates are ``metrics.json``'s ``gates``. The code is 2 where any could not be evaluated (``errors``),
    else 1 where any failed, else 0.
    """
    record = record or {}
    failed = record.get("failed", [])
    for line in failed:
        print(f"hzval: gate failed: {line}", file=sys.stderr)
    for line in record.get("errors", []):
        print(f"hzval: error: {line}", file=sys.stderr)
    if record.get("errors"):
        return errors.EXIT_BAD_INPUT
    return errors.EXIT_CHECK_FAILED if failed else errors.EXIT_OK


def bake_params(args, scene):
    """Return the :class:`hzval.bake.maps.BakeParams` of the bake flags on ``scene``'s material, checked.

    The bake flags are :func:`add_bake_flags`'s; the material's depth and boundary are HEIGHT's sidecar's
    where it has one.
    """
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.bake import maps as bake

    d = bake.BakeParams()
    return bake.BakeParams(
        depth=scene.material.depth,
        radius=args.radius,
        angles=args.angles,
        boundary=scene.material.boundary,
        method=args.method,
        directions=getattr(args, "directions", d.directions),
        ssbump_lift=getattr(args, "ssbump_lift", d.ssbump_lift),
    ).validate()


def print_notes(args) -> None:
    """Print the notes the flags' scene left for the end of a run.

    The scene is :func:`hzval.cli.scenes.scene_from_args`'s.
    """
    for note in getattr(args, "notes", []):
        print(f"hzval: note: {note}", file=sys.stderr)


def command_line(args) -> str:
    """Return the command as typed (``hzval sweep m.png --spp 4``), shell-quoted.

    It is for a report's Reproduce line.
    """
    return "hzval " + " ".join(shlex.quote(a) for a in (getattr(args, "argv", None) or []))


def names(text: str | None) -> list[str] | None:
    """Return a comma-separated flag value (``--views top,ortho-45``) as its names; ``None`` if not given."""
    return None if text is None else [v.strip() for v in text.split(",") if v.strip()]
