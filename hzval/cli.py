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

from hzval import errors, fit_cli


def _add_material_args(p: argparse.ArgumentParser, default_size: int | None = None) -> None:
    from hzval import materials

    if default_size is None:
        default_size = materials.DEFAULT_SIZE
    p.add_argument("height", nargs="?", metavar="HEIGHT",
                   help="height map: PNG (8/16-bit), EXR or .npy; default: the built-in brick wall")
    p.add_argument("--material", choices=materials.names(), default=None, metavar="NAME",
                   help=f"a built-in material instead of HEIGHT: {', '.join(materials.names())} "
                        "(`hzval materials` describes them)")
    p.add_argument("--depth", type=float, default=None,
                   help="world height of H = 1 in image widths (default: the material's, 0.05 for a file)")
    p.add_argument("--boundary", choices=["wrap", "open"], default=None,
                   help="wrap: the texture tiles; open: a terrain with nothing outside (default: the "
                        "material's, wrap for a file)")
    p.add_argument("--size", type=int, default=None, metavar="N",
                   help=f"size in texels of a built-in material (default {default_size}); ignored with HEIGHT")


def _material_of(args) -> str | None:
    """The material the command line names: HEIGHT's path, ``--material``'s name, or ``None``."""
    if args.height is not None and args.material is not None:
        raise errors.InputError("--material", f"give HEIGHT ({args.height}) or --material, not both")
    return str(args.height) if args.height is not None else args.material


def _scene_name(args, scene) -> str:
    """A sweep's name: HEIGHT's stem, else the scene's (a built-in material's name unless a scene file
    names it)."""
    if args.height is not None:
        return Path(args.height).stem
    if getattr(args, "material", None) is not None and not getattr(args, "scene", None):
        return args.material
    return scene.name


def _tradeoff_default_size() -> int:
    from hzval import tradeoff

    return tradeoff.DEFAULT_SIZE


def _add_technique_args(p: argparse.ArgumentParser) -> None:
    """``--techniques``, a ``--no-NAME`` for each technique, and each technique's
    own options (:meth:`hzval.technique.Technique.add_arguments`), from the registry."""
    from hzval import technique

    names = technique.names()
    p.add_argument("--techniques", default=None, metavar="NAMES",
                   help=f"comma-separated techniques to score: {', '.join(names)} (default: every one that "
                        "applies to the declared effects)")
    for name in names:
        t = technique.get(name)
        p.add_argument(f"--no-{name}", dest="exclude", action="append_const", const=name, default=[],
                       help=f"leave out {t.label} ({t.summary})")
    for name in names:
        technique.get(name).add_arguments(p)


def _technique_options(args) -> dict:
    """``sweep.Options`` keywords of the technique options."""
    from hzval import technique

    requested = None
    if args.techniques is not None:
        requested = tuple(n.strip() for n in args.techniques.split(",") if n.strip())
    settings = {n: technique.get(n).settings_from_args(args) for n in technique.names()}
    return {"techniques": requested, "exclude": tuple(args.exclude), "settings": settings}


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="hzval", description="Validate horizon mapping and the self-shadowing techniques it competes with "
                                  "against ray-traced ground truth.")
    parser.add_argument("--variant", default=None,
                        help="Mitsuba variant (default: cuda_ad_rgb with a GPU, else llvm_ad_rgb; "
                             "or $HZVAL_VARIANT)")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    _add_bake(sub)
    _add_sweep(sub)
    _add_check(sub)
    _add_tradeoff(sub)
    _add_views(sub)
    _add_export_scene(sub)
    _add_score(sub)
    _add_suite(sub)
    _add_materials(sub)
    fit_cli.add_parser(sub)
    return parser


def _add_bake(sub) -> None:
    p = sub.add_parser("bake", help="bake normal, horizon and ambient maps from a height map",
                       description="Bake the horizon-mapping textures of a height map (docs/ARCHITECTURE.md).")
    _add_material_args(p)
    p.add_argument("--radius", type=int, default=16, help="search radius in texels (default 16)")
    p.add_argument("--angles", type=int, default=32, help="angular bins, a multiple of 2 x --directions (16 or 32) (default 32)")
    p.add_argument("--directions", type=int, default=8,
                   help="stored horizon directions: 8 (Lengyel's, two RGBA layers) or 16 (22.5 degrees apart, "
                        "four layers; seed method, --angles a multiple of 32) (default 8)")
    p.add_argument("--method", choices=["seed", "exact"], default="seed",
                   help="horizon bake: seed (Lengyel's bins within --radius) or exact (exact horizons toward "
                        "the 8 channel directions, unlimited radius; ignores --radius and --angles) (default seed)")
    p.add_argument("--mesh", action="store_true",
                   help="also write the displaced triangle mesh as mesh.ply")
    p.add_argument("--out", required=True, type=Path, help="output folder")
    p.set_defaults(run=cmd_bake)


