"""``hzval fit``: the horizon map fitted to the truth, the representation's floor
(:mod:`hzval.techniques.fitted.fit`)."""

from __future__ import annotations

import math
from pathlib import Path

from hzval.cli import flags, scenes
from hzval.core import errors


def add_parser(sub) -> None:
    """``hzval fit``: the best horizon map (:mod:`hzval.techniques.fitted.fit`)."""
    from hzval.bake import maps as bake
    from hzval.io import storage
    from hzval.techniques.fitted import guard as fit_guard
    from hzval.techniques.fitted import training as fitted_training
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
    flags.add_material_args(p)
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
    p.add_argument("--out", required=True, type=Path, help="output folder")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(run=run)


def run(args) -> int:
    """Bake, fit, write; one line of figures."""
    from hzval.bake import maps as bake
    from hzval.io import files
    from hzval.techniques.fitted import fit
    from hzval.techniques.fitted import training as fitted_training
    from hzval.truth import memory

    if not (math.isfinite(args.k) and args.k > 0):
        raise errors.InputError("--k", f"must be a positive number, got {args.k}")
    if args.guard is not None and not (math.isfinite(args.guard) and args.guard >= 0):
        raise errors.InputError("--guard", f"must be a number >= 0, got {args.guard}")
    lights = fitted_training.parse_lights(args.lights, "--lights")
    held_out = fitted_training.parse_lights(args.held_out, "--held-out") if args.held_out.strip() else ()
    fitted_training.check_held_out(lights, held_out)
    scene = scenes.scene_from_args(args, quiet=True)  # HEIGHT's sidecar gives depth and boundary
    params = flags.bake_params(args, scene)
    rows, cols = memory.material_shape(scene)
    what = args.height or "--size"
    bake.check_fits(what, rows, cols, params)
    fitted_training.check_fits(
        what, rows, cols, scene.spp, len(lights) * (1 if args.guard is None else 2) + len(held_out), scene
    )
    with files.output_folder(args.out, force=args.force):
        height, info = scenes.load_material(scene)
        baked = bake.bake(height, params)
        result = _fitted(args, fit, height, baked, scene, params, info, lights, held_out)
    _print_fit(args, info, rows, cols, result)
    return errors.EXIT_OK


def _fitted(args, fit, height, baked, scene, params, info, lights, held_out):
    """The fit of ``baked`` to the truth, written to ``args.out`` with the sweep's cache key."""
    from hzval.techniques.fitted import store as fitted_store

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
    # the key of the sweep's cache (hzval.techniques.fitted.horizon_fit): a fit written into a
    # sweep's out/fit is reused there
    key = fitted_store.cache_key(
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
    fitted_store.write_fit(
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
        f"fitted {scenes.input_name(args, info)} ({cols}x{rows}, {args.storage}, k {result.k:.3g}) "
        f"in {result.epochs} epochs, "
        f"{result.seconds['fit']:.1f} s ({'converged' if result.converged else 'not converged'}): "
        f"{'; '.join(parts)} -> {args.out}"
    )
