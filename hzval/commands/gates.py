"""Gates that fail a build: ``--fail-if EXPR``, ``--baseline DIR`` and ``--strict``.

The first two are for ``sweep``, ``score`` and ``suite``; ``--strict`` is for ``sweep`` and ``suite``: every
warning about an external horizon map (:mod:`hzval.io.external`) fails the run.

A condition (:func:`parse`) compares a metric of ``metrics.json`` with a number
or with another metric::

The design in full: docs/internals.md, "hzval.commands.gates".
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hzval.commands import check
from hzval.core.errors import InputError
from hzval.io import documents
from hzval.metrics.results import FrameRecord, SweepResult, malformed_techniques

__all__ = [
    "Operand",
    "Condition",
    "parse",
    "evaluate",
    "read_baseline",
    "check_same_settings",
    "baseline_tests",
    "frame_noise",
    "regressions",
    "Gates",
    "check_names",
    "check_shape",
    "DIRECTION",
    "FRAME_METRICS",
    "TECHNIQUE_METRICS",
    "FLOOR_METRICS",
    "TRUTH_METRICS",
    "ALPHA",
    "ABS_TOLERANCE",
    "REL_TOLERANCE",
]

#: The metrics a baseline tests and which way is worse: +1 larger is worse, -1 smaller is worse.
DIRECTION = {
    "visibility_mae": 1,
    "leak_fraction": 1,
    "false_shadow_fraction": 1,
    "flip_mean": 1,
    "rmse": 1,
    "delta_e2000_mean": 1,
    "psnr_db": -1,
    "reflection_mae": 1,
    "perfect_parallax_mae": 1,
    "visibility_mae_facing": 1,
    "leak_fraction_facing": 1,
    "false_shadow_fraction_facing": 1,
}
#: The numbers a condition may name (module docstring), as ``metrics.json`` holds them: a frame's own,
#: a technique's (``frames[i].techniques.NAME``), the floor's and the truth's
#: (a score's frames carry the engine's image scores at their top level too;
#: ``tests/integration/test_audit3.py`` keeps these equal to what a sweep and a score write).
FRAME_METRICS = (
    "truth_s",
    "azimuth_deg",
    "elevation_deg",
    "flip_mean",
    "rmse",
    "psnr_db",
    "delta_e2000_mean",
)
TECHNIQUE_METRICS = (*DIRECTION, "seconds")
FLOOR_METRICS = ("flip_mean", "rmse", "psnr_db", "delta_e2000_mean")
TRUTH_METRICS = (
    "attached_fraction",
    "cast_fraction",
    "partial_fraction",
    "shadowed_fraction",
    "visibility_se",
)
#: The family-wise significance level of a baseline comparison (``hzval check``'s ``fail`` default).
ALPHA = 0.01
#: A change smaller than this is never a regression: ABS_TOLERANCE + REL_TOLERANCE * |baseline mean|.
ABS_TOLERANCE = 1e-5
REL_TOLERANCE = 0.01
#: The parameters of ``metrics.json`` that a baseline must share (the techniques' own may differ).
SAME = (
    "depth",
    "boundary",
    "elevation_deg",
    "elevations_deg",
    "azimuths_deg",
    "light",
    "light_radius_deg",
    "effects",
    "spp",
    "supersampling",
    "truth_tolerance",
    "camera",
)

_OPS = {
    ">": lambda a, b: a > b,
    ">=": lambda a, b: a >= b,
    "<": lambda a, b: a < b,
    "<=": lambda a, b: a <= b,
}
_NAME = r"[A-Za-z_][A-Za-z0-9_-]*(?:\.[A-Za-z_][A-Za-z0-9_]*)?"
_OPERAND = re.compile(
    rf"^\s*(?:(mean|max|min)\(\s*({_NAME})\s*\)|({_NAME})|([-+]?(?:\d++(?:\.\d*+)?+|\.\d++)(?:[eE][-+]?\d++)?+))\s*$"
)
_SPLIT = re.compile(r"(>=|<=|>|<)")
#: The longest ``--fail-if`` expression read; a condition is a line of a CI script, not data.
MAX_EXPRESSION = 400


@dataclass(frozen=True)
class Operand:
    """One side of a condition: a number, or a metric's path with an optional aggregate."""

    number: float | None = None
    path: str | None = None  # "horizon.flip_mean", "floor.flip_mean", "truth_s"
    aggregate: str | None = None  # None (per frame), "mean", "max", "min"

    def text(self) -> str:
        """Return the operand as the condition wrote it."""
        if self.path is None:
            return f"{self.number:g}"
        return f"{self.aggregate}({self.path})" if self.aggregate else self.path


