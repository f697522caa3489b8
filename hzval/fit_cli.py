"""``hzval fit``: the command line of :mod:`hzval.fit` (registered by :mod:`hzval.cli`)."""

from __future__ import annotations

from pathlib import Path

from hzval import errors


def add_parser(sub) -> None:
    """The ``fit`` subcommand and its flags."""
    from hzval import cli, fit, storage
    from hzval.approx import DEFAULT_K

    p = sub.add_parser("fit", help="fit the horizon map to the truth (the representation's floor)",
                       description="Fit the 8 horizon channels of a material to the truth's visibility with "
                                   "Dr.Jit's automatic differentiation through the horizon technique's own "
                                   "lookup and factor (docs/fit.md); writes horizon0/1.exr and .png in the "
                                   "bake's layout and fit.json.")
    cli._add_material_args(p)
    p.add_argument("--lights", default=fit.TRAINING_LIGHTS, metavar="SPEC",
                   help=f"training lights, ELEVATIONS@AZIMUTHS[;...] in degrees (default {fit.TRAINING_LIGHTS})")
    p.add_argument("--held-out", default=fit.HELD_OUT_LIGHTS, metavar="SPEC",
                   help=f"lights scored but not trained on (default {fit.HELD_OUT_LIGHTS}; '' for none)")
    p.add_argument("--fit-k", action="store_true", help="fit the shadow hardness k too")
    p.add_argument("--k", type=float, default=DEFAULT_K, help=f"shadow hardness k (the start with --fit-k) "
                                                            f"(default {DEFAULT_K:g})")
    p.add_argument("--storage", choices=storage.names(), default="float",
                   help="how the map is stored; the fit is quantisation-aware for all but float (default float)")
    p.add_argument("--spp", type=int, default=None, help="samples per pixel, as the sweep's (default 16)")
    p.add_argument("--seed", type=int, default=None, help="random seed of the samples (default 0)")
    p.add_argument("--radius", type=int, default=16, help="bake search radius in texels (default 16)")
    p.add_argument("--angles", type=int, default=32, help="bake angular bins (default 32)")
    p.add_argument("--method", choices=["seed", "exact"], default="seed",
                   help="the bake the fit starts from and is compared with (default seed)")
    p.add_argument("--out", required=True, type=Path, help="output folder")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(run=cmd_fit)


def cmd_fit(args) -> int:
    """Bake, fit, write; one line of figures."""
    import math

    from hzval import backend, bake, cli, fit, sweep
    from hzval import scene as sc

    if not (math.isfinite(args.k) and args.k > 0):
        raise errors.InputError("--k", f"must be a positive number, got {args.k}")
    lights = fit.parse_lights(args.lights, "--lights")
    held_out = fit.parse_lights(args.held_out, "--held-out") if args.held_out.strip() else ()
    scene = sc.override(sc.Scene(), size=args.size, depth=args.depth, boundary=args.boundary, spp=args.spp,
                        seed=args.seed, height=cli._material_of(args))
    params = bake.BakeParams(depth=scene.material.depth, radius=args.radius, angles=args.angles,
                             boundary=scene.material.boundary, method=args.method).validate()
    rows, cols = sweep.material_shape(scene)
    what = args.height or "--size"
    bake.check_fits(what, rows, cols, params)
    fit.check_fits(what, rows, cols, scene.spp, len(lights) + len(held_out), scene)
    height, info = cli.load_material(args)
    backend.variant(args.variant)
    baked = bake.bake(height, params)
    result = fit.fit(height, baked, scene, lights=lights, held_out=held_out, fit_k=args.fit_k,
                     storage=args.storage, k=args.k, progress=not args.quiet)
    # the key of the sweep's cache (hzval.horizon_fit): a fit written into a sweep's out/fit is reused there
    key = fit.cache_key(height, baked, scene, {"k": float(args.k), "storage": args.storage, "fit_k": bool(args.fit_k),
                                               "lights": args.lights, "held_out": args.held_out})
    fit.write_fit(result, args.out, input_info={**info, "depth": params.depth, "boundary": params.boundary,
                                                "bake": params.record(), "key": key})
    parts = [f"{w} |F-V| {m['baked']:.4f} baked -> {m['fitted']:.4f} fitted" for w, m in result.mae.items()]
    print(f"fitted {info['source']} ({cols}x{rows}, {args.storage}, k {result.k:.3g}) in {result.epochs} epochs, "
          f"{result.seconds['fit']:.1f} s ({'converged' if result.converged else 'not converged'}): "
          f"{'; '.join(parts)} -> {args.out}")
    return errors.EXIT_OK
