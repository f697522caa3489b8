"""Your own horizon map: read an external bake, convert it to hzval's layout, and detect its convention.

An engine's baker stores the horizon in its own way. :class:`Encoding` says
how; :func:`load` reads the layers (8- or 16-bit PNG, or EXR, RGBA each),
decodes them and returns the sines in hzval's layout (channel ``k`` of ``D``
toward azimuth ``360 k / D`` counterclockwise, +y up the image,
docs/ARCHITECTURE.md "Conventions"), which the ``horizon`` technique then
shades with in place of hzval's own bake (``hzval sweep --horizon-map``).

The design in full: docs/internals.md, "hzval.io.external".
"""

from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image

from hzval.core import conventions as cv
from hzval.core import errors, strict
from hzval.core.errors import InputError
from hzval.io import codecs, documents, ktx2

__all__ = [
    "Encoding",
    "VALUES",
    "CLEARLY_BETTER",
    "DESCRIBES_CORRELATION",
    "load",
    "read_layers",
    "to_hzval",
    "rings",
    "detect",
    "correlation",
    "advice",
    "warnings",
    "repeated_layers",
]

#: The value encodings a channel may hold (module docstring).
VALUES: tuple[str, ...] = ("sine", "cosine", "angle", "tangent", "sqrt")


@dataclass(frozen=True)
class Encoding:
    """How an external horizon map is stored (module docstring, "Encoding")."""

    channels: int = cv.CHANNEL_COUNT
    azimuth0: float = 0.0
    direction: str = "ccw"
    y: str = "up"
    values: str = "sine"

    def validate(self, what: str = "--horizon-map") -> "Encoding":
        """Return this encoding if each field has its type and range, else raise one line naming ``what``."""
        for f, hint in strict.schema_of(Encoding).items():  # types checked, not coerced
            strict.check_value(getattr(self, f), hint, what, f)
        if self.channels not in cv.DIRECTION_COUNTS:
            raise InputError(what, f"channels must be one of {cv.DIRECTION_COUNTS}, got {self.channels}")
        if self.direction not in ("ccw", "cw"):
            raise InputError(what, f"direction must be ccw or cw, got {self.direction!r}")
        if self.y not in ("up", "down"):
            raise InputError(what, f"y must be up or down, got {self.y!r}")
        if self.values not in VALUES:
            raise InputError(what, f"values must be one of {', '.join(VALUES)}, got {self.values!r}")
        if not math.isfinite(float(self.azimuth0)):
            raise InputError(what, f"azimuth0 must be a finite number of degrees, got {self.azimuth0}")
        return self

    def record(self) -> dict:
        """Return the encoding as a JSON object."""
        return dataclasses.asdict(self)

    def describe(self) -> str:
        """Return the encoding in words, for the terminal."""
        return (
            f"{self.channels} channels, channel 0 at {self.azimuth0:g} degrees, {self.direction}, "
            f"+y {self.y}, {self.values}"
        )

    @classmethod
    def from_toml(cls, path: str | Path) -> "Encoding":
        """Read an encoding from a TOML file, refusing unknown keys in one line naming ``path``."""
        data = documents.read_toml(path)
        if not isinstance(data, dict):
            raise InputError(path, "is not a table of encoding keys")

        table = data.get("encoding", data) if set(data) <= {"encoding"} else data
        strict.check_keys(table, strict.schema_of(cls), path, "encoding" if "encoding" in data else "")
        return cls(**table).validate(str(path))


