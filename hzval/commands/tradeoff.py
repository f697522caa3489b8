"""What accuracy costs: settings of the bake, the techniques and the truth, measured on one material.

:func:`measure` renders a converged ground truth once for the scene's sweep
(:mod:`hzval.truth.plane` at ``truth_spp`` samples per pixel), then measures every
setting of :func:`settings` against it, each with

The design in full: docs/internals.md, "hzval.commands.tradeoff".
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from tqdm import tqdm

from hzval.bake import horizon as bake_horizon
from hzval.bake import maps as bake
from hzval.core import backend, shading
from hzval.core import conventions as cv
from hzval.io import atomic, documents, staging
from hzval.metrics import compare
from hzval.metrics import facing as hzfacing
from hzval.pipeline import renders
from hzval.report import columns, figures, plots, ranking
from hzval.report import pages as report
from hzval.scene import spec as sc
from hzval.scene.spec import Scene
from hzval.techniques import registry as technique
from hzval.truth import memory
from hzval.truth import plane as truth

__all__ = [
    "Point",
    "Setting",
    "settings",
    "measure",
    "mark_pareto",
    "recommend",
    "write_tradeoff",
    "DEFAULT_TRUTH_SPP",
    "DEFAULT_SIZE",
]

#: Samples per pixel of the converged truth everything is measured against.
DEFAULT_TRUTH_SPP = 256
#: Size of the built-in material for a tradeoff (FLIP and 256 spp make 512 slow).
DEFAULT_SIZE = 256
KINDS = ("bake", "technique", "truth")


@dataclass
class Point:
    """One measured setting (a row of ``tradeoff.json``)."""

    name: str
    kind: str
    time_s: float
    storage_bytes: int
    visibility_mae: float
    flip_mean: float
    pareto: bool = False
    params: dict = field(default_factory=dict)
    visibility_mae_facing: float | None = None

    def as_dict(self) -> dict:
        """Return the point as a JSON object."""
        return dataclasses.asdict(self)

    @property
    def error(self) -> float:
        """The headline ``|F - V|``: over the pixels facing the light, where measured."""
        return self.visibility_mae if self.visibility_mae_facing is None else self.visibility_mae_facing

    @property
    def label(self) -> str:
        """The name, with what this run found out about the setting (``params["note"]``)."""
        note = self.params.get("note")
        return f"{self.name} ({note})" if note else self.name


@dataclass(frozen=True)
class Setting:
    """A setting to measure: its name, kind, and what it changes from the defaults.

    ``bake``: :class:`hzval.bake.maps.BakeParams` fields; ``technique``: the
    registry name of the technique it renders (``None``: the truth);
    ``settings``: that technique's build keywords (a
    :class:`hzval.techniques.registry.Variant`'s); ``params``: what the point records.
    """

    name: str
    kind: str
    bake: dict = field(default_factory=dict)
    technique: str | None = None
    settings: dict = field(default_factory=dict)
    params: dict = field(default_factory=dict)
    truth_spp: int | None = None


def baked_technique(scene=None) -> str | None:
    """Return the technique the bake settings are rendered with.

    It is the first in the registry that reads the horizon bake
    (:meth:`hzval.techniques.registry.Technique.bake_needs`) and applies to ``scene``.
    """
    sc_ = scene if scene is not None else Scene()
    return next(
        (
            n
            for n in technique.names()
            if "horizon_map" in technique.get(n).bake_needs(sc_)
            and (scene is None or technique.get(n).applies(scene))
        ),
        None,
    )


def settings(scene=None, *, fits: bool = False) -> list[Setting]:
    """Return every setting :func:`measure` measures, defaults first.

    They are the bake's (rendered with :func:`baked_technique`), every technique's own from the registry
    (those that apply to ``scene``, when given; a technique that fits another's textures, ``NAME-fit``, only
    with ``fits``: each of its settings is a fit), and the truth's ray counts.
    """
    s: list[Setting] = []
    baked = baked_technique(scene)
    if baked is not None:
        s.append(
            Setting("seed r16, 32 bins (default)", "bake", {"radius": 16, "angles": 32}, technique=baked)
        )
        s += [Setting(f"seed r{r}", "bake", {"radius": r}, technique=baked) for r in (4, 8, 32, 64)]
        s.append(Setting("exact, unlimited radius", "bake", {"method": "exact"}, technique=baked))
        s += [Setting(f"seed r16, {a} bins", "bake", {"angles": a}, technique=baked) for a in (16, 64)]
        # 16 stored directions (22.5 degrees apart) against the seed's 8: twice
        # the texture memory (4 RGBA layers); each channel averages angles/16 + 1 bins
        s += [
            Setting(
                f"seed r16, {a} bins, 16 directions", "bake", {"angles": a, "directions": 16}, technique=baked
            )
            for a in (32, 64)
        ]
    for name in technique.names():
        t = technique.get(name)
        if (scene is not None and not t.applies(scene)) or (t.fit_of and not fits):
            continue
        s += [
            Setting(
                v.name,
                "technique",
                technique=name,
                settings=dict(v.settings),
                params={"technique": name, **v.params},
            )
            for v in t.tradeoff_variants()
        ]
    s += [
        Setting(
            f"truth, {n} shadow ray{'s' if n > 1 else ''} per pixel", "truth", technique=None, truth_spp=n
        )
        for n in (1, 4, 16, 64)
    ]
    return s


# --------------------------------------------------------------------------
# Measuring
# --------------------------------------------------------------------------


@dataclass
class _Reference:
    scene: object
    height: np.ndarray
    albedo: np.ndarray
    visibility: list[np.ndarray]
    display: list[np.ndarray]
    scale: float
    seconds: float
    facing: list = field(default_factory=list)  # per light: the pixels facing it (top view), or None


def _reference(scene, height, truth_spp: int) -> _Reference:
    t0 = time.perf_counter()
    conv = dataclasses.replace(scene, spp=int(truth_spp), seed=scene.seed + 1)
    tr = truth.Truth(conv, height)
    scale = shading.exposure(scene)
    vis, disp = [], []
    for el, az in renders.lights(scene):
        f = _render(tr, el, az)
        vis.append(f.layers["visibility"])
        disp.append(compare.display(f.image, scale))
    rows, cols = height.shape
    facing = [None] * len(vis)
    if scene.camera.kind == "top":  # as the sweep measures: the normal map's texels that face each light
        normal = cv.normal_map(cv.heights_in_texels(height, scene.material.depth), scene.material.boundary)
        facing = [
            hzfacing.facing_mask(normal, scene.light.direction(az, el), scene.camera.supersampling)
            for el, az in renders.lights(scene)
        ]
    return _Reference(
        scene,
        height,
        sc.load_albedo(scene.material, rows, cols),
        vis,
        disp,
        scale,
        time.perf_counter() - t0,
        facing,
    )


def _errors(ref: _Reference, frames) -> tuple[float, float, float | None]:
    """``(|F - V| over the image, FLIP, |F - V| over the facing pixels or None)``, means over the sweep."""
    mae, flip, facing = [], [], []
    for f, V, d, mask in zip(frames, ref.visibility, ref.display, ref.facing):
        F = np.asarray(f.layers.get("factor", f.layers.get("visibility")), np.float64)
        mae.append(float(np.mean(np.abs(F - V))))
        flip.append(compare.flip(d, compare.display(f.image, ref.scale))[1])
        if mask is not None:
            facing.append(hzfacing.facing_metrics(V, F, mask)["visibility_mae_facing"])
    measured = [v for v in facing if v is not None]
    return float(np.mean(mae)), float(np.mean(flip)), (float(np.mean(measured)) if measured else None)


def _render(renderer, el: float | None, az: float, **kw):
    """Render one light's frame of a truth or a technique.

    A truth is lit from ``el`` first (:meth:`hzval.truth.plane.Truth.light_at`); ``el`` ``None``: the scene's
    one elevation.
    """
    if el is None:
        return renderer.render(az, **kw)
    if hasattr(renderer, "light_at"):
        renderer.light_at(el)
        return renderer.render(az, **kw)
    return renderer.render(az, elevation_deg=el, **kw)


def _render_all(renderer, lights, repeat: int = 3, **kw):
    """Return the sweep's frames and a frame's time.

    ``lights`` are :func:`hzval.pipeline.renders.lights`'s. The time is the mean over the sweep, the best of
    ``repeat`` sweeps (settings that share a kernel differ by about 10% from one sweep to the next otherwise).
    """
    _render(renderer, *lights[0], **kw)  # compile (or load) the kernels: time warm frames only
    frames = [_render(renderer, el, az, **kw) for el, az in lights]
    best = float(np.mean([f.seconds for f in frames]))
    for _ in range(repeat - 1):
        best = min(best, float(np.mean([_render(renderer, el, az, **kw).seconds for el, az in lights])))
    return frames, best


def _timed_bake(height, params):
    bake.bake(height, params)  # compile (or load) the kernels
    best = None
    for _ in range(2):
        bk = bake.bake(height, params)
        t = bk.timings.get("normal_s", 0.0) + bk.timings.get("horizon_s", 0.0)
        best = t if best is None else min(best, t)
    return bk, best


def check_fits(scene, truth_spp: int = DEFAULT_TRUTH_SPP) -> int:
    """Refuse a tradeoff that would not fit in memory, before the map is generated or decoded.

    The test is the sweep's estimate (:func:`hzval.truth.memory.check_fits`) at the converged truth's
    ``truth_spp``, the most samples it holds. Returns the estimate in bytes.
    """
    spp = max(int(scene.spp), int(truth_spp))
    return memory.check_fits(
        dataclasses.replace(scene, spp=spp),
        bake.BakeParams(depth=scene.material.depth, boundary=scene.material.boundary),
    )


def measure(
    scene,
    height: np.ndarray,
    *,
    truth_spp: int = DEFAULT_TRUTH_SPP,
    only: list[str] | None = None,
    fits: bool = False,
    progress: bool = False,
) -> tuple[list[Point], dict]:
    """Measure every setting of :func:`settings`, or those whose names contain one of ``only``.

    With ``fits``, the fitted techniques' settings too.
    """
    ref = _reference(scene, height, truth_spp)
    base = bake.BakeParams(depth=scene.material.depth, boundary=scene.material.boundary)
    todo = [s for s in settings(scene, fits=fits) if not only or any(o in s.name for o in only)]
    bakes: dict = {}
    points = []
    for s in tqdm(todo, desc="tradeoff", unit="setting", disable=not progress, leave=False):
        params = dataclasses.replace(base, **s.bake)
        key = dataclasses.astuple(params)
        if key not in bakes:
            bakes[key] = _timed_bake(height, params)
        points.append(_measure_one(s, ref, *bakes[key], params))
    mark_pareto(points)
    rows, cols = height.shape
    info = {
        "truth_spp": truth_spp,
        "truth_s": ref.seconds,
        "rows": rows,
        "cols": cols,
        "azimuths_deg": list(scene.light.azimuths_deg),
        "elevation_deg": scene.light.elevation_deg,
        "elevations_deg": list(scene.light.elevations()),
        "spp": scene.spp,
        "effects": list(scene.effects),
    }
    return points, info


def _measure_one(s: Setting, ref: _Reference, bk, bake_s: float, params) -> Point:
    """One setting's point: its time (a bake's for bake settings, else a frame's), storage and errors."""
    scene, height, lights = ref.scene, ref.height, renders.lights(ref.scene)
    rows, cols = height.shape
    if s.kind == "truth":
        tr = truth.Truth(dataclasses.replace(scene, spp=s.truth_spp, seed=scene.seed + 2), height)
        frames, t = _render_all(tr, lights, repeat=1)  # seconds a frame: timing noise is small here
        mae, flip, facing = _errors(ref, frames)
        return Point(
            s.name,
            s.kind,
            float(t),
            rows * cols * (12 + 24),
            mae,
            flip,
            params={"spp": s.truth_spp},
            visibility_mae_facing=facing,
        )
    cls = technique.get(s.technique)
    ctx = technique.Context(scene, height, bk, ref.albedo)
    # a setting fitted to the truth (horizon's k = "fit") is fitted at the scene's own (lowest) elevation
    low = [(V, az) for V, (el, az) in zip(ref.visibility, lights) if el in (None, scene.light.elevation_deg)]
    kw = cls.fit(ctx, dict(s.settings), [V for V, _ in low], [az for _, az in low])
    tech = cls.build(ctx, **kw)
    frames, frame_s = _render_all(tech, lights)
    p = {
        **s.params,
        **{k: v for k, v in tech.parameters.items() if k != "simulated"},
        "frame_s": frame_s,
        "bake": dataclasses.asdict(params),
        **({"technique": s.technique} if s.technique else {}),
    }
    if s.kind == "bake" and params.method == "seed":
        # a large radius may take the looped kernel (hzval.bake.horizon.choose_kernel): say so
        p["kernel"] = bake_horizon.kernel_for(rows, cols, params.radius, params.angles)
        if p["kernel"] != "unrolled":
            p["note"] = f"{p['kernel']}ed kernel, chosen for a fast first bake"
    if kw != s.settings:
        p["note"] = ", ".join(f"{k} = {v:.3g}" for k, v in kw.items() if s.settings.get(k) != v)
    mae, flip, facing = _errors(ref, frames)
    return Point(
        s.name,
        s.kind,
        float(bake_s if s.kind == "bake" else frame_s),
        int(tech.storage_bytes()),
        mae,
        flip,
        params=p,
        visibility_mae_facing=facing,
    )


