"""What accuracy costs: settings of the bake, the approximation and the truth, measured on one material.

:func:`measure` renders a converged ground truth once for the scene's sweep
(:mod:`hzval.truth` at ``truth_spp`` samples per pixel), then measures every
setting of :func:`settings` against it, each with

``time_s``
    what the setting costs in time: for a bake setting (``kind = "bake"``)
    the bake (normal and horizon maps, in process, kernels warm, best of
    two; in the kernel form :func:`hzval.bake.kernel_for` chooses, which
    for a large radius is the looped one, fast to compile and slower to
    run: ``params["kernel"]``); for an approximation or technique setting
    (``"approx"``, ``"technique"``) a frame's render, mean over the sweep,
    best of three sweeps (a bake setting's frame time is
    ``params["frame_s"]``); for a truth setting (``"truth"``) a frame of the
    truth at that many shadow rays, mean over the sweep.
``storage_bytes``
    the texture memory the setting needs at run time: the horizon map
    (channels x texels x 1 byte for 8-bit storage, 4 for float; 8 channels,
    or 16 for the "16 directions" bake settings), plus the
    weight cube map (6 faces x 16 x 16 texels x 2 RGBA layers, 8-bit) where
    it is sampled; the height map alone (16-bit) for the terrain technique;
    the displaced mesh (a float32 vertex and two triangles of uint32 indices
    per texel, margin excluded) for the truth.
``visibility_mae``
    mean over the sweep of the mean ``|F - V|`` against the converged
    truth's visibility ``V`` (for truth settings: ``|V_n - V|``).
``flip_mean``
    mean over the sweep of the mean FLIP error of the image against the
    converged truth's image (display values, :func:`hzval.compare.flip`).

and marks the Pareto front (no other setting of the same kind is at least
as good in time, storage and visibility error and better in one) within each
kind, since a bake's seconds and a frame's milliseconds do not trade against
each other. Every setting but the one it varies is the default
(:class:`hzval.bake.BakeParams`, ``k = 8``, float storage, analytic
weights); the approximation samples each pixel at the scene's ``spp``
positions, the converged truth at ``truth_spp`` others.

``k`` is also fitted: the ``k`` that minimises ``visibility_mae`` over the
sweep (a golden-section search on ``log k`` in [1, 128]), i.e. the k whose
ramp ``F = clamp(k (Lz - s) + 1, 0, 1)`` best matches the truth's
penumbrae.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hzval import compare, files

__all__ = ["Point", "Setting", "settings", "measure", "mark_pareto", "recommend", "write_tradeoff",
           "DEFAULT_TRUTH_SPP", "DEFAULT_SIZE"]

#: Samples per pixel of the converged truth everything is measured against.
DEFAULT_TRUTH_SPP = 256
#: Size of the built-in material for a tradeoff (FLIP and 256 spp make 512 slow).
DEFAULT_SIZE = 256
KINDS = ("bake", "approx", "technique", "truth")


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

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)

    @property
    def label(self) -> str:
        """The name, with what this run found out about the setting (``params["note"]``)."""
        note = self.params.get("note")
        return f"{self.name} ({note})" if note else self.name


@dataclass(frozen=True)
class Setting:
    """A setting to measure: its name, kind, and the parameters it changes from the defaults."""

    name: str
    kind: str
    bake: dict = field(default_factory=dict)        # BakeParams fields
    approx: dict = field(default_factory=dict)      # Approximation keywords (k, storage, weights)
    truth_spp: int | None = None
    technique: str | None = None
    fit_k: bool = False


def _available_bake_methods() -> set[str]:
    from hzval.bake import BakeParams
    from hzval.errors import InputError

    out = set()
    for m in ("seed", "exact"):
        try:
            BakeParams(method=m).validate()
            out.add(m)
        except InputError:
            pass
    return out


def _has_terrain() -> bool:
    try:
        import hzval.terrain  # noqa: F401
        return True
    except ImportError:
        return False


def settings() -> list[Setting]:
    """Every setting :func:`measure` measures, defaults first."""
    s = [Setting("seed r16, 32 bins (default)", "bake", {"radius": 16, "angles": 32})]
    s += [Setting(f"seed r{r}", "bake", {"radius": r}) for r in (4, 8, 32, 64)]
    if "exact" in _available_bake_methods():
        s.append(Setting("exact, unlimited radius", "bake", {"method": "exact"}))
    s += [Setting(f"seed r16, {a} bins", "bake", {"angles": a}) for a in (16, 64)]
    # 16 stored directions (22.5 degrees apart) against the seed's 8: twice
    # the texture memory (4 RGBA layers); each channel averages angles/16 + 1 bins
    s += [Setting(f"seed r16, {a} bins, 16 directions", "bake", {"angles": a, "directions": 16}) for a in (32, 64)]
    s += [Setting("8-bit horizon map", "approx", approx={"storage": "u8"}),
          Setting("cube-map weights", "approx", approx={"weights": "cube"}),
          Setting("GPU path: 8-bit map + cube weights", "approx", approx={"storage": "u8", "weights": "cube"})]
    s += [Setting(f"k = {k:g}", "approx", approx={"k": float(k)}) for k in (2, 4, 16, 32)]
    s.append(Setting("k fitted to the truth", "approx", fit_k=True))
    if _has_terrain():
        s.append(Setting("terrain shadow map (Raudins)", "technique", technique="terrain"))
    s += [Setting(f"truth, {n} shadow ray{'s' if n > 1 else ''} per pixel", "truth", truth_spp=n)
          for n in (1, 4, 16, 64)]
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


def _reference(scene, height, truth_spp: int) -> _Reference:
    from hzval import scene as sc, truth

    t0 = time.perf_counter()
    conv = dataclasses.replace(scene, spp=int(truth_spp), seed=scene.seed + 1)
    tr = truth.Truth(conv, height)
    scale = compare.exposure(scene)
    vis, disp = [], []
    for az in scene.light.azimuths_deg:
        f = tr.render(az)
        vis.append(f.layers["visibility"])
        disp.append(compare.display(f.image, scale))
    rows, cols = height.shape
    return _Reference(scene, height, sc.load_albedo(scene.material, rows, cols), vis, disp, scale,
                      time.perf_counter() - t0)


def _errors(ref: _Reference, frames) -> tuple[float, float]:
    mae, flip = [], []
    for f, V, d in zip(frames, ref.visibility, ref.display):
        F = f.layers.get("factor", f.layers.get("visibility"))
        mae.append(float(np.mean(np.abs(np.asarray(F, np.float64) - V))))
        flip.append(compare.flip(d, compare.display(f.image, ref.scale))[1])
    return float(np.mean(mae)), float(np.mean(flip))


def _render_all(renderer, azimuths, repeat: int = 3, **kw):
    """The sweep's frames and a frame's time: the mean over the sweep, the best of ``repeat`` sweeps
    (settings that share a kernel differ by about 10% from one sweep to the next otherwise)."""
    renderer.render(azimuths[0], **kw)       # compile (or load) the kernels: time warm frames only
    frames = [renderer.render(az, **kw) for az in azimuths]
    best = float(np.mean([f.seconds for f in frames]))
    for _ in range(repeat - 1):
        best = min(best, float(np.mean([renderer.render(az, **kw).seconds for az in azimuths])))
    return frames, best


def _horizon_bytes(bk, storage: str) -> int:
    rows, cols, ch = bk.horizon.shape
    return rows * cols * ch * (1 if storage == "u8" else 4)


CUBE_BYTES = 6 * 16 * 16 * 4 * 2


def _timed_bake(height, params):
    from hzval import bake

    bake.bake(height, params)                       # compile (or load) the kernels
    best = None
    for _ in range(2):
        bk = bake.bake(height, params)
        t = bk.timings.get("normal_s", 0.0) + bk.timings.get("horizon_s", 0.0)
        best = t if best is None else min(best, t)
    return bk, best


def fit_k(ref: _Reference, bk, lo: float = 1.0, hi: float = 128.0, iterations: int = 14) -> float:
    """The ``k`` minimising the sweep's mean ``|F - V|`` (golden-section search on ``log k``)."""
    from hzval import approx

    ap = approx.Approximation(ref.scene, bk, ref.albedo, path="exact")

    def cost(logk: float) -> float:
        k = math.exp(logk)
        return float(np.mean([np.mean(np.abs(ap.render(az, k=k).layers["factor"] - V))
                              for az, V in zip(ref.scene.light.azimuths_deg, ref.visibility)]))

    g = (math.sqrt(5) - 1) / 2
    a, b = math.log(lo), math.log(hi)
    c, d = b - g * (b - a), a + g * (b - a)
    fc, fd = cost(c), cost(d)
    for _ in range(iterations):
        if fc <= fd:
            b, d, fd = d, c, fc
            c = b - g * (b - a)
            fc = cost(c)
        else:
            a, c, fc = c, d, fd
            d = a + g * (b - a)
            fd = cost(d)
    return math.exp((a + b) / 2)


