"""Agreement of ``horizon --path gpu`` (Dr.Jit emulation) with ``horizon-gl`` (the shipped GLSL on OpenGL).

Bakes a height map (a built-in material or an image file; ``--size`` resamples a
built-in one), builds both techniques from one :class:`hzval.techniques.registry.Context`,
so that they read the same sample positions, and prints per light the mean and
max of ``|F_gpu - F_gl|`` per pixel, and the GL renderer (``--pom``: ``pom`` against ``pom-gl``).
Lights: the default sweep's azimuths at the scene's elevation plus the ``--extra`` ``AZ/EL`` pairs
(default the cube's corner, 45/35.26). ``--texel-centres`` reads one sample at
each texel centre instead of the sweep's jittered ones. Exits 1 when a bound
given with ``--max-mean`` / ``--max-max`` is exceeded.

Usage::

    GALLIVM_PERF=no_aos_sampling .venv/bin/python studies/gl_agreement.py --height photo.png --boundary wrap
    .venv/bin/python studies/gl_agreement.py --height photo.png --camera orthographic --view-elevation 90 \\
        --resolution 128 128 --filter trilinear --spp 4
"""

from __future__ import annotations

import argparse
import sys

import numpy as np


def _scene(args):
    from hzval.scene import spec as sc

    base = sc.Scene()
    scene = sc.override(
        base,
        height=args.height,
        size=args.size,
        boundary=args.boundary,
        depth=args.depth,
        effects="shadow",
        spp=args.spp,
        elevation=args.elevation,
        camera=args.camera,
        view_elevation=args.view_elevation,
        resolution=tuple(args.resolution) if args.resolution else None,
        filter=args.filter,
    )
    return scene.validate()


def _context(scene, texel_centres: bool):
    from hzval.bake import maps as bake
    from hzval.scene import lookup
    from hzval.scene import spec as sc
    from hzval.techniques import registry as technique

    hm = sc.load_material_height(scene.material)
    params = bake.BakeParams(depth=scene.material.depth, boundary=scene.material.boundary).validate()
    baked = bake.bake(hm.height, params)
    rows, cols = hm.height.shape
    points = None
    if texel_centres:
        r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
        like = lookup.Samples(np.zeros(1, np.float32), np.zeros(1, np.float32), rows, cols, 1)
        points = lookup.from_points((c + 0.5).ravel(), (rows - r - 0.5).ravel(), like, "texel centres")
        scene = sc.override(scene, spp=1)
    return technique.Context(
        scene, hm.height, baked, sc.load_albedo(scene.material, rows, cols), points=points
    )


def _from_sweep(args) -> int:
    """Per frame of a sweep's output folder: |F| of horizon's factor EXR against horizon-gl's."""
    import json
    from pathlib import Path

    from hzval.io import codecs

    out = Path(args.from_sweep)
    m = json.loads((out / "metrics.json").read_text())
    print(
        f"{out}: horizon {m['techniques']['horizon']['parameters']['path']} path against horizon-gl on "
        f"{m['techniques']['horizon-gl']['parameters']['gl']['renderer']}"
    )
    worst_mean = worst_max = 0.0
    for f in m["frames"]:
        a = codecs.read_exr(out / f["techniques"]["horizon"]["files"]["factor"])["Y"].astype(np.float64)
        b = codecs.read_exr(out / f["techniques"]["horizon-gl"]["files"]["factor"])["Y"].astype(np.float64)
        d = np.abs(a - b)
        worst_mean, worst_max = max(worst_mean, d.mean()), max(worst_max, d.max())
        print(
            f"  az {f['azimuth_deg']:7.2f} el {f['elevation_deg']:6.2f}: "
            f"mean |dF| {d.mean():.2e}  max {d.max():.2e}"
        )
    print(f"worst: mean {worst_mean:.2e}, max {worst_max:.2e}")
    bad = (args.max_mean is not None and worst_mean > args.max_mean) or (
        args.max_max is not None and worst_max > args.max_max
    )
    return 1 if bad else 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--height", default="bricks", help="a built-in material or an image file (default bricks)"
    )
    ap.add_argument("--size", type=int, default=None)
    ap.add_argument("--boundary", default=None, choices=("wrap", "open"))
    ap.add_argument("--depth", type=float, default=None)
    ap.add_argument("--elevation", type=float, default=None)
    ap.add_argument("--spp", type=int, default=4)
    ap.add_argument("--camera", default=None)
    ap.add_argument("--view-elevation", type=float, default=None)
    ap.add_argument("--resolution", type=int, nargs=2, default=None, metavar=("W", "H"))
    ap.add_argument("--filter", default=None)
    ap.add_argument("--storage", default="u8")
    ap.add_argument("--texel-centres", action="store_true")
    ap.add_argument("--extra", nargs="*", default=["45/35.26"], metavar="AZ/EL")
    ap.add_argument(
        "--pom",
        default=None,
        choices=("hard", "soft"),
        help="compare pom with pom-gl (this variant, 32 steps) instead of the horizon map",
    )
    ap.add_argument(
        "--from-sweep",
        default=None,
        metavar="OUT",
        help="compare the factor EXRs of a finished `hzval sweep --techniques horizon,horizon-gl` in OUT",
    )
    ap.add_argument("--max-mean", type=float, default=None)
    ap.add_argument("--max-max", type=float, default=None)
    args = ap.parse_args(argv)

    if args.from_sweep:
        return _from_sweep(args)
    from hzval.techniques.gl.horizon_gl import HorizonGL
    from hzval.techniques.horizon import Horizon

    scene = _scene(args)
    ctx = _context(scene, args.texel_centres)
    scene = ctx.scene
    if args.pom:
        from hzval.techniques.gl.horizon_gl import PomGL
        from hzval.techniques.pom import RayMarchShadow

        emu, real = RayMarchShadow.build(ctx, variant=args.pom), PomGL.build(ctx, variant=args.pom)
    else:
        emu = Horizon.build(ctx, path="gpu", storage=args.storage)
        real = HorizonGL.build(ctx, storage=args.storage)
    print(
        f"{scene.material.height} {ctx.height.shape[1]}x{ctx.height.shape[0]} {scene.material.boundary}, "
        f"{scene.camera.kind}, filter {scene.lookup.filter}, {scene.spp} spp, storage {args.storage}; "
        f"{real.gl['renderer']} ({real.gl['version']}), GALLIVM_PERF={real.gl.get('gallivm_perf', '')}"
    )
    lights = [(a, scene.light.elevation_deg) for a in scene.light.azimuths_deg]
    lights += [tuple(float(v) for v in e.split("/")) for e in args.extra]
    worst_mean = worst_max = 0.0
    for az, el in lights:
        a = emu.render(az, elevation_deg=el).layers["factor"]
        b = real.factor(az, el)
        d = np.abs(a.astype(np.float64) - b)
        worst_mean, worst_max = max(worst_mean, d.mean()), max(worst_max, d.max())
        print(
            f"  az {az:7.2f} el {el:6.2f}: mean |dF| {d.mean():.2e}  max {d.max():.2e}  "
            f"> 0.01: {100 * np.mean(d > 0.01):.2f}%"
        )
    print(f"worst: mean {worst_mean:.2e}, max {worst_max:.2e}")
    bad = (args.max_mean is not None and worst_mean > args.max_mean) or (
        args.max_max is not None and worst_max > args.max_max
    )
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
