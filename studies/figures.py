"""The figures of README.md and docs/: each reruns what it shows and rewrites its table in place.

A figure is a function that runs hzval (a sweep, a benchmark) and returns a
markdown block; in a document it stands between ``<!-- figure:NAME -->`` and
``<!-- /figure:NAME -->``, and the block says the command that made it, the
commit and the machine. Figures that take minutes are run only when named.

    .venv/bin/python studies/figures.py                  # every quick figure, every document
    .venv/bin/python studies/figures.py default-sweep    # one figure
    .venv/bin/python studies/figures.py --check          # exit 1 if a document has a figure no
                                                            # function makes, or lacks its end marker
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCUMENTS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
HZVAL = [sys.executable, "-m", "hzval"]


def _commit() -> str:
    try:
        out = subprocess.run(
            ["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "-C", str(ROOT), "status", "--porcelain", "--", "hzval"], capture_output=True, text=True
        ).stdout.strip()
        return out + (" + uncommitted changes" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def _machine() -> str:
    return f"{platform.system()} {platform.machine()}, {os.cpu_count()} cores"


def _sweep(*argv: str) -> dict:
    """``hzval sweep ARGV`` into a fresh folder; its metrics.json."""
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run(
            [*HZVAL, "sweep", *argv, "--quiet", "--out", tmp], check=True, cwd=ROOT, stdout=subprocess.DEVNULL
        )
        return json.loads((Path(tmp) / "metrics.json").read_text())


def _spread(values: list[float], digits: int = 3) -> str:
    vals = [v for v in values if v is not None]
    if not vals:
        return "—"
    mean = sum(vals) / len(vals)
    return f"{mean:.{digits}f} ({min(vals):.{digits}f}-{max(vals):.{digits}f})"


def _provenance(command: str) -> str:
    return f"*`{command}` at {_commit()}, {_machine()}; written by `studies/figures.py`.*"


def default_sweep() -> str:
    """README's headline table: every technique on the default sweep, and the perfect-shadows floor."""
    from hzval.report import ranking

    m = _sweep()
    frames = m["frames"]
    rows = [
        "| technique | mean \\|F - V\\| over the pixels facing the light (range over the sweep) "
        "| mean FLIP (range) | frame time |",
        "|---|---|---|---|",
    ]
    for name, info in m["techniques"].items():
        per = [f["techniques"][name] for f in frames]
        ms = 1000 * sum(t["seconds"] for t in per) / len(per)
        rows.append(
            f"| `{name}`: {info['label']} | {_spread([ranking.visibility_of(t) for t in per])} | "
            f"{_spread([t['flip_mean'] for t in per])} | {ms:.0f} ms |"
        )
    none = [f["no_shadows"] for f in frames if "no_shadows" in f]
    none_mae = _spread([ranking.visibility_of(n) for n in none])
    rows.append(
        f"| no shadows (F = 1: the unshadowed shading) | {none_mae} | "
        f"{_spread([n['flip_mean'] for n in none])} | — |"
    )
    floor = [f["floor"]["flip_mean"] for f in frames if "floor" in f]
    rows.append(
        f"| perfect shadows (the floor: unshadowed shading times the truth's V) | 0 | {_spread(floor)} | — |"
    )
    p = m["parameters"]
    what = (
        f"{m['material']['name']}, {m['material']['cols']} x {m['material']['rows']}, depth {p['depth']:g}, "
        f"{p['light']} light at {p['elevation_deg']:g} degrees, azimuths {p['azimuths_deg'][0]:g} to "
        f"{p['azimuths_deg'][-1]:+g}, {p['spp']} spp"
    )
    return "\n".join(rows) + f"\n\n*{what}.* " + _provenance("hzval sweep")


def reflection() -> str:
    """The reflection fade's score on a small sweep (README's sweep section)."""
    argv = ("--size", "128", "--azimuths", "0", "--effects", "shadow,diffuse,reflection_occlusion")
    m = _sweep(*argv)
    r = m["frames"][0]["techniques"]["horizon"]["reflection_mae"]
    return f"`reflection_mae` = {r:.3f}. " + _provenance("hzval sweep " + " ".join(argv))