@dataclass(frozen=True)
class Condition:
    """``left OP right`` (:func:`parse`)."""

    text: str
    left: Operand
    op: str
    right: Operand

    @property
    def per_frame(self) -> bool:
        """Return whether the condition is checked frame by frame (an operand names a per-frame score)."""
        return any(o.path is not None and o.aggregate is None for o in (self.left, self.right))


def _operand(text: str, expr: str) -> Operand:
    m = _OPERAND.match(text)
    if not m:
        raise InputError(
            "--fail-if",
            f"{expr!r}: {text.strip()!r} is neither a number nor a metric name "
            "(TECHNIQUE.METRIC, mean(...), max(...))",
        )
    if m.group(4) is not None:
        return Operand(number=float(m.group(4)))
    return Operand(path=m.group(2) or m.group(3), aggregate=m.group(1))


def parse(expr: str) -> Condition:
    """Return a ``--fail-if`` expression as a :class:`Condition` (module docstring).

    Anything else is refused in one line naming ``--fail-if``. Parsing is linear in the text's length
    (possessive quantifiers), and texts over :data:`MAX_EXPRESSION` characters are refused first.
    """
    if len(expr) > MAX_EXPRESSION:
        raise InputError("--fail-if", f"{expr[:40]!r}...: longer than {MAX_EXPRESSION} characters")
    parts = _SPLIT.split(expr)
    if len(parts) != 3:
        raise InputError(
            "--fail-if",
            f"{expr!r}: expected one comparison, e.g. horizon.flip_mean>0.1 (operators {', '.join(_OPS)})",
        )
    left, op, right = _operand(parts[0], expr), parts[1], _operand(parts[2], expr)
    if left.path is None and right.path is None:
        raise InputError(
            "--fail-if", f"{expr!r}: compares two numbers; name a metric, e.g. horizon.flip_mean"
        )
    return Condition(expr.strip(), left, op, right)


def known_names(techniques) -> list[str]:
    """Every name a condition may use in a run of ``techniques`` (:data:`FRAME_METRICS` and the rest)."""
    return [
        *FRAME_METRICS,
        *(f"floor.{k}" for k in FLOOR_METRICS),
        *(f"truth.{k}" for k in TRUTH_METRICS),
        *(f"{t}.{k}" for t in techniques for k in TECHNIQUE_METRICS),
    ]


def check_names(conditions: list[Condition], techniques) -> None:
    """Refuse, before a run, a condition that names no number the run will write.

    That is an unknown metric, or a technique the run does not score (``techniques``: its names). The refusal
    is one line naming ``--fail-if``, with the nearest names.
    """
    known = set(known_names(techniques))
    for cond in conditions:
        for op in (cond.left, cond.right):
            if op.path is None or op.path in known:
                continue
            head, dot, _ = op.path.partition(".")
            near = difflib.get_close_matches(op.path, sorted(known), n=3, cutoff=0.6)
            hint = f"; did you mean {', '.join(near)}?" if near else ""
            what = (
                f"{head} is not a technique of this run ({', '.join(techniques) or 'none'})"
                if dot and head not in ("floor", "truth", *techniques)
                else f"{op.path} is no metric hzval writes"
            )
            raise InputError("--fail-if", f"{cond.text!r}: {what}{hint}")