def mark_pareto(points: list[Point]) -> None:
    """Set ``pareto`` on the points no other point of the same kind dominates.

    Dominance is in (time_s, storage_bytes, the headline |F - V|: :attr:`Point.error`).
    """
    for p in points:
        obj = (p.time_s, p.storage_bytes, p.error)
        p.pareto = not any(
            q is not p
            and q.kind == p.kind
            and all(a <= b for a, b in zip((q.time_s, q.storage_bytes, q.error), obj))
            and any(a < b for a, b in zip((q.time_s, q.storage_bytes, q.error), obj))
            for q in points
        )


def _pick(cand: list[Point], tolerance: float) -> tuple[Point, Point]:
    """``(pick, best)``: the least storage, then time, within ``tolerance`` of the best."""
    best = min(cand, key=lambda p: p.error)
    limit = best.error * (1 + tolerance) + 1e-4
    good = [p for p in cand if p.error <= limit]
    return min(good, key=lambda p: (p.storage_bytes, p.time_s, p.error)), best


#: What a recommendation's ``error`` is, by whether the points have facing pixels (the top view).
ERROR_IS = {
    True: "mean |F - V| over the pixels that face the light",
    False: "mean |F - V| over the whole image (a view other than top has no facing mask)",
}


def recommend(points: list[Point], tolerance: float = 0.1) -> dict:
    """Return the setting to use among the techniques' settings, and the fewest truth rays to use.

    Among the techniques' settings (bake and technique) it is the one of least storage, then least time, whose
    visibility error is within ``tolerance`` (relative) of the best; the same among the settings of the
    technique whose bake is varied (its bake and its own) is given under ``own`` with that technique's name,
    since another technique (terrain shadows) has another cost, a sweep per light. For the truth it is the
    fewest rays whose own error is below a tenth of the best.
    """
    cand = [p for p in points if p.kind != "truth"]
    if not cand:
        return {}
    pick, best = _pick(cand, tolerance)
    default = next((p for p in points if "(default)" in p.name), None)
    out = {
        "setting": pick.name,
        "error": pick.error,
        "error_is": ERROR_IS[pick.visibility_mae_facing is not None],
        "best": best.name,
        "best_error": best.error,
        "tolerance": tolerance,
        "default": default.name if default else None,
        "default_error": default.error if default else None,
    }
    baked = next((p.params.get("technique") for p in cand if p.kind == "bake"), None)
    own = [p for p in cand if p.kind == "bake" or p.params.get("technique", "") == baked]
    if own and pick not in own:
        hpick, hbest = _pick(own, tolerance)
        out["own"] = {
            "technique": baked,
            "setting": hpick.name,
            "error": hpick.error,
            "best": hbest.name,
            "best_error": hbest.error,
        }
    truths = sorted((p for p in points if p.kind == "truth"), key=lambda p: p.params.get("spp", 0))
    enough = next((p for p in truths if p.error <= best.error / 10), None)
    if enough:
        out["truth"] = enough.name
    return out