def read_layers(paths: list[str | Path]) -> np.ndarray:
    """Return the layers' RGBA values in [0, 1] concatenated, ``(rows, cols, 4 * len(paths))`` float32.

    One file given twice is refused (it would stand for two layers' directions).
    """
    seen: dict = {}
    for i, p in enumerate(paths):
        try:
            key = os.stat(p)
        except OSError:
            continue  # a missing layer is named below
        key = (key.st_dev, key.st_ino)
        if key in seen:
            raise InputError(
                p,
                f"is given twice to --horizon-map (layers {seen[key]} and {i}): each layer holds "
                "other directions",
            )
        seen[key] = i
    out = []
    for p in paths:
        p = Path(p)
        if p.suffix.lower() == ".ktx2":  # hzval export-textures' layers: level 0, as a GPU decodes it
            tex = ktx2.read(p)
            if tex.format.channels != 4:
                raise InputError(
                    p, f"a horizon layer must be RGBA (4 channels), got a KTX2 of VK_FORMAT_{tex.format.name}"
                )
            out.append(ktx2.decode_level(tex, 0))
            continue
        if p.suffix.lower() == ".exr":
            ch = codecs.read_exr(p)
            if not all(c in ch for c in "RGBA"):
                raise InputError(
                    p, f"a horizon layer needs R, G, B and A channels, has {', '.join(sorted(ch))}"
                )
            out.append(np.stack([ch[c] for c in "RGBA"], axis=-1))
            continue
        try:
            with Image.open(p) as im:
                if im.mode not in ("RGBA", "RGBa", "RGBA;16B"):  # nothing converted: 4 channels or none
                    raise InputError(
                        p,
                        f"a horizon layer must be an RGBA image (4 channels), got a PNG of "
                        f"mode {im.mode} ({len(im.getbands())} channel(s))",
                    )
                arr = np.asarray(im)
        except FileNotFoundError:
            raise InputError(p, "no such horizon layer") from None
        except OSError as exc:
            raise InputError(p, f"not a readable image ({errors.first_line(exc)})") from None
        scale = 65535.0 if arr.dtype == np.uint16 else 255.0
        if arr.ndim != 3 or arr.shape[-1] != 4:
            raise InputError(p, f"a horizon layer must be RGBA, got shape {arr.shape}")
        out.append(arr.astype(np.float32) / np.float32(scale))
    shapes = {a.shape[:2] for a in out}
    if len(shapes) != 1:
        raise InputError(paths[0], f"the layers differ in size: {sorted(shapes)}")
    return np.concatenate(out, axis=-1)


#: What a channel may hold under each value encoding (module docstring, "Encoding"): the sine, the
#: angle over 90 degrees and the signed square root of the sine lie in [-1, 1], the cosine of an
#: elevation in [0, 1]; a tangent may be any finite number.
VALUE_RANGES: dict[str, tuple[float, float]] = {
    "sine": (-1.0, 1.0),
    "cosine": (0.0, 1.0),
    "angle": (-1.0, 1.0),
    "tangent": (-np.inf, np.inf),
    "sqrt": (-1.0, 1.0),
}


def check_layers(raw: np.ndarray, enc: Encoding, paths) -> np.ndarray:
    """Check that ``raw`` holds the layers ``enc`` declares, with finite values in the encoding's range.

    ``raw`` comes from :func:`read_layers`; the layers are ``channels / 4`` RGBA layers, no more, no fewer,
    and the ranges are :data:`VALUE_RANGES`. Returns ``raw``; anything else is refused in one line naming the
    first layer and what is wrong.
    """
    first = paths[0] if isinstance(paths, (list, tuple)) and paths else paths
    layers = cv.layer_count(enc.channels)
    if raw.shape[-1] != enc.channels:
        raise InputError(
            first,
            f"{enc.channels} channels declared: {layers} RGBA layers, got "
            f"{raw.shape[-1] // cv.CHANNELS_PER_LAYER}",
        )
    bad = ~np.isfinite(raw)
    if bad.any():
        row, col, ch = (int(i[0]) for i in np.nonzero(bad))
        raise InputError(
            first,
            f"{int(bad.sum())} values are not finite (NaN or infinity), the first at texel "
            f"({row}, {col}), channel {ch}",
        )
    lo, hi = VALUE_RANGES[enc.values]
    vmin, vmax = float(raw.min()), float(raw.max())
    if vmin < lo - 1e-6 or vmax > hi + 1e-6:
        raise InputError(
            first, f"values from {vmin:g} to {vmax:g}; {enc.values} values lie in [{lo:g}, {hi:g}]"
        )
    return raw


def _decode_values(v: np.ndarray, values: str) -> np.ndarray:
    """Sines of the horizon angle from the stored values."""
    v = np.asarray(v, np.float64)
    if values == "sine":
        return v
    if values == "cosine":
        return np.sqrt(np.clip(1.0 - v * v, 0.0, 1.0))
    if values == "angle":
        return np.sin(np.clip(v, 0.0, 1.0) * (math.pi / 2))
    if values == "tangent":
        return v / np.sqrt(1.0 + v * v)
    return v * np.abs(v)  # signed square root