def pom_steps() -> str:
    """The ray march's error and cost against its step count (benchmarks/bench_pom.py)."""
    out = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "bench_pom.py"), "--frames", "5"],
        capture_output=True,
        text=True,
        check=True,
        cwd=ROOT,
    ).stdout
    table = [line for line in out.splitlines() if not line.startswith("#")]
    return "```\n" + "\n".join(table) + "\n```\n\n" + _provenance("python benchmarks/bench_pom.py --frames 5")


def photo_like(seed: int, slope: float, size: int = 128) -> "np.ndarray":  # noqa: F821
    """A height map with a photograph's power spectrum, ``1 / f^slope`` (natural images and terrain: a
    slope about 2), exactly periodic, in [0, 1]: the engines' figure's stand-in for a photo."""
    import numpy as np

    rng = np.random.default_rng(seed)
    fy, fx = np.fft.fftfreq(size)[:, None], np.fft.rfftfreq(size)[None, :]
    f = np.hypot(fx, fy)
    f[0, 0] = 1.0
    spectrum = (rng.normal(size=f.shape) + 1j * rng.normal(size=f.shape)) / f ** (slope / 2)
    spectrum[0, 0] = 0.0
    h = np.fft.irfft2(spectrum, s=(size, size))
    return ((h - h.min()) / (h.max() - h.min())).astype(np.float32)


#: The engines' figure: every built-in material and two photo-like maps, 128 texels, over elevations.
ENGINE_MAPS = ("bricks", "cobblestones", "fabric", "gravel", "panels", "planks", "ridges", "spikes")
ENGINE_ARGS = ("--size", "128", "--spp", "4", "--elevation", "15:75:15", "--azimuths", "-60:60:30")


def engines() -> str:
    """docs/techniques.md's table: each technique's mean |F - V| at each light elevation over the
    built-in materials and two photo-like maps, and on how many of those maps it is worse than no
    shadows at that elevation."""
    import numpy as np

    from hzval.report import ranking

    runs = {}
    with tempfile.TemporaryDirectory() as tmp:
        for i, slope in enumerate((1.8, 2.4)):
            np.save(Path(tmp) / f"photo-like-{slope:g}.npy", photo_like(7 + i, slope))
        for name in ENGINE_MAPS:
            runs[name] = _sweep("--material", name, *ENGINE_ARGS)
        for path in sorted(Path(tmp).glob("*.npy")):
            runs[path.stem] = _sweep(str(path), *ENGINE_ARGS[2:])
    tables = {m: ranking.by_elevation(r) for m, r in runs.items()}
    names = [*next(iter(runs.values()))["techniques"], ranking.NONE]
    elevations = [r["elevation_deg"] for r in next(iter(tables.values()))[ranking.NONE]]
    head = "| technique | " + " | ".join(f"{e:g}°" for e in elevations) + " |"
    rows = [head, "|---" * (len(elevations) + 1) + "|"]
    for n in names:
        cells = []
        for k, e in enumerate(elevations):
            vals = [t[n][k]["visibility_mae"] for t in tables.values() if n in t]
            worse = sum(e in ranking.worse_than_none(t, n) for t in tables.values())
            mark = "" if n == ranking.NONE else f" ({worse}/{len(tables)})"
            cells.append(f"{np.mean(vals):.3f}{mark}")
        label = "no shadows (F = 1)" if n == ranking.NONE else f"`{n}`"
        rows.append(f"| {label} | " + " | ".join(cells) + " |")
    what = (
        f"mean |F - V| over the pixels facing the light, averaged over {len(tables)} maps ("
        + ", ".join(tables)
        + ") and the azimuths; in brackets, on how many maps the technique is worse than no shadows "
        "at that elevation"
    )
    command = "hzval sweep MAP " + " ".join(ENGINE_ARGS)
    return "\n".join(rows) + f"\n\n*{what}.* " + _provenance(command)