def _number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def check_shape(data, file) -> dict:
    """Return ``data`` (a ``metrics.json`` read as JSON) when it has the shape a gate reads.

    ``frames`` is a list of objects, each with a numeric ``azimuth_deg`` (and ``elevation_deg`` a number or
    null), its ``techniques``, ``truth`` and ``floor`` objects; ``parameters``, ``material`` and
    ``techniques`` are objects. Otherwise the error is one line naming ``--baseline``, the file and the key.
    """

    def bad(key: str, want: str):
        raise InputError(
            "--baseline", f"{file}: {key} must be {want} (not the metrics.json of a sweep or a score)"
        )

    if not isinstance(data, dict) or not isinstance(data.get("frames"), list):
        bad("frames", "a list")
    for key in ("parameters", "material", "techniques"):
        if data.get(key) is not None and not isinstance(data[key], dict):
            bad(key, "an object")
    for i, f in enumerate(data["frames"]):
        if not isinstance(f, dict):
            bad(f"frames[{i}]", "an object")
        if not _number(f.get("azimuth_deg")) or not math.isfinite(f["azimuth_deg"]):
            bad(f"frames[{i}].azimuth_deg", "a number")
        if f.get("elevation_deg") is not None and not _number(f["elevation_deg"]):
            bad(f"frames[{i}].elevation_deg", "a number or null")
        for key in ("techniques", "truth", "floor"):
            if f.get(key) is not None and not isinstance(f[key], dict):
                bad(f"frames[{i}].{key}", "an object")
        for name in malformed_techniques(f):
            bad(f"frames[{i}].techniques.{name}", "an object")
    return data


def _table(frame: dict, path: str) -> tuple[dict | None, str]:
    """Return the table of ``frame`` that holds ``path``'s value, and its key there."""
    head, _, key = path.partition(".")
    if not key:
        return frame, head
    table = frame.get(head) if head in ("floor", "truth") else FrameRecord(frame).scores(head)
    return (table if isinstance(table, Mapping) else None), key


def _lookup(frame: dict, path: str):
    table, key = _table(frame, path)
    return None if table is None else table.get(key)


def _known(frames: list[dict]) -> list[str]:
    names = set()
    for f in frames:
        names |= {k for k, v in f.items() if isinstance(v, (int, float)) and not isinstance(v, bool)}
        for head in ("floor", "truth"):
            names |= {f"{head}.{k}" for k, v in (f.get(head) or {}).items() if not isinstance(v, dict)}
        for t, per in FrameRecord(f).techniques.items():
            names |= {f"{t}.{k}" for k, v in per.items() if not isinstance(v, (dict, str))}
    return sorted(names)


def _values(frames: list[dict], op: Operand, expr: str) -> list:
    """Per frame the operand's value (``None`` where it has none); an aggregate once for all."""
    if op.path is None:
        return [op.number] * len(frames)
    vals = [_lookup(f, op.path) for f in frames]
    if not any(key in table for table, key in (_table(f, op.path) for f in frames) if table is not None):
        near = difflib.get_close_matches(op.path, _known(frames), n=3, cutoff=0.5)
        hint = f"; did you mean {', '.join(near)}?" if near else ""
        raise InputError("--fail-if", f"{expr!r}: no frame has a value of {op.path}{hint}")
    if op.aggregate is None:
        return vals
    nums = [float(v) for v in vals if isinstance(v, (int, float))]
    if not nums:
        return [None] * len(frames)
    agg = {"mean": np.mean, "max": np.max, "min": np.min}[op.aggregate](nums)
    return [float(agg)] * len(frames)


def _frame_name(f: dict) -> str:
    return f.get("name") or f"az{f['azimuth_deg']:+g}"


def evaluate(cond: Condition, metrics: dict, where: str = "") -> list[str]:
    """Return the failures of ``cond`` on ``metrics.json``'s content.

    There is one line per condition that fails, naming its frames and their values (none: the gate passes).
    """
    frames = metrics.get("frames") or []
    left, right = _values(frames, cond.left, cond.text), _values(frames, cond.right, cond.text)
    test = _OPS[cond.op]
    bad = [
        (f, a, b) for f, a, b in zip(frames, left, right) if a is not None and b is not None and test(a, b)
    ]
    if not bad:
        return []
    prefix = f"{where}: " if where else ""
    if not cond.per_frame:
        _, a, b = bad[0]
        other = "" if cond.right.path is None else f", {cond.right.text()} = {_g(b)}"
        return [f"{prefix}--fail-if {cond.text}: the sweep's {cond.left.text()} = {_g(a)}{other}"]
    listed = ", ".join(
        f"{_frame_name(f)} {_g(a)}" + ("" if cond.right.path is None else f" vs {_g(b)}") for f, a, b in bad
    )
    return [f"{prefix}--fail-if {cond.text}: {len(bad)} of {len(frames)} frames ({listed})"]