def _add_sweep(sub) -> None:
    from hzval import technique

    labels = ", ".join(technique.get(n).label for n in technique.names())
    p = sub.add_parser("sweep", help="render the truth and every technique over a light sweep and report",
                       description=f"Render the ground truth and every self-shadowing technique ({labels}: "
                                   "--techniques) for every light of the sweep (Lengyel's Figure 5.3 by "
                                   "default), compare them, and write metrics.json and an HTML report.")
    _add_material_args(p)
    p.add_argument("--scene", type=Path, default=None,
                   help="scene description (TOML); the flags below override it (default: built-in bricks)")
    _add_sweep_flags(p)
    p.add_argument("--out", type=Path, default=None, help="output folder (default reports/<scene name>)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=cmd_sweep)


def _add_sweep_flags(p: argparse.ArgumentParser) -> None:
    """The light, samples, shading, bake and technique flags of ``sweep`` (and ``suite``)."""
    p.add_argument("--elevation", type=float, default=None, help="light elevation in degrees (default 30)")
    p.add_argument("--azimuths", default=None,
                   help="light azimuths in degrees, START:STOP:STEP or a list (default -60:60:15)")
    p.add_argument("--light", choices=["hard", "soft"], default=None, help="directional or disk light")
    p.add_argument("--light-radius", type=float, default=None, metavar="DEG",
                   help="angular radius of a soft light in degrees")
    p.add_argument("--effects", default=None,
                   help="comma-separated effects: shadow, diffuse, specular, ambient, "
                        "reflection_occlusion, interreflection (default shadow,diffuse)")
    p.add_argument("--spp", type=int, default=None, help="samples per pixel (default 16)")
    p.add_argument("--seed", type=int, default=None, help="random seed of the samples (default 0)")
    p.add_argument("--supersampling", type=int, default=None,
                   help="pixels per texel along each axis: a magnification, not anti-aliasing (--spp samples "
                        "each pixel); FLIP and the other image scores depend on it (default 1)")
    p.add_argument("--shading", choices=["smooth", "faceted"], default=None,
                   help="the truth's shading normal: smooth (interpolated vertex normals, as the normal map) "
                        "or faceted (each triangle's own) (default smooth)")
    _add_view_flags(p)
    p.add_argument("--radius", type=int, default=16, help="bake search radius in texels (default 16)")
    p.add_argument("--angles", type=int, default=32, help="bake angular bins, a multiple of 2 x --directions (default 32)")
    p.add_argument("--directions", type=int, default=8, help="stored horizon directions, 8 or 16 (default 8)")
    p.add_argument("--method", choices=["seed", "exact"], default="seed",
                   help="horizon bake method: seed or exact (unlimited radius) (default seed)")
    p.add_argument("--all-files", action="store_true",
                   help="also write each frame's files that the others determine: the unshadowed render and "
                        "each technique's image as EXR, V and F as PNG (about 1.6x the bytes)")
    _add_technique_args(p)


def _add_views(sub) -> None:
    from hzval import views

    p = sub.add_parser("views", help="the light sweep from a set of views, and where each technique breaks",
                       description="Sweep one material from the top, orthographically at 60, 45, 30 and 15 "
                                   "degrees and in perspective near and far, each with bilinear reads, "
                                   "mip-maps, parallax occlusion mapping and both; write DIR/<view>/<lookup>/ "
                                   "(sweep reports), DIR/views.json and DIR/index.html, which plots each "
                                   "technique's error against view elevation and pixel footprint.")
    _add_material_args(p, default_size=128)
    p.add_argument("--azimuths", default="-60:60:30", help="light azimuths in degrees (default -60:60:30)")
    p.add_argument("--elevation", type=float, default=None, help="light elevation in degrees (default 30)")
    p.add_argument("--spp", type=int, default=4, help="samples per pixel (default 4)")
    p.add_argument("--views", default=None, help=f"comma-separated views (default all: {', '.join(views.VIEWS)})")
    p.add_argument("--lookups", default=None,
                   help=f"comma-separated lookups (default all: {', '.join(views.LOOKUPS)})")
    p.add_argument("--out", type=Path, default=None, help="output folder (default reports/views-<name>)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(run=cmd_views)


def cmd_views(args) -> int:
    import shlex

    from hzval import backend, scene as sc, views

    base = sc.Scene()
    if args.height is not None and sc.sidecar_of(args.height) is not None:
        base = sc.load_sidecar(sc.sidecar_of(args.height), args.height)
    size = args.size if args.size is not None else (None if args.height else 128)
    scene = sc.override(base, height=_material_of(args), size=size, depth=args.depth, boundary=args.boundary,
                        elevation=args.elevation, azimuths=args.azimuths, spp=args.spp)
    scene = dataclasses.replace(scene, name=_scene_name(args, scene))
    backend.variant(args.variant)
    out = args.out or Path("reports") / f"views-{scene.name}"
    command = "hzval " + " ".join(shlex.quote(a) for a in (args.argv or []))
    split = (lambda t: None if t is None else [v.strip() for v in t.split(",") if v.strip()])
    data = views.run(scene, out, views=split(args.views), lookups=split(args.lookups), progress=not args.quiet,
                     command=command)
    names = sorted({n for r in data["rows"] for n in r["techniques"]})
    print(f"{'view':10} {'lookup':14} {'footprint':>9} {'parallax':>9}  " + "  ".join(f"{n:>9}" for n in names))
    for r in data["rows"]:
        fp, pe = r["footprint_texels"].get("p50"), r["parallax_error_texels"].get("mean")
        vals = "  ".join(f"{r['techniques'][n]['visibility_mae']:9.4f}" for n in names)
        print(f"{r['view']:10} {r['lookup']:14} {fp if fp is not None else float('nan'):9.2f} "
              f"{pe if pe is not None else float('nan'):9.3f}  {vals}")
    print(f"report: {out / 'index.html'}")
    return errors.EXIT_OK


def _add_view_flags(p: argparse.ArgumentParser) -> None:
    """The camera's and the techniques' lookup flags (:mod:`hzval.camera`, :mod:`hzval.lookup`)."""
    from hzval import camera, lookup

    g = p.add_argument_group("view", "where the camera is, and how the techniques read their textures")
    g.add_argument("--camera", choices=camera.KINDS, default=None,
                   help="top (straight down, one pixel per texel: the default), orthographic or perspective")
    g.add_argument("--view-elevation", type=float, default=None, metavar="DEG",
                   help="the camera's elevation above the surface (default 45)")
    g.add_argument("--view-azimuth", type=float, default=None, metavar="DEG",
                   help="the direction from the surface toward the camera, as the light's azimuth (default -90)")
    g.add_argument("--fov", type=float, default=None, metavar="DEG",
                   help="perspective: horizontal field of view (default 40)")
    g.add_argument("--distance", type=float, default=None, metavar="D",
                   help="perspective: the eye's distance from the tile's centre in tile widths (default 1.5)")
    g.add_argument("--resolution", default=None, metavar="WxH", help="image size (default the top view's)")
    g.add_argument("--plane", choices=lookup.PLANES, default=None,
                   help="the techniques' flat surface at the bottom, mean or top of the relief (default mean)")
    g.add_argument("--filter", choices=lookup.FILTERS, default=None,
                   help="texture filtering: nearest, bilinear (default), trilinear from mip-maps, anisotropic")
    g.add_argument("--mips", choices=lookup.MIPS, default=None,
                   help="the horizon map's mip-maps by averaging (default) or by the maximum (conservative)")
    g.add_argument("--parallax", choices=lookup.PARALLAX, default=None,
                   help="parallax mapping of the lookup: none (default), offset (with offset limiting) or "
                        "occlusion (linear search and refinement)")


def _resolution(text: str | None):
    """``"WxH"`` as ``(W, H)``."""
    if text is None:
        return None
    try:
        w, h = (int(v) for v in text.lower().split("x"))
        if w < 1 or h < 1:
            raise ValueError
    except ValueError:
        raise errors.InputError("--resolution", f"expected WIDTHxHEIGHT in pixels, e.g. 512x384, got {text!r}") from None
    return (w, h)


def _add_suite(sub) -> None:
    from hzval import materials

    p = sub.add_parser("suite", help="sweep many materials (the built-in ones by default) and write an overview",
                       description="Sweep every material (the built-in ones, or scene TOMLs, height maps - each "
                                   "with an optional sidecar <stem>.toml - folders of them, or built-in names) "
                                   "with the same options, on a pool of worker processes or a Dask cluster; "
                                   "write each material's report under DIR, and DIR/index.html and "
                                   "DIR/suite.json with every material's mean errors and times.")
    p.add_argument("inputs", nargs="*", metavar="SCENE.toml|HEIGHT|FOLDER|NAME",
                   help="materials to sweep (default: every built-in material)")
    p.add_argument("--depth", type=float, default=None, help="override every material's depth")
    p.add_argument("--boundary", choices=["wrap", "open"], default=None, help="override every material's boundary")
    p.add_argument("--size", type=int, default=None, metavar="N",
                   help=f"size of the built-in materials (default {materials.DEFAULT_SIZE})")
    _add_sweep_flags(p)
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="worker processes on this machine, each sweeping one material at a time (default: "
                        "1 per core, as many as fit in memory, at most the number of materials, at least 1); "
                        "0 sweeps them in this process, where a crash ends the suite")
    p.add_argument("--cluster", default=None, metavar="ADDRESS",
                   help="run on the Dask scheduler at ADDRESS (tcp://host:8786) instead; its workers need "
                        "hzval and DIR and the inputs at the same paths")
    p.add_argument("--out", type=Path, default=Path("reports") / "suite", metavar="DIR",
                   help="output folder (default reports/suite)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=cmd_suite)


def _add_materials(sub) -> None:
    p = sub.add_parser("materials", help="list the built-in materials",
                       description="List the built-in materials (--material NAME, [material] height = \"NAME\", "
                                   "hzval suite) with their default depth and boundary.")
    p.set_defaults(run=cmd_materials)


def _add_check(sub) -> None:
    p = sub.add_parser("check", help="render the shipped scenes and compare them with reference/ (CI)",
                       description="Render every scene of scenes/ at its small [check] size and compare the "
                                   "truth (statistically) and the approximation (tightly) with the references. "
                                   "Exit 0 when all pass, 1 when any fails; a failure writes an HTML report.")
    p.add_argument("--references", type=Path, default=None, help="reference folder (default: reference/)")
    p.add_argument("--scenes", type=Path, default=None, help="scene folder (default: scenes/)")
    p.add_argument("--report", type=Path, default=None,
                   help="write the HTML report here (default: reports/check, and only on failure)")
    p.add_argument("--update", action="store_true",
                   help="rewrite the references that are missing or failing, and say which")
    p.add_argument("--seed", type=int, default=None, help="render the truth with this seed instead of the scene's")
    p.add_argument("--scene", dest="only", action="append", default=None, metavar="NAME",
                   help="check only this scene (repeatable)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=cmd_check)


def _add_tradeoff(sub) -> None:
    p = sub.add_parser("tradeoff", help="measure what accuracy costs in time and memory on one material",
                       description="Measure bake, approximation and truth settings against a converged truth "
                                   "over the sweep: time, texture memory, visibility error and FLIP; write "
                                   "tradeoff.json, a Pareto plot and a page that recommends a setting.")
    _add_material_args(p, default_size=_tradeoff_default_size())
    p.add_argument("--elevation", type=float, default=None, help="light elevation in degrees (default 30)")
    p.add_argument("--azimuths", default=None, help="light azimuths in degrees (default -60:60:15)")
    p.add_argument("--truth-spp", type=int, default=None, metavar="N",
                   help="shadow rays per pixel of the converged truth (default 256)")
    p.add_argument("--spp", type=int, default=None, help="samples per pixel of the settings (default 16)")
    p.add_argument("--only", action="append", default=None, metavar="TEXT",
                   help="measure only the settings whose names contain TEXT (repeatable)")
    p.add_argument("--out", type=Path, default=None, help="output folder (default reports/tradeoff-<name>)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=cmd_tradeoff)


def _add_export_scene(sub) -> None:
    p = sub.add_parser("export-scene", help="write the truth of one light as a Mitsuba 3 scene file",
                       description="Write DIR/scene.xml and DIR/mesh.ply: the displaced mesh with its vertex "
                                   "normals, a diffuse BSDF with the albedo, a directional emitter and an "
                                   "orthographic sensor over the tile, as hzval's truth traces them. "
                                   "Render it with `mitsuba DIR/scene.xml -o out.exr`.")
    _add_material_args(p)
    p.add_argument("--scene", type=Path, default=None, help="scene description (TOML)")
    p.add_argument("--elevation", type=float, default=None, help="light elevation in degrees (default 30)")
    p.add_argument("--azimuth", type=float, default=0.0, help="light azimuth in degrees (default 0)")
    p.add_argument("--effects", default=None, help="shadow and/or diffuse (default shadow,diffuse)")
    p.add_argument("--spp", type=int, default=None, help="samples per pixel (default 16)")
    p.add_argument("--shading", choices=["smooth", "faceted"], default=None,
                   help="vertex normals in the PLY (smooth, default) or none (faceted)")
    p.add_argument("--out", required=True, type=Path, help="output folder")
    p.set_defaults(run=cmd_export_scene)


def _add_score(sub) -> None:
    p = sub.add_parser("score", help="score your engine's frames of a sweep against its truth",
                       description="Read one image per light of SWEEP_DIR (named after its frame folders: "
                                   "az+0.exr linear, or az+0.png sRGB; SWEEP_DIR/frames.json says how to render "
                                   "them), score each against the sweep's truth with the sweep's image metrics, "
                                   "and write metrics.json and a report.")
    p.add_argument("frames", type=Path, metavar="FRAMES_DIR", help="folder of your renderer's frames")
    p.add_argument("--against", required=True, type=Path, metavar="SWEEP_DIR", help="a folder hzval sweep wrote")
    p.add_argument("--out", type=Path, default=None, help="output folder (default FRAMES_DIR/score)")
    p.set_defaults(run=cmd_score)


def load_material(args) -> tuple["np.ndarray", dict]:  # noqa: F821
    """The height map named on the command line, or a built-in one, with its description."""
    from hzval import heightmap, materials
    from hzval import scene as sc

    if args.height is None:
        name = args.material or materials.DEFAULT
        m = materials.get(name)
        size = materials.DEFAULT_SIZE if args.size is None else args.size
        if size < m.min_size:
            raise errors.InputError("--size", f"the built-in {name} needs at least {m.min_size} texels, got {size}")
        hm = sc.load_material_height(sc.MaterialSpec(height=name, size=size))
        info = {"path": None, "builtin": name, "size": size}
    else:
        hm = heightmap.load_height(args.height)
        info = {"path": str(args.height)}
    rows, cols = hm.height.shape
    info.update(source=hm.source, digest=hm.digest, rows=rows, cols=cols)
    return hm.height, info


def cmd_bake(args) -> int:
    from hzval import backend, bake, heightmap, materials, mesh
    from hzval.scene import material_defaults

    defaults = material_defaults(_material_of(args) or materials.DEFAULT)
    params = bake.BakeParams(depth=defaults["depth"] if args.depth is None else args.depth, radius=args.radius,
                             angles=args.angles, boundary=args.boundary or defaults["boundary"],
                             method=args.method, directions=args.directions).validate()
    if args.height is not None:
        rows, cols = heightmap.probe_shape(args.height)
        bake.check_fits(args.height, rows, cols, params)
    else:   # estimate before generating the built-in map too
        size = materials.DEFAULT_SIZE if args.size is None else args.size
        bake.check_fits("--size", size, size, params)
    t0 = time.perf_counter()
    height, info = load_material(args)
    t_load = time.perf_counter() - t0
    backend.variant(args.variant)
    result = bake.bake(height, params)
    result.timings = {"load_s": t_load, **result.timings}
    written = bake.write_bake(result, args.out, input_info=info)
    if args.mesh:
        from hzval import files

        m = mesh.displaced_mesh(height, params.depth, params.boundary)
        with files.atomic_path(args.out / "mesh.ply") as tmp:
            m.write_ply(str(tmp))
        written.append(args.out / "mesh.ply")
    total = time.perf_counter() - t0
    rows, cols = height.shape
    how = (f"radius {params.radius}, {params.angles} bins, {params.directions} directions" if params.method == "seed"
           else "exact horizons, unlimited radius")
    print(f"baked {info['source']} ({cols}x{rows}, depth {params.depth:g}, {how}, "
          f"{params.boundary}) in {total:.2f} s -> {args.out} ({len(written)} files)")
    return errors.EXIT_OK


def cmd_sweep(args) -> int:
    import shlex

    from hzval import backend, scene as sc, sweep

    base = sc.Scene()
    if args.scene:
        base = sc.load_scene(args.scene)
    elif args.height is not None and sc.sidecar_of(args.height) is not None:
        base = sc.load_sidecar(sc.sidecar_of(args.height), args.height)
        print(f"hzval: using the sidecar scene {sc.sidecar_of(args.height)}", file=sys.stderr)
    scene = sc.override(base, **_scene_overrides(args), height=_material_of(args))
    scene = dataclasses.replace(scene, name=_scene_name(args, scene))
    options = sweep_options(args)
    out = args.out or Path("reports") / scene.name
    backend.variant(args.variant)
    command = "hzval " + " ".join(shlex.quote(a) for a in (args.argv or []))
    result = sweep.run(scene, out, options=options, command=command, progress=not args.quiet)
    for w in result.get("warnings", []):
        print(f"hzval: warning: {w}", file=sys.stderr)
    print(sweep.summary_table(result))
    t = result["timings"]
    parts = [f"bake {t['bake_s']:.2f} s{', cached' if t['bake_cached'] else ''}",
             f"truth {t['truth_setup_s'] + t['truth_s']:.2f} s"]
    parts += [f"{name} {t.get(info['file_stem'] + '_setup_s', 0) + t[info['file_stem'] + '_s']:.2f} s"
              for name, info in result["techniques"].items()]
    print(f"\n{len(result['frames'])} frames in {t['total_s']:.1f} s ({', '.join(parts)}; peak memory "
          f"{result['memory']['peak_rss_bytes'] / 2**30:.2f} GiB); report: {out / 'index.html'}")
    return errors.EXIT_OK


def _scene_overrides(args) -> dict:
    """The sweep flags that change a scene (:func:`hzval.scene.override`'s keywords), material aside."""
    return dict(size=args.size, depth=args.depth, boundary=args.boundary, elevation=args.elevation,
                azimuths=args.azimuths, light=args.light, light_radius=args.light_radius, effects=args.effects,
                spp=args.spp, seed=args.seed, supersampling=args.supersampling, shading=args.shading,
                camera=args.camera, view_elevation=args.view_elevation, view_azimuth=args.view_azimuth,
                fov=args.fov, distance=args.distance, resolution=_resolution(args.resolution), plane=args.plane,
                filter=args.filter, mips=args.mips, parallax=args.parallax)


def sweep_options(args):
    """The :class:`hzval.sweep.Options` of the sweep flags."""
    from hzval import sweep

    return sweep.Options(radius=args.radius, angles=args.angles, method=args.method, directions=args.directions,
                         all_files=args.all_files, **_technique_options(args))


def cmd_suite(args) -> int:
    import shlex

    from hzval import backend, suite

    items = suite.entries(args.inputs, **_scene_overrides(args))
    workers = args.workers if args.workers is not None else suite.default_workers(items)
    if args.cluster is None and workers == 0:
        backend.variant(args.variant)
    command = "hzval " + " ".join(shlex.quote(a) for a in (args.argv or []))
    result = suite.run(items, args.out, options=sweep_options(args), workers=workers, cluster=args.cluster,
                       variant=args.variant, command=command, progress=not args.quiet)
    print(suite.summary_table(result))
    s = result["suite"]
    print(f"\n{s['materials']} materials ({s['failed']} failed) in {s['seconds']:.1f} s on {s['engine']}; "
          f"overview: {args.out / 'index.html'}")
    return errors.EXIT_OK if not s["failed"] else errors.EXIT_CHECK_FAILED


def cmd_materials(args) -> int:
    from hzval import materials

    print(f"{'name':13s} {'depth':>6s}  {'boundary':8s}  what it is")
    for name in materials.names():
        m = materials.get(name)
        print(f"{name:13s} {m.depth:6g}  {m.boundary:8s}  {m.label}: {m.summary}")
    return errors.EXIT_OK


def cmd_check(args) -> int:
    import shlex

    from hzval import backend, check

    backend.variant(args.variant)
    result = check.run(scenes_dir=args.scenes, references=args.references, update=args.update,
                       seed=args.seed, progress=not args.quiet, only=args.only)
    print(check.summary(result))
    for path in result.updated:
        print(f"updated {path}")
    failed = not result.passed and not args.update
    if failed or args.report:
        out = args.report or Path("reports") / "check"
        command = "hzval " + " ".join(shlex.quote(a) for a in (args.argv or []))
        index = check.write_report(result, out, command=command)
        print(f"report: {index}")
    return errors.EXIT_CHECK_FAILED if failed else errors.EXIT_OK


def cmd_tradeoff(args) -> int:
    import shlex

    from hzval import backend, scene as sc, technique, tradeoff

    size = args.size if args.size is not None else (None if args.height else tradeoff.DEFAULT_SIZE)
    scene = sc.override(sc.Scene(), height=_material_of(args), size=size, depth=args.depth,
                        boundary=args.boundary, elevation=args.elevation, azimuths=args.azimuths, spp=args.spp)
    name = _scene_name(args, scene)
    truth_spp = tradeoff.DEFAULT_TRUTH_SPP if args.truth_spp is None else args.truth_spp
    if truth_spp < 1:
        raise errors.InputError("--truth-spp", f"must be at least 1, got {truth_spp}")
    backend.variant(args.variant)
    hm = sc.load_material_height(scene.material)
    points, info = tradeoff.measure(scene, hm.height, truth_spp=truth_spp, only=args.only,
                                    progress=not args.quiet)
    if not points:
        raise errors.InputError("--only", "no setting matches")
    out = args.out or Path("reports") / f"tradeoff-{name}"
    command = "hzval " + " ".join(shlex.quote(a) for a in (args.argv or []))
    material = {"name": name, "source": hm.source, "digest": hm.digest, "depth": scene.material.depth,
                "boundary": scene.material.boundary}
    index = tradeoff.write_tradeoff(out, points, info, material=material, command=command)
    print(tradeoff.table(points))
    rec = tradeoff.recommend(points)
    if rec:
        print(f"\nrecommended: {rec['setting']} (|F-V| {rec['visibility_mae']:.4f}; "
              f"best {rec['best']} {rec['best_visibility_mae']:.4f})")
        if "horizon_map" in rec:
            h = rec["horizon_map"]
            default = "" if rec["default"] is None else \
                f"; default {rec['default']} {rec['default_visibility_mae']:.4f}"
            print(f"for the {technique.get(technique.PRIMARY).label}'s own settings: {h['setting']} "
                  f"(|F-V| {h['visibility_mae']:.4f}{default})")
    print(f"report: {index}")
    return errors.EXIT_OK


def cmd_export_scene(args) -> int:
    from hzval import backend, export, scene as sc

    base = sc.load_scene(args.scene) if args.scene else sc.Scene()
    scene = sc.override(base, height=_material_of(args), size=args.size, depth=args.depth,
                        boundary=args.boundary, elevation=args.elevation, effects=args.effects, spp=args.spp,
                        shading=args.shading)
    if not math.isfinite(args.azimuth):
        raise errors.InputError("--azimuth", f"must be a finite number of degrees, got {args.azimuth}")
    backend.variant(args.variant)
    hm = sc.load_material_height(scene.material)
    written = export.write_scene(scene, hm.height, args.out, azimuth_deg=args.azimuth)
    print(f"wrote {', '.join(str(p) for p in written)}; render it with: mitsuba {args.out / 'scene.xml'} "
          f"-o {args.out / 'mitsuba.exr'}")
    return errors.EXIT_OK


def cmd_score(args) -> int:
    import shlex

    from hzval import backend, score

    backend.variant(args.variant)
    result, maps = score.score(args.frames, args.against)
    out = args.out or args.frames / "score"
    command = "hzval " + " ".join(shlex.quote(a) for a in (args.argv or []))
    index = score.write(result, maps, out, command=command)
    print("azimuth     FLIP   dE2000    RMSE  PSNR dB  floor FLIP")
    for f in result["frames"]:
        floor = (f.get("floor") or {}).get("flip_mean")
        psnr = "inf" if f["psnr_db"] is None else f"{f['psnr_db']:.2f}"
        print(f"{f['azimuth_deg']:+7g}  {f['flip_mean']:.4f}  {f['delta_e2000_mean']:7.3f}  {f['rmse']:.4f}  "
              f"{psnr:>7}  {'-' if floor is None else f'{floor:.4f}':>10}")
    print(f"report: {index}")
    return errors.EXIT_OK


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
    argv = list(sys.argv[1:] if argv is None else argv)
    args = _parser().parse_args(_join_negative_values(argv))
    args.argv = argv
    try:
        return args.run(args)
    except errors.HzvalError as exc:
        print(f"hzval: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print("hzval: interrupted", file=sys.stderr)
        return 130