def tradeoff() -> str:
    """docs/GUIDE.md's tradeoff table: every setting `hzval tradeoff` measures on the 256 x 256 bricks,
    |F - V| over the pixels facing the light (the headline), its Pareto front in bold."""
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run(
            [*HZVAL, "tradeoff", "--size", "256", "--quiet", "--out", tmp],
            check=True,
            cwd=ROOT,
            stdout=subprocess.DEVNULL,
        )
        data = json.loads((Path(tmp) / "tradeoff.json").read_text())
    rows = [
        "| setting | kind | time | texture memory | \\|F - V\\| (facing) | FLIP |",
        "|---|---|---|---|---|---|",
    ]
    for p in data["points"]:
        t = p["time_s"]
        time_ = f"{t * 1000:.1f} ms" if t < 1 else f"{t:.2f} s"
        err = p["visibility_mae_facing"] if p["visibility_mae_facing"] is not None else p["visibility_mae"]
        err_ = f"**{err:.4f}**" if p["pareto"] else f"{err:.4f}"
        name = p["name"] + (f" ({p['params']['note']})" if p["params"].get("note") else "")
        rows.append(
            f"| {name} | {p['kind']} | {time_} | {p['storage_bytes'] / 2**20:.1f} MiB | {err_} | "
            f"{p['flip_mean']:.3f} |"
        )
    rec = data["recommendation"]
    said = f"recommended: {rec['setting']} ({rec['error']:.4f}; the best: {rec['best']}"
    said += f", {rec['best_error']:.4f})"
    return (
        "\n".join(rows)
        + f"\n\n*bricks, 256 x 256; {said}; in bold the Pareto front of each kind.* "
        + _provenance("hzval tradeoff --size 256")
    )


#: The gates' figure: the built-in materials at 256 texels, the default lights (30 degrees, -60..60).
GATE_ARGS = ("--size", "256", "--spp", "8")
#: The |F - V| levels the picture strip shows.
LEVELS = (0.01, 0.03, 0.1, 0.2)


def _round_up(x: float) -> str:
    """``x`` rounded up to two significant digits, as a threshold."""
    import math

    if x <= 0:
        return "0"
    step = 10.0 ** (math.floor(math.log10(x)) - 1)
    return f"{math.ceil(x / step - 1e-9) * step:.2g}"


def gates() -> str:
    """docs/ci.md's recommended gates: each technique's sweep mean of |F - V| (facing) and FLIP on every
    built-in material, a threshold a quarter above the largest, and docs/levels.png, what those levels
    look like (truth | technique | visibility difference, from the same runs)."""
    from hzval.report import ranking

    rows_of: dict[str, list] = {}
    picks = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in ENGINE_MAPS:
            out = Path(tmp) / name
            subprocess.run(
                [*HZVAL, "sweep", "--material", name, *GATE_ARGS, "--quiet", "--out", str(out)],
                check=True,
                cwd=ROOT,
                stdout=subprocess.DEVNULL,
            )
            m = json.loads((out / "metrics.json").read_text())
            for t in m["techniques"]:
                per = [f["techniques"][t] for f in m["frames"]]
                vis = [ranking.visibility_of(r) for r in per]
                flip = [r["flip_mean"] for r in per]
                rows_of.setdefault(t, []).append((sum(vis) / len(vis), sum(flip) / len(flip)))
                picks += [(v, r["flip_mean"], name, t, f, out) for v, r, f in zip(vis, per, m["frames"])]
        strip = _level_strip(picks)
    head = [
        "| technique | mean \\|F - V\\| over the built-ins: median (range) | `--fail-if` | "
        "mean FLIP: median (range) | `--fail-if` |",
        "|---|---|---|---|---|",
    ]
    for t, rs in rows_of.items():
        vis, flip = sorted(r[0] for r in rs), sorted(r[1] for r in rs)
        head.append(
            f"| `{t}` | {vis[len(vis) // 2]:.3f} ({vis[0]:.3f}-{vis[-1]:.3f}) | "
            f"`mean({t}.visibility_mae_facing)>{_round_up(1.25 * vis[-1])}` | "
            f"{flip[len(flip) // 2]:.3f} ({flip[0]:.3f}-{flip[-1]:.3f}) | "
            f"`mean({t}.flip_mean)>{_round_up(1.25 * flip[-1])}` |"
        )
    what = (
        f"each technique's sweep means on the {len(ENGINE_MAPS)} built-in materials "
        f"({', '.join(ENGINE_MAPS)}); a threshold a quarter above the worst material's, which every "
        "built-in passes today"
    )
    command = "hzval sweep --material NAME " + " ".join(GATE_ARGS)
    return "\n".join(head) + f"\n\n*{what}.* " + _provenance(command) + "\n\n" + strip