def _g(v) -> str:
    return f"{v:.4g}"


# --------------------------------------------------------------------------
# Baselines
# --------------------------------------------------------------------------


def read_baseline(path: str | Path) -> dict:
    """Return the ``metrics.json`` of an earlier run (its folder, or the file).

    A missing or unreadable ``metrics.json`` is refused in one line naming ``--baseline``.
    """
    path = Path(path)
    file = path / "metrics.json" if path.is_dir() else path
    if not file.is_file():
        raise InputError("--baseline", f"{path}: no metrics.json (give the folder of an earlier run)")
    try:
        data = documents.read_json(file)
    except InputError as exc:
        raise InputError("--baseline", str(exc)) from None
    return check_shape(data, file)


def check_same_settings(new: dict, old: dict, where: str) -> None:
    """Refuse a baseline of another material or other scene parameters (:data:`SAME`).

    The refusal is one line naming ``--baseline``; the techniques' own settings may differ.
    """
    a, b = (new.get("material") or {}).get("digest"), (old.get("material") or {}).get("digest")
    if a and b and a != b:
        raise InputError("--baseline", f"{where}: another height map (digest {b[:19]}, this run's {a[:19]})")
    pa, pb = new.get("parameters") or {}, old.get("parameters") or {}
    for key in SAME:
        if key == "elevations_deg" and None in (pa.get(key), pb.get(key)):
            continue  # a run from before the elevation axis: its one elevation_deg is compared
        if pa.get(key) != pb.get(key):
            raise InputError(
                "--baseline",
                f"{where}: another run's settings: {key} {pb.get(key)!r}, this run's "
                f"{pa.get(key)!r} (a baseline must have the same scene)",
            )


def _frames_by_light(metrics: dict) -> dict:
    """Return a run's frames by their light, ``(elevation, azimuth)``.

    A sweep over several elevations has several frames of one azimuth.
    """
    return {
        (round(float(f.get("elevation_deg") or 0.0), 6), round(float(f["azimuth_deg"]), 6)): f
        for f in metrics.get("frames", [])
    }


def _same_truth(new: dict, old: dict) -> bool:
    """Whether both runs rendered the same truth: the same scene (:func:`check_same_settings`) and seed."""
    return (new.get("parameters") or {}).get("seed") == (old.get("parameters") or {}).get("seed")


def _pixels(metrics: dict) -> int:
    m, p = metrics.get("material") or {}, metrics.get("parameters") or {}
    res = (metrics.get("camera") or {}).get("resolution")
    if isinstance(res, list) and len(res) == 2:
        return max(int(res[0]) * int(res[1]), 1)
    s = int(p.get("supersampling") or 1)
    return max(int(m.get("rows") or 1) * int(m.get("cols") or 1) * s * s, 1)


def frame_noise(frame: dict, metric: str, pixels: int) -> float | None:
    """Return the standard error the truth's Monte Carlo noise puts on one frame's ``metric``.

    It comes from the frame's truth statistics (:mod:`hzval.metrics.facing`), as in the module docstring;
    ``None`` if unknown.
    """
    t = frame.get("truth") or {}
    facing = metric.endswith("_facing")
    share = max(1.0 - float(t.get("attached_fraction") or 0.0), 1e-9) if facing else 1.0
    base = metric.removesuffix("_facing")
    if base in ("visibility_mae", "reflection_mae", "perfect_parallax_mae") and "visibility_se" in t:
        return float(t["visibility_se"]) / share
    if base in ("leak_fraction", "false_shadow_fraction") and "partial_fraction" in t:
        return 0.5 * math.sqrt(float(t["partial_fraction"]) / pixels) / share
    return None


