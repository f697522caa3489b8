"""Each tangent bug's |F - V| on models with mirrored UVs, on their mirrored and unmirrored pixels
(:mod:`hzval.studies.bug_signatures`: the cube from azimuth 150, the mirrored sphere from +x; the scene's
lights turned to the camera's side). docs/models.md and docs/meshes.md quote its output.

    PYTHONPATH=. python studies/tangent_bugs.py [HEIGHT ...] [--size 128] [--spp 2] [--resolution 128]

HEIGHT: built-in materials or image files (default: bricks spikes).
"""

import argparse
import time

from hzval.scene import spec as sc
from hzval.studies import bug_signatures


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("heights", nargs="*", default=["bricks", "spikes"])
    ap.add_argument("--size", type=int, default=128, help="a built-in material's size")
    ap.add_argument("--spp", type=int, default=2)
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument(
        "--azimuths", default=None, help="the lights before they are turned (default the sweep's)"
    )
    a = ap.parse_args()
    print(
        f"{'height':16s} {'case':16s} {'bug':18s} {'mirrored':>9s} {'unmirrored':>10s} {'ratio':>6s} "
        f"{'perfect':>8s} {'ratio':>6s}  mirrored per light"
    )
    for height in a.heights:
        is_file = "." in height
        scn = sc.override(
            sc.Scene(),
            height=height,
            size=None if is_file else a.size,
            spp=a.spp,
            camera="orthographic",
            resolution=(a.resolution, a.resolution),
            azimuths=a.azimuths,
        )
        h = sc.load_material_height(scn.material).height
        for case, (shape, az, light_az, uv_scale) in bug_signatures.CASES.items():
            t0 = time.perf_counter()
            rec, _ = bug_signatures.measure(scn, h, "horizon", shape, az, light_az, uv_scale)
            for bug, r in rec["bugs"].items():

                def fmt(v, k=4):
                    return "-" if v is None else f"{v:.{k}f}"

                print(
                    f"{height[-16:]:16s} {case:16s} {bug:18s} {fmt(r['mirrored']):>9s} "
                    f"{fmt(r['unmirrored']):>10s} "
                    f"{fmt(r['mirrored_ratio'], 2):>6s} {fmt(r['mirrored_perfect_parallax']):>8s} "
                    f"{fmt(r['mirrored_perfect_parallax_ratio'], 2):>6s}  "
                    + " ".join(fmt(v, 3) for v in r["mirrored_per_light"])
                )
            print(
                f"# {case}: lights {rec['azimuths_deg'][0]:g}..{rec['azimuths_deg'][-1]:g} at "
                f"{rec['elevation_deg']:g} deg, {rec['mirrored_pixels']} mirrored / "
                f"{rec['unmirrored_pixels']} "
                f"unmirrored pixels, {time.perf_counter() - t0:.1f} s"
            )


if __name__ == "__main__":
    main()