def to_hzval(raw: np.ndarray, enc: Encoding) -> np.ndarray:
    """Return the sines in hzval's layout ``(rows, cols, D)`` float32 from the stored values.

    The values are decoded and their channels put in hzval's order under ``enc`` (module docstring).
    """
    D = enc.channels
    if raw.shape[-1] < D:
        raise InputError("--horizon-map", f"{D} channels declared, the layers hold {raw.shape[-1]}")
    s = _decode_values(raw[..., :D], enc.values)
    sy = -1.0 if enc.y == "down" else 1.0
    sd = -1.0 if enc.direction == "cw" else 1.0
    step = 360.0 / D
    out = np.empty(s.shape, np.float64)
    for k in range(D):
        # baker channel position j (fractional) whose direction is hzval's 360 k / D
        phi_baker = sy * k * step  # the same direction in the baker's frame
        j = (sd * (phi_baker - enc.azimuth0) / step) % D
        j0 = int(math.floor(j + 1e-9)) % D
        f = j - math.floor(j + 1e-9)
        f = 0.0 if abs(f) < 1e-9 or abs(f - 1) < 1e-9 else f
        out[..., k] = s[..., j0] * (1 - f) + s[..., (j0 + 1) % D] * f
    return out.astype(np.float32)


def load(paths: list[str | Path], enc: Encoding) -> np.ndarray:
    """Read, check (:func:`check_layers`) and convert an external bake.

    The result is the sines ``(rows, cols, D)`` in hzval's layout.
    """
    enc = enc.validate()
    return to_hzval(check_layers(read_layers(paths), enc, list(paths)), enc)


#: A candidate must beat the declared convention's error by this share to be called a better match:
#: the sine, tangent and angle encodings nearly agree on low horizons, and a bake at another radius
#: than the exact one differs from it anyway.
CLEARLY_BETTER = 0.15

#: A horizon map "does not describe" the height map when its best convention's :func:`correlation`
#: with hzval's exact horizons is below this. Measured (``studies/external_bound.py``, docs/ci.md):
#: hzval's seed bakes of the 8 built-in materials at 64 and 128 texels, 8-bit, against the exact bake
#: of the same material correlate 0.57 to 0.98 (radius 4 included), against another material's at most
#: 0.29 (median 0.00). The mean |s - s_exact| cannot tell them apart: a right map of the deep spikes
#: scores up to 0.16, a wrong map of the flat panels as low as 0.055.
DESCRIBES_CORRELATION = 0.4
#: The spread (standard deviation about each channel's mean) of the exact horizons below which a
#: surface is too flat for :func:`detect` to judge whether a map describes it.
MIN_SPREAD = 0.005


def rings(D: int) -> list[tuple[str, str, float]]:
    """Return the 2 D rotations and reflections of a ring of ``D`` channels.

    Each is ``(y, direction, azimuth0)``: a reflection named as +y down first (the likelier bug), then as
    clockwise.
    """
    step = 360.0 / D
    return [(y, d, r * step) for y, d in (("up", "ccw"), ("down", "ccw"), ("up", "cw")) for r in range(D)]


def _score(raw: np.ndarray, exact: np.ndarray, enc: Encoding) -> float:
    return float(np.mean(np.abs(to_hzval(raw, enc).astype(np.float64) - exact)))


def correlation(raw: np.ndarray, exact: np.ndarray, enc: Encoding) -> float:
    """Return the Pearson correlation between ``raw`` decoded under ``enc`` and hzval's exact horizons.

    It runs over texels and channels, each channel's mean removed first (a map of the right surface baked at a
    short radius is lower everywhere, yet correlated; one of another surface is not).
    """
    a = to_hzval(raw, enc).astype(np.float64)
    b = np.asarray(exact, np.float64)
    a, b = a - a.mean(axis=(0, 1)), b - b.mean(axis=(0, 1))
    den = math.sqrt(float((a * a).sum()) * float((b * b).sum()))
    return float((a * b).sum()) / den if den > 0 else 0.0