# --------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------


def write_tradeoff(
    out: str | Path, points: list[Point], info: dict, *, material: dict, command: str, force: bool = False
) -> Path:
    """``out/tradeoff.json``, ``out/pareto.png`` and ``out/index.html``; returns the index path.

    The folder is held while they are written (:func:`hzval.io.staging.output_folder`, ``force`` as there).
    """
    out = Path(out)
    with staging.output_folder(out, force=force):
        return _write_tradeoff(out, points, info, material, staging.portable_command(command))


def _write_tradeoff(out: Path, points: list[Point], info: dict, material: dict, command: str) -> Path:

    rec = recommend(points)
    texels = info["rows"] * info["cols"]
    data = {
        "error_per_byte": error_per_byte(points, texels),
        "floors": floors(points),
        "material": material,
        "measurement": info,
        "recommendation": rec,
        "versions": backend.versions(),
        "command": command,
        "points": [
            {
                k: v
                for k, v in p.as_dict().items()
                if k
                in (
                    "name",
                    "kind",
                    "time_s",
                    "storage_bytes",
                    "visibility_mae",
                    "visibility_mae_facing",
                    "flip_mean",
                    "pareto",
                    "params",
                )
            }
            for p in points
        ],
    }
    figures.plot_tradeoff(out / "pareto.png", points, KINDS)
    per_byte = _plot_error_per_byte(out / "error_per_byte.png", data["error_per_byte"], info)
    documents.write_json(out / "tradeoff.json", data)
    html = (
        report.environment()
        .get_template("tradeoff.html.j2")
        .render(
            points=points,
            rec=rec,
            info=info,
            material=material,
            command=command,
            versions=data["versions"],
            per_byte=per_byte,
            floors=floor_lines(points),
        )
    )
    index = out / "index.html"
    with atomic.atomic_path(index) as tmp:
        tmp.write_text(html, encoding="utf-8")
    return index