def _level_strip(picks: list) -> str:
    """docs/levels.png: for each of :data:`LEVELS` the frame whose |F - V| is nearest, its truth,
    technique and visibility difference side by side (a 96-pixel crop where the difference is
    largest); the markdown that shows it and says what each column is."""
    import numpy as np
    from PIL import Image

    crop, tiles, said = 96, [], []
    for level in LEVELS:
        v, flip, name, t, frame, out = min(picks, key=lambda p: abs(p[0] - level))
        files = frame["techniques"][t]["files"]
        images = [out / frame["files"]["truth_png"], out / files["png"], out / files["visdiff_png"]]
        arrays = [np.asarray(Image.open(p).convert("RGB")) for p in images]
        diff = arrays[2].astype(np.int32).sum(-1)
        diff = np.abs(diff - np.median(diff))
        h, w = diff.shape
        cs = np.cumsum(np.cumsum(np.pad(diff, ((1, 0), (1, 0))), 0), 1)
        win = cs[crop:, crop:] - cs[:-crop, crop:] - cs[crop:, :-crop] + cs[:-crop, :-crop]
        r, c = np.unravel_index(int(np.argmax(win)), win.shape)
        tiles.append(np.concatenate([a[r : r + crop, c : c + crop] for a in arrays], axis=1))
        said.append(f"{level:g}: {name}, `{t}` at {frame['name']} (|F - V| {v:.3f}, FLIP {flip:.3f})")
    gap = np.full((crop, 8, 3), 255, np.uint8)
    strip = np.concatenate([x for tile in tiles for x in (tile, gap)][:-1], axis=1)
    Image.fromarray(strip).save(ROOT / "docs" / "levels.png", optimize=True)
    return (
        "![What |F - V| levels look like: truth, technique and visibility difference for each level]"
        "(levels.png)\n\n*Left to right, |F - V| near " + "; ".join(said) + ". Each: truth | technique | "
        "visibility difference (leaks and false shadows in two colours), the 96-pixel crop where the "
        "difference is largest.*"
    )


#: name -> (function, quick): quick figures run by default, the others only when named.
#: The floors' figure: four built-in materials and a photo-like map, 128 texels, at elevations off
#: the fits' training grid (10, 20, 40, 60) but 30, the default sweep's.
FLOOR_MAPS = ("bricks", "gravel", "ridges", "panels")
FLOOR_ARGS = ("--size", "128", "--spp", "4", "--elevation", "25,30,50", "--azimuths", "-60:60:30")
FLOOR_TECHNIQUES = ("microshadow-filament", "microshadow-hdrp", "bent-cone", "ssbump")


def floors() -> str:
    """docs/techniques.md's floors: each per-pixel technique shipped and with its textures fitted to
    the truth (NAME-fit), beside no shadows, per elevation, over several maps; and docs/floors.png,
    the error per byte of every technique and storage, shipped and fitted, with its Pareto front."""
    import numpy as np

    from hzval.report import columns, plots, ranking

    wanted = ",".join(n for t in FLOOR_TECHNIQUES for n in (t, f"{t}-fit"))
    storages = (
        ("float", ()),
        ("bc", ("--ao-storage", "bc4", "--bent-normal-storage", "bc5", "--ssbump-storage", "bc1")),
    )
    runs: dict[str, dict] = {}
    with tempfile.TemporaryDirectory() as tmp:
        np.save(Path(tmp) / "photo-like.npy", photo_like(7, 1.8))
        for store, flags in storages:
            for name in (*FLOOR_MAPS, "photo-like"):
                if name == "photo-like":  # a file has its own size
                    source = (str(Path(tmp) / "photo-like.npy"), *FLOOR_ARGS[2:])
                else:
                    source = ("--material", name, *FLOOR_ARGS)
                runs[f"{name}/{store}"] = _sweep(*source, "--techniques", wanted, *flags)
    float_runs = [r for k, r in runs.items() if k.endswith("/float")]
    per = [ranking.floors(r) for r in float_runs]
    tables = [ranking.by_elevation(r) for r in float_runs]
    elevations = [r["elevation_deg"] for r in tables[0][ranking.NONE]]
    rows = [
        "| technique | " + " | ".join(f"{e:g}°: shipped / floor / no shadows" for e in elevations) + " |",
        "|---" * (len(elevations) + 1) + "|",
    ]
    for t in FLOOR_TECHNIQUES:
        cells = []
        for k in range(len(elevations)):
            s, f, n = (np.mean([p[t][k][key] for p in per]) for key in ("shipped", "floor", "none"))
            harm = sum(p[t][k]["harms"] for p in per)
            cells.append(f"{s:.3f} / {f:.3f} / {n:.3f}" + (f" (harms {harm}/{len(per)})" if harm else ""))
        rows.append(f"| `{t}` | " + " | ".join(cells) + " |")
    # error per byte: every technique and storage, shipped and fitted, averaged over the maps
    points: dict[float, list[dict]] = {}
    for store, _ in storages:
        group = [r for k, r in runs.items() if k.endswith(f"/{store}")]
        for e in elevations:
            tabs = [ranking.error_per_byte(r)[e] for r in group]
            for i, p in enumerate(tabs[0]):
                if store != "float" and p["name"] == ranking.NONE:
                    continue
                mean = float(np.mean([tab[i]["error"] for tab in tabs]))
                points.setdefault(e, []).append({**p, "error": mean})
    for pts in points.values():
        for p, front in zip(pts, ranking.pareto([(p["bytes_per_texel"], p["error"]) for p in pts])):
            p["pareto"] = front
    views = columns.technique_views(float_runs[0])
    plots.plot_error_per_byte(ROOT / "docs" / "floors.png", points, views)
    what = (
        f"mean |F - V| over the pixels facing the light, averaged over {len(per)} maps ("
        + ", ".join((*FLOOR_MAPS, "a photo-like map"))
        + ") and the azimuths; the floor is the technique with its textures fitted to the truth on "
        "lights at 10, 20, 40 and 60 degrees (NAME-fit, float storage); in brackets, on how many maps "
        "even the floor is worse than no shadows"
    )
    command = "hzval sweep MAP " + " ".join(FLOOR_ARGS) + " --techniques NAME,NAME-fit,..."
    return (
        "\n".join(rows)
        + f"\n\n*{what}.* "
        + _provenance(command)
        + "\n\n![error per byte](floors.png)\n\n*docs/floors.png: the same runs at float and BC "
        "(BC4 AO, BC5 bent normal, BC1 ssbump) storage; fitted hollow; the dotted steps are the Pareto "
        "front of least bytes and least error.*"
    )


