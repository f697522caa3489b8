"""``hzval fit``'s flags: a technique's textures fitted to the truth, the representation's floor.

See :mod:`hzval.commands.fit`.
"""

from __future__ import annotations

import math
from pathlib import Path

from hzval.cli import flags, scenes
from hzval.core import errors
from hzval.io import storage as hz_storage

#: The flags that only the horizon map's fit reads.
HORIZON_FLAGS = ("--k", "--fit-k", "--storage", "--guard")


def add_parser(sub) -> None:
    """``hzval fit``: the best textures of a technique (:mod:`hzval.commands.fit`)."""
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.bake import maps as bake
    from hzval.commands import fit as fit_command
    from hzval.techniques import registry as technique
    from hzval.techniques.fitted import guard as fit_guard
    from hzval.techniques.fitted import textures as fitted_textures
    from hzval.techniques.fitted import training as fitted_training
    from hzval.techniques.horizon import DEFAULT_K

    d = bake.BakeParams()

    p = sub.add_parser(
        "fit",
        help="fit a technique's textures to the truth (the representation's floor)",
        description="Fit a technique's textures to the truth's visibility through its own lookup and "
        "factor (docs/fit.md): the horizon map's 8 channels with Dr.Jit's automatic "
        "differentiation (horizon0/1.exr and .png in the bake's layout), or a per-pixel "
        "technique's AO (a per-texel search), bent normal and AO, or self-shadowed bump map "
        "(Adam); writes fit.json.",
    )
    flags.add_material_args(p)
    p.add_argument(
        "--technique",
        default=fit_command.HORIZON,
        choices=[fit_command.HORIZON, *fitted_textures.fittable()],
        help=f"whose textures to fit (default {fit_command.HORIZON})",
    )
    p.add_argument(
        "--lights",
        default=fitted_training.TRAINING_LIGHTS,
        metavar="SPEC",
        help="training lights, ELEVATIONS@AZIMUTHS[;...] in degrees "
        f"(default {fitted_training.TRAINING_LIGHTS})",
    )
    p.add_argument(
        "--held-out",
        default=fitted_training.HELD_OUT_LIGHTS,
        metavar="SPEC",
        help=f"lights scored but not trained on (default {fitted_training.HELD_OUT_LIGHTS}; '' for none)",
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
        choices=hz_storage.names(),
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
        help=f"samples per pixel, as the sweep's (default {flags.scene_module().Scene().spp})",
    )
    p.add_argument(
        "--seed",
        type=int,
        default=None,
        help=f"random seed of the samples (default {flags.scene_module().Scene().seed})",
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
    p.add_argument(
        "--ssbump-lift",
        type=float,
        default=d.ssbump_lift,
        metavar="TEXELS",
        help=f"the self-shadowed bump map's ray lift (default {d.ssbump_lift:g})",
    )
    for name in fitted_textures.fittable():  # their storage, variant and opacity flags
        technique.get(name).add_arguments(p)
    p.add_argument("--out", required=True, type=Path, help="output folder")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(run=run)


def run(args) -> int:
    """Bake, fit, write; one line of figures."""
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.commands import fit as fit_command
    from hzval.techniques.fitted import training as fitted_training

    _check_flags(args)
    lights = fitted_training.parse_lights(args.lights, "--lights")
    held_out = fitted_training.parse_lights(args.held_out, "--held-out") if args.held_out.strip() else ()
    fitted_training.check_held_out(lights, held_out)
    scene = scenes.scene_from_args(args, quiet=True)  # HEIGHT's sidecar gives depth and boundary
    params = flags.bake_params(args, scene)
    horizon = args.technique == fit_command.HORIZON
    result, info = fit_command.run(
        scene,
        params,
        args.technique,
        args.out,
        lights=lights,
        held_out=held_out,
        options=_horizon_options(args) if horizon else _technique_options(args),
        what=args.height or "--size",
        force=args.force,
        progress=not args.quiet,
    )
    if horizon:
        how = f"{args.storage}, k {result.k:.3g}"
        found = f"{result.epochs} epochs"
        scope = " (whole image)"  # the horizon fit's loss and scores count every pixel
    else:
        how = ", ".join(f"{t} {s}" for t, s in result.storage.items())
        found = " then ".join(result.options["steps"])
        scope = ""  # over the pixels facing the light
    rows, cols = info["rows"], info["cols"]
    print(
        f"fitted {scenes.input_name(args, info)} ({args.technique}, {cols}x{rows}, {how}) in "
        f"{result.seconds['fit']:.1f} s by {found} "
        f"({'converged' if result.converged else 'not converged'}): "
        f"{fit_command.summary(result.mae, scope)} -> {args.out}"
    )
    return errors.EXIT_OK


def _check_flags(args) -> None:
    """Refuse a bad value, and a horizon-only flag given to another technique's fit."""
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.commands import fit as fit_command

    if not (math.isfinite(args.k) and args.k > 0):
        raise errors.InputError("--k", f"must be a positive number, got {args.k}")
    if args.guard is not None and not (math.isfinite(args.guard) and args.guard >= 0):
        raise errors.InputError("--guard", f"must be a number >= 0, got {args.guard}")
    if args.technique != fit_command.HORIZON:
        argv = getattr(args, "argv", None) or []
        for flag in HORIZON_FLAGS:
            if any(a == flag or a.startswith(flag + "=") for a in argv):
                raise errors.InputError(
                    flag, f"is the horizon map's fit's; --technique {args.technique} ignores it"
                )


def _horizon_options(args) -> dict:
    """:func:`hzval.techniques.fitted.fit.fit`'s keywords (the sweep's cache key's settings)."""
    return {
        "k": float(args.k),
        "storage": args.storage,
        "fit_k": bool(args.fit_k),
        "lights": args.lights,
        "held_out": args.held_out,
        "guard": args.guard,
    }


def _technique_options(args) -> dict:
    """Return the technique's settings from its own flags, as keywords of a fit.

    The keywords are :func:`hzval.techniques.fitted.textures.fit_textures`'s.
    """
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.techniques import registry as technique

    return {
        "settings": technique.get(args.technique).settings_from_args(args),
        "lights": args.lights,
        "held_out": args.held_out,
    }