def error_per_byte(points: list[Point], texels: int) -> list[dict]:
    """Return the techniques' settings as error against bytes per texel.

    Each is marked on the front of least bytes and least error (:func:`hzval.report.ranking.pareto`). This is
    ``tradeoff.json``'s ``error_per_byte``.

    Parameters
    ----------
    points : list of Point
        The measured settings (those of kind ``technique`` are kept).
    texels : int
        The material's texels.

    Returns
    -------
    list of dict
        ``name``, ``technique``, ``fitted`` (a ``NAME-fit``'s setting), ``storage``,
        ``bytes_per_texel``, ``error`` (:attr:`Point.error`) and ``pareto``.
    """
    kept = [p for p in points if p.kind == "technique"]
    out = [
        {
            "name": p.name,
            "technique": p.params.get("technique"),
            "fitted": bool(technique.get(p.params["technique"]).fit_of)
            if p.params.get("technique")
            else False,
            "storage": p.params.get("storage"),
            "bytes_per_texel": p.storage_bytes / texels,
            "error": p.error,
        }
        for p in kept
    ]
    for row, front in zip(out, ranking.pareto([(r["bytes_per_texel"], r["error"]) for r in out])):
        row["pareto"] = front
    return out


def _plot_error_per_byte(path: Path, rows: list[dict], info: dict) -> str | None:
    """Plot :func:`error_per_byte` as the report draws it, a panel for the sweep's lights.

    The drawing is :func:`hzval.report.plots.plot_error_per_byte`'s. Returns its file name, or ``None`` with
    no technique setting.
    """
    if not rows:
        return None
    names = list(dict.fromkeys(r["technique"] for r in rows))
    views = columns.technique_views({"techniques": {n: {"label": technique.get(n).label} for n in names}})
    points = [
        {
            **r,
            "label": technique.get(r["technique"]).label,
            "fit_of": technique.get(r["technique"]).fit_of,
            "name": r["technique"],
        }
        for r in rows
    ]
    elevations = ", ".join(f"{e:g}" for e in info["elevations_deg"])
    plots.plot_error_per_byte(path, {info["elevation_deg"]: points}, views, title=f"lights at {elevations}°")
    return path.name