def measure(scene, height: np.ndarray, *, truth_spp: int = DEFAULT_TRUTH_SPP, only: list[str] | None = None,
            progress: bool = False) -> tuple[list[Point], dict]:
    """Measure every setting of :func:`settings` (or those whose names contain one of ``only``)."""
    from tqdm import tqdm

    from hzval import approx, bake, truth

    ref = _reference(scene, height, truth_spp)
    base = bake.BakeParams(depth=scene.material.depth, boundary=scene.material.boundary)
    az = scene.light.azimuths_deg
    todo = [s for s in settings() if not only or any(o in s.name for o in only)]
    bakes: dict = {}
    points = []
    rows, cols = height.shape
    for s in tqdm(todo, desc="tradeoff", unit="setting", disable=not progress, leave=False):
        params = dataclasses.replace(base, **s.bake)
        key = dataclasses.astuple(params)
        if key not in bakes:
            bakes[key] = _timed_bake(height, params)
        bk, bake_s = bakes[key]
        p = {"bake": dataclasses.asdict(params)}
        if params.method == "seed" and s.kind == "bake":
            # a large radius may take the looped kernel (hzval.bake.choose_kernel): say so
            p["kernel"] = bake.kernel_for(rows, cols, params.radius, params.angles)
            if p["kernel"] != "unrolled":
                p["note"] = f"{p['kernel']}ed kernel, chosen for a fast first bake"
        if s.kind == "truth":
            tr = truth.Truth(dataclasses.replace(scene, spp=s.truth_spp, seed=scene.seed + 2), height)
            frames, t = _render_all(tr, az, repeat=1)     # seconds a frame: timing noise is small here
            storage = rows * cols * (12 + 24)
            p = {"spp": s.truth_spp}
        elif s.kind == "technique":
            from hzval import terrain

            tech = terrain.TerrainShadow(scene, height, bake=bk, albedo=ref.albedo)
            frames, t = _render_all(tech, az)
            storage = rows * cols * 2
            p = {"technique": s.technique}
        else:
            kw = dict(s.approx)
            if s.fit_k:
                kw["k"] = fit_k(ref, bk)
            ap = approx.Approximation(scene, bk, ref.albedo, path="exact", **kw)
            frames, frame_s = _render_all(ap, az)
            t = bake_s if s.kind == "bake" else frame_s
            storage = _horizon_bytes(bk, ap.storage) + (CUBE_BYTES if ap.weights == "cube" else 0)
            p.update(k=ap.k, storage=ap.storage, weights=ap.weights, frame_s=frame_s)
            if s.fit_k:
                p["note"] = f"k = {ap.k:.3g}"
        mae, flip = _errors(ref, frames)
        points.append(Point(s.name, s.kind, float(t), int(storage), mae, flip, params=p))
    mark_pareto(points)
    info = {"truth_spp": truth_spp, "truth_s": ref.seconds, "rows": rows, "cols": cols,
            "azimuths_deg": list(az), "elevation_deg": scene.light.elevation_deg, "spp": scene.spp,
            "effects": list(scene.effects)}
    return points, info