def _variance(fn: list[dict], fo: list[dict], metric: str, same: bool, pixels: int):
    """Return ``sum sigma_i^2`` of a test's worsenings (module docstring).

    It is ``None`` when it cannot be estimated (an image metric of runs of different seeds).
    """
    if same:
        return 0.0
    noise = [(frame_noise(a, metric, pixels), frame_noise(b, metric, pixels)) for a, b in zip(fn, fo)]
    if all(na is not None and nb is not None for na, nb in noise):
        return float(sum(na * na + nb * nb for na, nb in noise))
    # an image metric of another seed: the seed moves every frame's samples alike (each frame is read
    # at the same sample positions), so the frames' worsenings share one shift that their scatter
    # cannot see (gravel at 32 x 32, 2 spp, 4 lights: PSNR "regressed" at p 1e-11 on the seed alone)
    return None


def baseline_tests(new: dict, old: dict) -> list[dict]:
    """Return a test of the frames' worsenings per technique and metric of :data:`DIRECTION`.

    The techniques are those in both runs. Each test has the frames' worsenings ``d_i``, ``z = sum d_i /
    sqrt(sum sigma_i^2)`` and its one-sided p-value (module docstring).
    """
    fn, fo = _frames_by_light(new), _frames_by_light(old)
    shared = [az for az in fn if az in fo]
    known = SweepResult.of(old).techniques
    names = [n for n in SweepResult.of(new).techniques if n in known]
    same, pixels = _same_truth(new, old), _pixels(new)
    tests = []
    for name in names:
        for metric, sign in DIRECTION.items():
            rows = [
                (_lookup(fn[az], f"{name}.{metric}"), _lookup(fo[az], f"{name}.{metric}"), az)
                for az in shared
            ]
            rows = [
                (a, b, az) for a, b, az in rows if isinstance(a, (int, float)) and isinstance(b, (int, float))
            ]
            if not rows:
                continue
            d = np.array([sign * (a - b) for a, b, _ in rows], np.float64)
            var = _variance([fn[az] for *_, az in rows], [fo[az] for *_, az in rows], metric, same, pixels)
            base = float(np.mean([b for _, b, _ in rows]))
            test = {
                "technique": name,
                "metric": metric,
                "frames": len(d),
                "baseline": base,
                "new": float(np.mean([a for a, _, _ in rows])),
                "worse_by": float(d.mean()),
                "tau": ABS_TOLERANCE + REL_TOLERANCE * abs(base),
                "same_truth": same,
                "z": None,
                "p": None,
            }
            if var is not None:
                total = float(d.sum())
                z = (
                    total / math.sqrt(var)
                    if var > 0
                    else (math.inf if total > 0 else -math.inf if total < 0 else 0.0)
                )
                # JSON has no infinity: an infinite z (the same truth, any change) is written as null
                test.update(z=z if math.isfinite(z) else None, p=float(check.p_value(z, one_sided=True)))
            tests.append(test)
    return tests


def regressions(tests: list[dict], where: str = "", n_tests: int | None = None) -> list[str]:
    """Return the lines of the tests that are significant regressions at :data:`ALPHA`.

    They are Sidak-corrected over ``n_tests`` (default: these tests).
    """
    level = check.sidak_level(ALPHA, n_tests or len(tests))
    prefix = f"{where}: " if where else ""
    return [
        f"{prefix}--baseline: {t['technique']}.{t['metric']} regressed: mean {_g(t['new'])} against "
        f"{_g(t['baseline'])} over {t['frames']} frames (p {t['p']:.2g} < {level:.2g})"
        for t in tests
        if t["p"] is not None and t["p"] < level and t["worse_by"] > t["tau"]
    ]


# --------------------------------------------------------------------------
# The command line's gates
# --------------------------------------------------------------------------