#: The light elevations, in degrees, at which :func:`shadow_error` compares a reading's shadows.
SHADOW_ELEVATIONS: tuple[float, ...] = tuple(float(e) for e in range(5, 90, 10))


def shadow_error(raw: np.ndarray, exact: np.ndarray, enc: Encoding, k: float = 8.0) -> float:
    """Return how a reading of the map would shadow, as a mean ``|F - V|``.

    The mean runs over every texel, stored direction and :data:`SHADOW_ELEVATIONS`, with ``F = clamp(k (sin e
    - s) + 1, 0, 1)`` of the sines read under ``enc`` (Lengyel's factor) and ``V = [sin e > s_exact]`` of
    hzval's exact horizons.

    A map fitted to render well (``hzval fit``) can lie closer to the exact sines under another
    reading, yet shadow worse under it: a convention is suggested only where this is lower.
    """
    s = to_hzval(raw, enc)
    exact = np.asarray(exact, np.float32)
    total = 0.0
    for e in SHADOW_ELEVATIONS:
        z = np.float32(math.sin(math.radians(e)))
        F = np.clip(np.float32(k) * (z - s) + np.float32(1.0), 0.0, 1.0)
        total += float(np.mean(np.abs(F - (z > exact)), dtype=np.float64))
    return total / len(SHADOW_ELEVATIONS)


def detect(raw: np.ndarray, exact: np.ndarray, declared: Encoding, keep: int = 8, k: float = 8.0) -> dict:
    """Return the conventions' scores, each convention with its mean |s - s_exact|.

    The result is ``{declared, best_match, scores, matches, correlation, describes}``.

    In two stages: the ring (which channel points where) under the declared value encoding, then
    the value encoding on the best ring. ``best_match`` is the lowest of every candidate;
    ``suggested`` what a warning proposes: at each stage the declared choice unless another's error
    is :data:`CLEARLY_BETTER` lower, and then only where it also shadows better (:func:`shadow_error`,
    at the technique's ``k``);
    ``matches``: the map describes the height map (``correlation`` of the best match at least
    :data:`DESCRIBES_CORRELATION`) and no candidate's error is :data:`CLEARLY_BETTER` lower than
    the declared convention's. ``scores``: the ``keep`` best of every candidate.
    """
    exact = np.asarray(exact, np.float64)
    D = declared.channels
    declared_mae = _score(raw, exact, declared)
    ring_scores = [
        (dataclasses.replace(declared, y=y, direction=d, azimuth0=a), None) for y, d, a in rings(D)
    ]
    ring_scores = [(e, _score(raw, exact, e)) for e, _ in ring_scores]
    ring, ring_mae = min(ring_scores, key=lambda es: es[1])
    # what the warning suggests: at each stage the declared choice stands unless another is clearly better
    # (sine, tangent and angle nearly agree on low horizons: a tangent 3% lower is no reason to switch)
    if ring_mae >= declared_mae * (1 - CLEARLY_BETTER):
        ring, ring_mae = declared, declared_mae
    value_scores = [(dataclasses.replace(ring, values=v), None) for v in VALUES]
    value_scores = [(e, _score(raw, exact, e)) for e, _ in value_scores]
    suggested, suggested_mae = min(value_scores, key=lambda es: es[1])
    if suggested_mae >= ring_mae * (1 - CLEARLY_BETTER):
        suggested, suggested_mae = ring, ring_mae
    # suggested only where it would also shadow better (|F - V| against the exact horizons' V)
    shadows = {declared: shadow_error(raw, exact, declared, k)}
    if suggested != declared:
        shadows[suggested] = shadow_error(raw, exact, suggested, k)
        if shadows[suggested] >= shadows[declared]:
            suggested, suggested_mae = declared, declared_mae
    everything = sorted(ring_scores + value_scores + [(declared, declared_mae)], key=lambda es: es[1])
    best, best_mae = everything[0]
    seen, rows = set(), []
    for e, m in everything:
        if e not in seen and len(rows) < keep:
            seen.add(e)
            rows.append({**e.record(), "mae": m})
    # a surface with next to no horizons (flat, or a tiny depth) leaves nothing to correlate: not judged
    judged = float(np.std(exact - exact.mean(axis=(0, 1)))) > MIN_SPREAD
    corr = correlation(raw, exact, best) if judged else None
    describes = corr is None or corr >= DESCRIBES_CORRELATION
    fits = suggested == declared
    return {
        "declared": {**declared.record(), "mae": declared_mae, "shadow_error": shadows[declared]},
        "best_match": {**best.record(), "mae": best_mae},
        "suggested": {**suggested.record(), "mae": suggested_mae, "shadow_error": shadows[suggested]},
        "scores": rows,
        "matches": bool(fits and describes),
        "convention_fits": bool(fits),
        "correlation": corr,
        "describes": bool(describes),
        "describes_bound": DESCRIBES_CORRELATION,
    }