def mark_pareto(points: list[Point]) -> None:
    """Set ``pareto`` on the points no other point of the same kind dominates in
    (time_s, storage_bytes, visibility_mae)."""
    for p in points:
        obj = (p.time_s, p.storage_bytes, p.visibility_mae)
        p.pareto = not any(
            q is not p and q.kind == p.kind
            and all(a <= b for a, b in zip((q.time_s, q.storage_bytes, q.visibility_mae), obj))
            and any(a < b for a, b in zip((q.time_s, q.storage_bytes, q.visibility_mae), obj))
            for q in points)


def _pick(cand: list[Point], tolerance: float) -> tuple[Point, Point]:
    """``(pick, best)``: the least storage, then time, within ``tolerance`` of the best."""
    best = min(cand, key=lambda p: p.visibility_mae)
    limit = best.visibility_mae * (1 + tolerance) + 1e-4
    good = [p for p in cand if p.visibility_mae <= limit]
    return min(good, key=lambda p: (p.storage_bytes, p.time_s, p.visibility_mae)), best


def recommend(points: list[Point], tolerance: float = 0.1) -> dict:
    """The setting to use: among the approximation's settings (bake, approx, technique), the one
    of least storage, then least time, whose visibility error is within ``tolerance`` (relative)
    of the best; the same among the horizon map's own settings (bake and approx), under
    ``horizon_map``, since another technique (terrain shadows) has another cost, a sweep per
    light; and the fewest truth rays whose own error is below a tenth of the best."""
    cand = [p for p in points if p.kind != "truth"]
    if not cand:
        return {}
    pick, best = _pick(cand, tolerance)
    default = next((p for p in points if "(default)" in p.name), None)
    out = {"setting": pick.name, "visibility_mae": pick.visibility_mae, "best": best.name,
           "best_visibility_mae": best.visibility_mae, "tolerance": tolerance,
           "default": default.name if default else None,
           "default_visibility_mae": default.visibility_mae if default else None}
    horizon = [p for p in cand if p.kind in ("bake", "approx")]
    if horizon and pick not in horizon:
        hpick, hbest = _pick(horizon, tolerance)
        out["horizon_map"] = {"setting": hpick.name, "visibility_mae": hpick.visibility_mae,
                              "best": hbest.name, "best_visibility_mae": hbest.visibility_mae}
    truths = sorted((p for p in points if p.kind == "truth"), key=lambda p: p.params.get("spp", 0))
    enough = next((p for p in truths if p.visibility_mae <= best.visibility_mae / 10), None)
    if enough:
        out["truth"] = enough.name
    return out