FIGURES = {
    "default-sweep": (default_sweep, True),
    "reflection": (reflection, True),
    "pom-steps": (pom_steps, False),
    "engines": (engines, False),
    "tradeoff": (tradeoff, False),
    "gates": (gates, False),
    "floors": (floors, False),
}


def _pattern(name: str) -> re.Pattern:
    return re.compile(
        rf"(<!-- figure:{re.escape(name)} -->\n)(.*?)(\n<!-- /figure:{re.escape(name)} -->)", re.S
    )


def used_figures(text: str) -> list[str]:
    """The figure names a document marks."""
    return re.findall(r"<!-- figure:([\w-]+) -->", text)


def replace(text: str, name: str, block: str) -> str:
    """``text`` with figure ``name``'s block replaced by ``block``."""
    pattern = _pattern(name)
    if not pattern.search(text):
        raise SystemExit(f"figure {name}: no end marker <!-- /figure:{name} -->")
    return pattern.sub(lambda mt: mt.group(1) + block + mt.group(3), text)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "names", nargs="*", help=f"figures to rerun (default: the quick ones): {', '.join(FIGURES)}"
    )
    ap.add_argument("--check", action="store_true", help="check the documents' markers only")
    args = ap.parse_args(argv)
    docs = {p: p.read_text(encoding="utf-8") for p in DOCUMENTS}
    problems = [
        f"{p.name}: figure {n} is made by no function"
        for p, t in docs.items()
        for n in used_figures(t)
        if n not in FIGURES
    ]
    problems += [
        f"{p.name}: figure {n} has no end marker"
        for p, t in docs.items()
        for n in used_figures(t)
        if n in FIGURES and not _pattern(n).search(t)
    ]
    if args.check or problems:
        print("\n".join(problems) or "every figure marker is known and closed")
        return 1 if problems else 0
    wanted = args.names or [n for n, (_, quick) in FIGURES.items() if quick]
    for name in wanted:
        make, _ = FIGURES[name]
        users = [p for p, t in docs.items() if name in used_figures(t)]
        if not users:
            print(f"figure {name}: no document shows it")
            continue
        block = make()
        for p in users:
            docs[p] = replace(docs[p], name, block)
            p.write_text(docs[p], encoding="utf-8")
        print(f"figure {name}: {', '.join(str(p.relative_to(ROOT)) for p in users)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