def advice(result: dict) -> str | None:
    """Return a line on what looks wrong when a convention fits clearly better than the declared one.

    The line names each fix by its flag. It is ``None`` otherwise, and also when the map does not describe the
    height map at all (:func:`warnings` says that instead).
    """
    if result.get("convention_fits", result["matches"]) or not result.get("describes", True):
        return None
    d, b = result["declared"], result.get("suggested", result["best_match"])
    what = []
    mirrored = (d["y"] != b["y"]) != (d["direction"] != b["direction"])
    if mirrored:
        what.append(
            "the channels look mirrored: is +y down?"
            if d["y"] == "up"
            else "the channels look mirrored: is +y up?"
        )
    elif (d["azimuth0"] - b["azimuth0"]) % 360.0 != 0.0 or d["direction"] != b["direction"]:
        what.append(f"the channels look rotated: does channel 0 point to {b['azimuth0']:g} degrees?")
    if d["values"] != b["values"]:
        what.append(f"the values look like {b['values']}, not {d['values']}")
    # the flags that turn the declared convention into the best match, each one that differs
    flags = [
        f"--horizon-{key} {b[key]:g}" if key == "azimuth0" else f"--horizon-{key} {b[key]}"
        for key in ("y", "direction", "azimuth0", "values")
        if d[key] != b[key]
    ]
    detail = "; ".join(what) or "another convention fits better"
    fix = f"; try {' '.join(flags)}" if flags else ""
    shadows = (
        f"; its shadows |F - V| {b['shadow_error']:.4f} against {d['shadow_error']:.4f} as declared"
        if "shadow_error" in d and "shadow_error" in b
        else ""
    )
    return (
        f"horizon map: {detail} (declared {d['channels']} channels at {d['azimuth0']:g} degrees "
        f"{d['direction']}, +y {d['y']}, {d['values']}: |s - exact| {d['mae']:.4f}; better "
        f"{b['azimuth0']:g} degrees {b['direction']}, +y {b['y']}, {b['values']}: {b['mae']:.4f}"
        f"{shadows}){fix}"
    )


def warnings(result: dict, layers, height) -> list[str]:
    """Return every warning of a detection (:func:`detect`), each naming the flag that fixes it.

    The warnings are: the map does not describe the height map (naming both files), or :func:`advice`'s
    convention.
    """
    if not result.get("describes", True):
        names = ",".join(str(p) for p in layers)
        return [
            f"horizon map {names} does not describe this height map {height}: under its best convention "
            f"it correlates {result['correlation']:.2f} with hzval's exact horizons (a map of this surface: "
            f"at least {result['describes_bound']:g}; |s - exact| {result['best_match']['mae']:.3f}); was it "
            "baked from another height map, or at another --depth? (--horizon-map)"
        ]
    line = advice(result)
    return [line] if line else []


def repeated_layers(raw: np.ndarray, layers) -> list[str]:
    """Return a warning where two layers of an external map hold the same values.

    That is one layer exported twice under two names. No warning is given when every value is the same (a
    flat surface's map may be so).
    """
    n = cv.CHANNELS_PER_LAYER
    parts = [raw[..., n * i : n * (i + 1)] for i in range(raw.shape[-1] // n)]
    if float(np.ptp(raw)) == 0.0:
        return []
    for i in range(len(parts)):
        for j in range(i + 1, len(parts)):
            if np.array_equal(parts[i], parts[j]):
                return [
                    f"horizon map layers {layers[i]} and {layers[j]} hold the same values, though they stand "
                    "for other directions: was one layer exported twice? (--horizon-map)"
                ]
    return []