class Gates:
    """``--fail-if`` conditions and a ``--baseline``, parsed and read before a run.

    :meth:`apply` tests a run's ``metrics.json`` content and records ``gates`` in it (what the report lists).
    """

    def __init__(
        self, conditions: list[str] | None = None, baseline: str | Path | None = None, strict: bool = False
    ):
        self.conditions = [parse(c) for c in conditions or []]
        self.strict = bool(strict)
        self.baseline_path = None if baseline is None else Path(baseline)
        self.baseline = None
        if baseline is not None:
            if not self.baseline_path.is_dir() and not self.baseline_path.is_file():
                raise InputError("--baseline", f"{baseline}: no such folder (an earlier run's --out)")
            if (self.baseline_path / "metrics.json").is_file() or self.baseline_path.is_file():
                self.baseline = read_baseline(baseline)
            elif not (self.baseline_path / "suite.json").is_file():
                raise InputError(
                    "--baseline",
                    f"{baseline}: neither a run's folder (metrics.json) nor a suite's (suite.json)",
                )

    def __bool__(self) -> bool:
        """Return whether any gate is set (a condition, a baseline or ``--strict``)."""
        return bool(self.conditions) or self.baseline_path is not None or self.strict

    def failures(
        self, metrics: dict, baseline: dict | None = None, where: str = "", use_baseline: bool = True
    ) -> tuple[list, list]:
        """Return the failure lines and baseline tests of one run against the conditions and ``baseline``.

        The result is ``(failure lines, baseline tests)``; ``baseline`` defaults to :attr:`baseline` (none
        with ``use_baseline`` false); a baseline of other settings is an InputError.
        """
        out = [line for c in self.conditions for line in evaluate(c, metrics, where)]
        if self.strict:  # every warning about an external bake (hzval.io.external.warnings) fails the run
            prefix = f"{where}: " if where else ""
            out += [
                f"{prefix}--strict: {w}" for w in (metrics.get("external_bake") or {}).get("warnings", [])
            ]
        baseline = (self.baseline if baseline is None else baseline) if use_baseline else None
        if use_baseline and baseline is None and self.baseline_path is not None:
            raise InputError(
                "--baseline", f"{self.baseline_path}: a suite's folder; give a run's folder (metrics.json)"
            )
        tests = []
        if baseline is not None:
            label = f"{self.baseline_path}" + (f" ({where})" if where else "")
            check_same_settings(metrics, baseline, label)
            tests = baseline_tests(metrics, baseline)
            if not tests:
                raise InputError(
                    "--baseline",
                    f"{label}: no technique and metric in common with this run (another "
                    f"hzval's metrics.json, or other techniques: "
                    f"{', '.join(SweepResult.of(baseline).techniques) or 'none'})",
                )
            out += regressions(tests, where)
        return out, tests

    def check_before(self, techniques, parameters: dict | None = None) -> "Gates":
        """Return these gates once every condition names a number a run of ``techniques`` writes.

        The conditions are checked by :func:`check_names`, and the baseline must have the ``parameters`` of
        the run to come (the ``metrics.json`` ``parameters`` it will write, where known). It is called before
        anything renders.
        """
        check_names(self.conditions, list(techniques))
        if self.baseline is not None and parameters is not None:
            check_same_settings({"parameters": parameters}, self.baseline, str(self.baseline_path))
        return self

    def apply(self, metrics: dict) -> dict:
        """Test ``metrics`` (one sweep's or score's), store ``metrics["gates"]`` and return it.

        ``metrics["gates"]`` is ``{failed, conditions, baseline, tests}``, and ``errors``, one line each,
        where they could not be evaluated (a baseline of another height map): the run's report is kept either
        way.
        """
        try:
            failed, tests = self.failures(metrics)
        except InputError as exc:
            metrics["gates"] = {**self.record([], []), "errors": [str(exc)]}
        else:
            metrics["gates"] = self.record(failed, tests)
        return metrics["gates"]

    def record(self, failed: list[str], tests: list[dict]) -> dict:
        """Return what ``metrics.json`` records of the gates: the failures, the conditions and the tests."""
        return {
            "failed": failed,
            "conditions": [c.text for c in self.conditions],
            "strict": self.strict,
            "baseline": None if self.baseline_path is None else str(self.baseline_path),
            "alpha": ALPHA,
            "tests": tests,
        }