# --------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------

def plot_tradeoff(path: Path, points: list[Point]) -> None:
    """Time against visibility error, one panel per kind; marker area ~ storage; Pareto front ringed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import EngFormatter, LogLocator, MaxNLocator, NullFormatter

    kinds = [k for k in KINDS if any(p.kind == k for p in points)]
    fig, axes = plt.subplots(1, len(kinds), figsize=(4.6 * len(kinds), 4.2), squeeze=False)
    labels = {"bake": "bake time (s)", "approx": "frame time (s)", "technique": "frame time (s)",
              "truth": "truth frame time (s)"}
    smax = max(p.storage_bytes for p in points) or 1
    for ax, kind in zip(axes[0], kinds):
        pts = [p for p in points if p.kind == kind]
        for p in pts:
            area = 30 + 270 * p.storage_bytes / smax
            ax.scatter(p.time_s, p.visibility_mae, s=area, alpha=0.75,
                       color="#d62728" if p.pareto else "#1f77b4", edgecolors="black", linewidths=0.5)
            ax.annotate(p.label, (p.time_s, p.visibility_mae), fontsize=7, xytext=(4, 4),
                        textcoords="offset points")
        front = sorted((p for p in pts if p.pareto), key=lambda p: p.time_s)
        if len(front) > 1:
            ax.plot([p.time_s for p in front], [p.visibility_mae for p in front], color="#d62728", lw=1)
        times = [p.time_s for p in pts if p.time_s > 0]
        if times and max(times) > 10 * min(times):
            # decades only, in engineering units: finer log ticks crowd the axis
            ax.set_xscale("log")
            ax.xaxis.set_major_locator(LogLocator(numticks=6))
            ax.xaxis.set_minor_formatter(NullFormatter())
        else:
            ax.xaxis.set_major_locator(MaxNLocator(4))
        ax.xaxis.set_major_formatter(EngFormatter(unit="s", places=None, sep=" "))
        ax.set_xlabel(labels[kind])
        ax.set_ylabel("visibility mean |F - V|")
        ax.set_title(kind)
        ax.grid(True, alpha=0.3)
    fig.suptitle("what accuracy costs: red = Pareto front of its kind; marker area ~ texture memory",
                 fontsize=10)
    fig.tight_layout()
    with files.atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)


def write_tradeoff(out: str | Path, points: list[Point], info: dict, *, material: dict, command: str) -> Path:
    """``out/tradeoff.json``, ``out/pareto.png`` and ``out/index.html``; returns the index path."""
    from hzval import backend, report

    out = Path(out)
    rec = recommend(points)
    data = {"material": material, "measurement": info, "recommendation": rec,
            "versions": backend.versions(), "command": command,
            "points": [{k: v for k, v in p.as_dict().items()
                        if k in ("name", "kind", "time_s", "storage_bytes", "visibility_mae", "flip_mean",
                                 "pareto", "params")} for p in points]}
    plot_tradeoff(out / "pareto.png", points)
    files.write_json(out / "tradeoff.json", data)
    html = report._environment().get_template("tradeoff.html.j2").render(
        points=points, rec=rec, info=info, material=material, command=command, versions=data["versions"])
    index = out / "index.html"
    with files.atomic_path(index) as tmp:
        tmp.write_text(html, encoding="utf-8")
    return index


def table(points: list[Point]) -> str:
    """The points as a plain-text table for the terminal."""
    head = ("setting", "kind", "time", "storage", "|F-V|", "FLIP", "pareto")
    rows = [(p.label, p.kind, _fmt_s(p.time_s), _fmt_bytes(p.storage_bytes), f"{p.visibility_mae:.4f}",
             f"{p.flip_mean:.4f}", "*" if p.pareto else "") for p in points]
    w = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(head)]
    line = lambda c: "  ".join(x.ljust(w[0]) if i == 0 else x.rjust(w[i]) for i, x in enumerate(c))  # noqa: E731
    return "\n".join([line(head), line(["-" * x for x in w]), *map(line, rows)])


def _fmt_s(s: float) -> str:
    return f"{s * 1000:.1f} ms" if s < 1 else f"{s:.2f} s"


def _fmt_bytes(n: int) -> str:
    for unit, size in (("MiB", 2**20), ("KiB", 2**10)):
        if n >= size:
            return f"{n / size:.1f} {unit}"
    return f"{n} B"