def floors(points: list[Point]) -> list[dict]:
    """Return each fitted setting beside the shipped one of the same storage.

    Each row has ``technique``, ``storage``, ``shipped`` and ``floor`` (:attr:`Point.error`) and ``bake_loss``
    (shipped minus floor). This is ``tradeoff.json``'s ``floors``.

    Parameters
    ----------
    points : list of Point
        The measured settings.

    Returns
    -------
    list of dict
    """
    shipped = {
        (p.params.get("technique"), repr(p.params.get("storage"))): p for p in points if p.kind == "technique"
    }
    out = []
    for p in points:
        name = p.params.get("technique")
        of = technique.get(name).fit_of if name else None
        base = shipped.get((of, repr(p.params.get("storage")))) if of else None
        if base is not None:
            out.append(
                {
                    "technique": of,
                    "storage": p.params.get("storage"),
                    "shipped": base.error,
                    "floor": p.error,
                    "bake_loss": base.error - p.error,
                }
            )
    return out


def floor_lines(points: list[Point]) -> list[str]:
    """:func:`floors` for the terminal, a line each."""
    return [
        f"{f['technique']} ({', '.join(f'{t} {s}' for t, s in (f['storage'] or {}).items())}): shipped "
        f"{f['shipped']:.4f} = bake loss {f['bake_loss']:.4f} + floor {f['floor']:.4f}"
        for f in floors(points)
    ]


def table(points: list[Point]) -> str:
    """Return the points as a plain-text table for the terminal."""
    head = ("setting", "kind", "time", "storage", "|F-V|", "FLIP", "pareto")
    rows = [
        (
            p.label,
            p.kind,
            _fmt_s(p.time_s),
            _fmt_bytes(p.storage_bytes),
            f"{p.error:.4f}",
            f"{p.flip_mean:.4f}",
            "*" if p.pareto else "",
        )
        for p in points
    ]
    w = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(head)]

    def line(c):
        return "  ".join(x.ljust(w[0]) if i == 0 else x.rjust(w[i]) for i, x in enumerate(c))

    return "\n".join([line(head), line(["-" * x for x in w]), *map(line, rows)])


def _fmt_s(s: float) -> str:
    return f"{s * 1000:.1f} ms" if s < 1 else f"{s:.2f} s"


def _fmt_bytes(n: int) -> str:
    for unit, size in (("MiB", 2**20), ("KiB", 2**10)):
        if n >= size:
            return f"{n / size:.1f} {unit}"
    return f"{n} B"
