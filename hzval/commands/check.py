"""The regression check: the shipped scenes, rendered small, against the references in ``reference/``.

:func:`run` renders every scene of ``scenes/*.toml`` at the small size its
``[check]`` section asks for (64-128 px) with the truth (:mod:`hzval.truth.plane`)
and every technique of the registry that applies to the scene
(:mod:`hzval.techniques.registry`), each in the variants it asks to be guarded
(:meth:`hzval.techniques.registry.Technique.check_variants`: the horizon map's
``exact`` and ``gpu`` paths, the others as built), and compares each image
with its reference::

The design in full: docs/internals.md, "hzval.commands.check".
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from PIL import Image
from tqdm import tqdm

from hzval import materials
from hzval.bake import maps as bake
from hzval.core import backend, errors, shading
from hzval.core.errors import InputError
from hzval.io import atomic, codecs, paths, staging
from hzval.metrics import compare
from hzval.pipeline import renders, sweep
from hzval.pipeline.records import frame_folder
from hzval.report import images
from hzval.report import pages as report
from hzval.scene import files as scene_files
from hzval.scene import spec as sc
from hzval.techniques import registry as technique

__all__ = [
    "Tiers",
    "DEFAULT_TIERS",
    "CROSS_BACKEND_TIERS",
    "BACKEND_ATTRIBUTE",
    "backend_name",
    "reference_backend",
    "across_backends",
    "BLOCK",
    "ImageResult",
    "CheckResult",
    "check_scene",
    "render_references",
    "check_material",
    "compare_image",
    "run",
    "write_report",
    "repository_path",
    "p_value",
    "sidak_level",
]

#: Side of the pixel blocks whose means the truth's test also compares.
BLOCK = 8
#: Largest side of a check render, in texels (references stay small).
MAX_CHECK_SIZE = 128
#: Smallest ``[check] size``: the smallest height map hzval takes (:data:`hzval.io.heightmap.MIN_SIDE`).
MIN_CHECK_SIZE = 8


@dataclass(frozen=True)
class Tiers:
    """Thresholds of one kind of image (see the module docstring for their meaning)."""

    fail: float
    fail_percent: float
    hard_fail: float
    warn: float

    @classmethod
    def of(cls, scene, kind: str, technique_name: str | None = None) -> "Tiers":
        """Return the tiers of image ``kind`` (``truth`` or a technique's check variant) of ``scene``."""
        base = DEFAULT_TIERS["truth" if kind == "truth" else "technique"]
        tables = ("truth",) if kind == "truth" else ("approx", "technique", technique_name, kind)
        given = {}
        for table in dict.fromkeys(t for t in tables if t):
            given.update(scene.tolerances.get(table, {}))
        unknown = set(given) - {f.name for f in dataclasses.fields(cls)}
        if unknown:
            raise InputError(
                scene.source or scene.name,
                f"unknown tolerance {sorted(unknown)[0]!r}; use fail, fail_percent, hard_fail, warn",
            )
        tiers = dataclasses.replace(base, **{k: _number(scene, k, v) for k, v in given.items()})
        return tiers.validated(scene, "truth" if kind == "truth" else "technique")

    def validated(self, scene, kind: str) -> "Tiers":
        """Return these tiers once each is in its range.

        Otherwise the error is one line naming the scene file and the setting. ``fail`` is a probability in
        (0, 1) for the truth (a significance level), a difference in (0, 1] (exposed linear units) for a
        technique; ``hard_fail`` is in (0, 1]; the percentages are in [0, 100]. NaN is no number: a NaN
        tolerance would let every image pass.
        """
        fail_ok = 0 < self.fail < 1 if kind == "truth" else 0 < self.fail <= 1
        checks = {
            "fail": (fail_ok, "in (0, 1), a significance level" if kind == "truth" else "in (0, 1]"),
            "hard_fail": (0 < self.hard_fail <= 1, "in (0, 1]"),
            "fail_percent": (0 <= self.fail_percent <= 100, "a percentage in [0, 100]"),
            "warn": (0 <= self.warn <= 100, "a percentage in [0, 100]"),
        }
        for name, (ok, want) in checks.items():
            if not ok:  # NaN fails every comparison, so lands here
                raise InputError(
                    scene.source or scene.name,
                    f"[tolerances] {name} = {getattr(self, name)!r} for the {kind}: must be {want}",
                )
        return self


def _number(scene, key: str, value) -> float:
    """Return a tolerance's value as a float, or one line naming the scene file."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(scene.source or scene.name, f"[tolerances] {key} = {value!r}: must be a number")
    return float(value)


#: Default tiers. technique: absolute differences in exposed linear units (1 =
#: white); 1e-4 is about 1/40 of an 8-bit step in the darks and far above
#: float32 rounding. truth: significance level 0.01 (Sidak-corrected), an
#: allowance of 0.2% of pixels, and a bias of 0.01 in the image mean.
DEFAULT_TIERS = {
    "technique": Tiers(fail=1e-4, fail_percent=0.0, hard_fail=0.01, warn=0.0),
    "truth": Tiers(fail=0.01, fail_percent=0.2, hard_fail=0.01, warn=0.05),
}


#: The floor of a technique's tiers where the new image and its reference were rendered on different
#: backends (module docstring): a pixel fails above 1e-3, the image above 0.1% of such pixels or
#: any pixel above 0.05 (one 8-bit level of a horizon sine moves F by 8/255 = 0.031 at k = 8).
CROSS_BACKEND_TIERS = Tiers(fail=1e-3, fail_percent=0.1, hard_fail=0.05, warn=0.0)

#: The header attribute that names the backend a reference was rendered on.
BACKEND_ATTRIBUTE = "hzval_backend"


def backend_name(variant: str) -> str:
    """``llvm`` or ``cuda`` (or ``scalar``): the backend of a Mitsuba variant's name.

    >>> backend_name("cuda_ad_rgb")
    'cuda'
    """
    return variant.split("_", 1)[0]


def reference_backend(path: Path) -> str:
    """Return the backend that rendered a reference file.

    It is its header's :data:`BACKEND_ATTRIBUTE`, else ``llvm`` (references written before the attribute were
    all rendered there).
    """
    return codecs.read_exr_attributes(path).get(BACKEND_ATTRIBUTE, "llvm")


def across_backends(tiers: Tiers) -> Tiers:
    """``tiers`` loosened to at least :data:`CROSS_BACKEND_TIERS` (a technique's image only)."""
    c = CROSS_BACKEND_TIERS
    return Tiers(
        fail=max(tiers.fail, c.fail),
        fail_percent=max(tiers.fail_percent, c.fail_percent),
        hard_fail=max(tiers.hard_fail, c.hard_fail),
        warn=max(tiers.warn, c.warn),
    )


@dataclass
class ImageResult:
    """The comparison of one image with its reference."""

    scene: str
    frame: str
    kind: str
    status: str  # "pass", "warn", "fail" or "new"
    reasons: list[str] = field(default_factory=list)
    tiers: Tiers | None = None
    numbers: dict = field(default_factory=dict)
    maps: dict = field(default_factory=dict)  # "score": per-pixel map for the report
    new: dict | None = None
    reference: dict | None = None
    scale: float = 1.0
    #: the backend that rendered the reference, where it is not the one that rendered ``new``
    other_backend: str | None = None

    @property
    def name(self) -> str:
        """Return the image's name in the check's report: ``scene/frame/kind``."""
        return f"{self.scene}/{self.frame}/{self.kind}"


@dataclass
class CheckResult:
    """The outcome of a check: every image compared, the references updated and the wall time."""

    images: list[ImageResult]
    updated: list[str] = field(default_factory=list)
    seconds: float = 0.0

    @property
    def passed(self) -> bool:
        """Return whether every image passed (a warning passes)."""
        return all(r.status in ("pass", "warn") for r in self.images)

    def count(self, status: str) -> int:
        """Return how many images have ``status``."""
        return sum(r.status == status for r in self.images)


def repository_path(name: str) -> Path:
    """``scenes/`` or ``reference/`` of the source tree hzval runs from."""
    return Path(__file__).resolve().parents[2] / name


# --------------------------------------------------------------------------
# Rendering
# --------------------------------------------------------------------------


def check_scene(scene):
    """``scene`` as the check renders it: the ``[check]`` section's size, azimuths, spp and depth.

    ``depth``: a material whose relief is a few texels at 512 has next to none at a check size of
    64-96 texels (its depth is in image widths); a deeper check keeps its shadows there to guard.
    """
    c = scene.check
    size = c.get("size")
    if size is not None and (
        isinstance(size, bool) or not isinstance(size, int) or not MIN_CHECK_SIZE <= size <= MAX_CHECK_SIZE
    ):
        raise InputError(
            scene.source or scene.name,
            f"check.size must be in [{MIN_CHECK_SIZE}, {MAX_CHECK_SIZE}] texels (references stay "
            f"small), got {size!r}",
        )
    unknown = set(c) - {"size", "azimuths", "spp", "depth", "resolution"}
    if unknown:
        raise InputError(
            scene.source or scene.name,
            f"unknown check setting {sorted(unknown)[0]!r}; use size, azimuths, spp, depth, resolution",
        )
    return sc.override(
        scene,
        size=size if materials.is_builtin(scene.material.height) else None,  # a file: check_material
        azimuths=c.get("azimuths"),
        spp=c.get("spp"),
        depth=c.get("depth"),
        resolution=c.get("resolution"),
    )


def check_material(scene) -> tuple[np.ndarray, np.ndarray]:
    """Return the height map and linear albedo ``(rows, cols, 3)`` the check renders.

    A built-in material is generated at ``check.size``; a file's, where larger than ``check.size`` (default
    :data:`MAX_CHECK_SIZE`), is averaged down (box filter, the aspect kept) until its larger side is, so that
    a user's map of any size has small references.
    """
    hm = sc.load_material_height(scene.material)
    h = hm.height
    rows, cols = h.shape
    if materials.is_builtin(scene.material.height):
        return h, sc.load_albedo(scene.material, rows, cols)
    target = int(scene.check.get("size") or MAX_CHECK_SIZE)
    albedo = sc.load_albedo(scene.material, rows, cols)
    if max(rows, cols) <= target:
        return h, albedo
    scale = target / max(rows, cols)
    shape = (max(MIN_CHECK_SIZE, round(rows * scale)), max(MIN_CHECK_SIZE, round(cols * scale)))
    small = np.stack([_box(albedo[..., c], shape) for c in range(3)], axis=-1)
    return _box(h, shape), small


def _box(values: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Return ``values`` averaged down to ``shape`` ``(rows, cols)``.

    Each output texel is the mean of the input area it covers: Pillow's box filter, in float32.
    """
    img = Image.fromarray(np.ascontiguousarray(values, np.float32))
    return np.asarray(img.resize((shape[1], shape[0]), Image.Resampling.BOX), np.float32)


def renderers(scene, height: np.ndarray, points=None, albedo: np.ndarray | None = None) -> dict:
    """Return every check variant of every technique that applies to ``scene``.

    The result is ``{kind: (variant, technique class, built technique)}``. On a model, ``points`` are the
    truth's samples, and only the techniques that render on models are included; ``albedo`` is as
    :func:`check_material` gives it (default: the material's at the map's size).
    """
    params = bake.BakeParams(depth=scene.material.depth, boundary=scene.material.boundary).validate()
    rows, cols = height.shape
    if albedo is None:
        albedo = sc.load_albedo(scene.material, rows, cols)
    ctx = technique.Context(scene, height, bake.bake(height, params), albedo, points=points)
    out = {}
    for t in technique.select(None, scene):
        if points is not None and t.not_on_models:
            continue
        for v in t.check_variants():
            out[v.name] = (v, t, t.build(ctx, **v.settings))
    return out


def render_references(scene, *, seed: int | None = None) -> dict[tuple[str, str], dict[str, np.ndarray]]:
    """Render ``scene`` (already :func:`check_scene`'d) into ``{(frame, kind): channels}``.

    ``seed`` replaces the scene's seed for the truth.
    """
    # another seed moves the samples: only the truth takes it (the techniques are
    # deterministic, and their references hold their images at the scene's own positions)
    truth_scene = scene if seed is None else dataclasses.replace(scene, seed=int(seed))
    height, albedo = check_material(scene)
    rows, cols = height.shape
    if max(rows, cols) > MAX_CHECK_SIZE:
        raise InputError(
            scene.source or scene.name,
            f"{cols}x{rows} is too large for a reference (at most {MAX_CHECK_SIZE} px; set check.size)",
        )
    the_truth, points = sweep.truth_of(truth_scene, height, albedo)
    if points is not None and seed is not None:
        # the techniques read at the truth's hits: at the scene's own seed, whatever the truth's
        points = sweep.truth_of(scene, height, albedo)[1]
    kinds = renderers(scene, height, points, albedo)
    out = {}
    for el, az in renders.lights(scene):  # a scene over several elevations: each (elevation, azimuth)
        name = frame_folder(az, el)
        if el is not None:
            the_truth.light_at(el)
        t = the_truth.render(az)
        ch = _rgb(t.image)
        ch["V"] = t.layers["visibility"]
        var = _rgb(t.variance["image"])
        ch.update({f"var.{k}": v for k, v in var.items()})
        ch["var.V"] = t.variance["visibility"]
        out[(name, "truth")] = ch
        for kind, (_, _, r) in kinds.items():
            a = r.render(az, elevation_deg=el)
            ch = _rgb(a.image)
            ch["F"] = a.layers["factor"]
            out[(name, kind)] = ch
    return out


def _rgb(image: np.ndarray) -> dict[str, np.ndarray]:
    return {c: np.asarray(image[..., k], np.float32) for k, c in enumerate("RGB")}


# --------------------------------------------------------------------------
# Comparing
# --------------------------------------------------------------------------


def _values(ch: dict[str, np.ndarray], names: list[str] | None = None) -> tuple[list[str], np.ndarray]:
    """Return the value channels (not ``var.*``) stacked last, in the order of ``names`` if given.

    An EXR file lists its channels sorted by name.
    """
    names = names or [k for k in ch if not k.startswith("var.")]
    return names, np.stack([np.asarray(ch[k], np.float64) for k in names], axis=-1)


def compare_image(
    new: dict[str, np.ndarray], ref: dict[str, np.ndarray], kind: str, tiers: Tiers, scale: float, spp: int
) -> tuple[str, list[str], dict, dict]:
    """``(status, reasons, numbers, maps)`` of one image against its reference.

    ``scale`` multiplies the RGB channels (the exposure); ``V`` and ``F`` are
    already in [0, 1].
    """
    names, a = _values(new)
    ref_names = sorted(k for k in ref if not k.startswith("var."))
    shapes = {np.shape(v) for v in ref.values()}
    if (
        ref_names != sorted(names)
        or (kind == "truth" and any(f"var.{n}" not in ref for n in names))
        or shapes != {a.shape[:2]}
    ):
        return (
            "fail",
            [
                f"reference has channels {sorted(ref)} of shape {sorted(shapes)}, the new render "
                f"{sorted(new)} of shape {a.shape[:2]}: render it again with --update"
            ],
            {},
            {},
        )
    _, b = _values(ref, names)
    bad = _non_finite(ref, names, kind)
    if bad:
        # NaN compares false with every bound: such a reference would pass anything
        return "fail", [f"the reference has {bad}: render it again with --update"], {}, {}
    s = np.array([scale if n in "RGB" else 1.0 for n in names])
    a, b = a * s, b * s
    diff = a - b
    absdiff = np.abs(diff)
    n_pix = diff.shape[0] * diff.shape[1]
    numbers = {
        "max_abs": float(absdiff.max()),
        "mean_abs": float(absdiff.mean()),
        "mean_diff": float(diff.mean()),
        "pixels": n_pix,
    }
    reasons: list[str] = []
    bad = _non_finite(new, names, kind)
    if bad:
        return (
            "fail",
            [f"the new render has {bad}"],
            numbers,
            {"score": np.nan_to_num(absdiff.max(-1), nan=1.0)},
        )
    if kind != "truth":
        failing, maps = _technique_test(absdiff, tiers, reasons)
    else:
        failing, maps = _truth_test(new, ref, names, a, b, diff, absdiff, s, tiers, spp, numbers, reasons)
    percent = 100.0 * float(failing.mean())
    numbers.update(failing_pixels=int(failing.sum()), failing_percent=percent)
    if percent > tiers.fail_percent:
        what = f"|diff| > {tiers.fail:g}" if kind != "truth" else f"p < {numbers['alpha']:.2g}"
        reasons.append(f"{percent:.3g}% of pixels fail ({what}) > fail_percent {tiers.fail_percent:g}%")
    if reasons:
        return "fail", reasons, numbers, maps
    if percent > tiers.warn:
        return (
            "warn",
            [f"{percent:.3g}% of pixels fail > warn {tiers.warn:g}% (allowed up to {tiers.fail_percent:g}%)"],
            numbers,
            maps,
        )
    return "pass", [], numbers, maps


def _non_finite(ch: dict[str, np.ndarray], names: list[str], kind: str) -> str:
    """Return what of an image is not finite, or ``""``.

    It says how many pixels, of how many, and in which channels (a truth's variances included).
    """
    names = [*names, *(f"var.{n}" for n in names)] if kind == "truth" else names
    bad = {n: ~np.isfinite(np.asarray(ch[n])) for n in names if n in ch}
    where = [n for n, b in bad.items() if b.any()]
    if not where:
        return ""
    pixels = np.logical_or.reduce([bad[n] for n in where])
    return f"{int(pixels.sum())} of {pixels.size} pixels not finite (NaN or infinite) in {', '.join(where)}"


def _technique_test(absdiff: np.ndarray, tiers: Tiers, reasons: list) -> tuple[np.ndarray, dict]:
    """Return a deterministic image: a pixel's score is its largest absolute difference over the channels."""
    score = absdiff.max(-1)
    if (score > tiers.hard_fail).any():
        reasons.append(f"a pixel differs by {score.max():.3g} > hard_fail {tiers.hard_fail:g}")
    return score > tiers.fail, {"score": score}


def _truth_test(
    new, ref, names, a, b, diff, absdiff, s, tiers: Tiers, spp: int, numbers: dict, reasons: list
) -> tuple[np.ndarray, dict]:
    """Test a Monte Carlo image against its reference with per-pixel and per-block z-tests.

    The z-tests of every pixel and 8 x 8 block are under one Sidak correction, and there is a bound on the
    bias of the image mean (module docstring).
    """
    var_a = np.stack([np.asarray(new[f"var.{n}"], np.float64) for n in names], -1) * s * s
    var_b = np.stack([np.asarray(ref[f"var.{n}"], np.float64) for n in names], -1) * s * s
    q = 1.0 / (spp + 2)
    floor = np.maximum(np.abs(a), np.abs(b)) ** 2 * q * (1 - q) / spp
    var = np.maximum(np.nan_to_num(var_a), floor) + np.maximum(np.nan_to_num(var_b), floor)
    var = np.maximum(var, 1e-12)  # two exact zeros: any difference is significant
    p_pix = _p_value(absdiff / np.sqrt(var)).min(-1)
    blocks_d, blocks_v = _block_sums(diff), _block_sums(var)
    nb = blocks_d.shape[0] * blocks_d.shape[1]
    p_blk = _p_value(np.abs(blocks_d) / np.sqrt(blocks_v)).min(-1)
    n_tests = (diff.shape[0] * diff.shape[1] + nb) * len(names)
    alpha = sidak_level(tiers.fail, n_tests)
    bad_blocks = int((p_blk < alpha).sum())
    bias = np.abs(diff.mean(axis=(0, 1)))
    numbers.update(
        alpha=alpha, min_p=float(p_pix.min()), failing_blocks=bad_blocks, blocks=nb, bias=float(bias.max())
    )
    # the map shows the stronger evidence at each pixel: its own test or its block's
    p_map = p_pix.copy()
    hb, wb = p_blk.shape
    p_map[: hb * BLOCK, : wb * BLOCK] = np.minimum(
        p_map[: hb * BLOCK, : wb * BLOCK], np.kron(p_blk, np.ones((BLOCK, BLOCK)))
    )
    if (bias > tiers.hard_fail).any():
        reasons.append(f"the image mean differs by {bias.max():.3g} > hard_fail {tiers.hard_fail:g}")
    if bad_blocks:
        reasons.append(f"{bad_blocks} of {nb} blocks of {BLOCK}x{BLOCK} pixels differ (p < {alpha:.2g})")
    return p_pix < alpha, {"score": np.minimum(-np.log10(np.maximum(p_map, 1e-300)), 300.0), "alpha": alpha}


def _p_value(z: np.ndarray) -> np.ndarray:
    # SciPy: 0.3-0.4 s to import, paid only where it is used
    from scipy.special import erfc

    return erfc(z / math.sqrt(2.0))


def p_value(z, *, one_sided: bool = False):
    """Return the p-value of a z-score, two-sided or one-sided.

    Two-sided is ``erfc(z / sqrt 2)`` (the truth's test); one-sided is half of it (a test of one direction
    only, e.g. a regression: :mod:`hzval.commands.gates`).
    """
    p = _p_value(np.asarray(z, np.float64))
    return p / 2.0 if one_sided else p


def sidak_level(alpha: float, n_tests: int) -> float:
    """Return the per-test level of ``n_tests`` tests at family-wise level ``alpha``.

    It is Sidak's ``1 - (1 - alpha)^(1/n)``, computed without cancellation.
    """
    return -math.expm1(math.log1p(-alpha) / max(int(n_tests), 1))


def _block_sums(x: np.ndarray) -> np.ndarray:
    """Return the sums of ``BLOCK x BLOCK`` blocks.

    Means of the blocks (for differences) are sums / BLOCK^2; variances of means are sums / BLOCK^4: the ratio
    tested is the same, so sums are enough.
    """
    h, w = x.shape[0] // BLOCK * BLOCK, x.shape[1] // BLOCK * BLOCK
    x = x[:h, :w]
    return x.reshape(h // BLOCK, BLOCK, w // BLOCK, BLOCK, -1).sum(axis=(1, 3))


# --------------------------------------------------------------------------
# The run
# --------------------------------------------------------------------------


def reference_file(references: Path, scene: str, frame: str, kind: str) -> Path:
    return Path(references) / scene / frame / f"{kind}.exr"


def _variants(scene) -> dict:
    """Return ``{variant name: (variant, technique name)}`` of the techniques that apply to ``scene``.

    A ``[tolerances.X]`` table whose name is no technique's or variant's is refused, in one line.
    """
    out = {v.name: (v, t.name) for t in technique.select(None, scene) for v in t.check_variants()}
    known = {
        "truth",
        "technique",
        "approx",
        *technique.names(),
        *(v.name for n in technique.names() for v in technique.get(n).check_variants()),
    }
    for table in scene.tolerances:
        if table not in known:
            near = difflib.get_close_matches(table, sorted(known), n=1)
            raise InputError(
                scene.source or scene.name,
                f"unknown table [tolerances.{table}]"
                + (f"; did you mean [tolerances.{near[0]}]?" if near else ""),
            )
    return out


def _former_reference(references: Path, scene: str, frame: str, entry) -> Path | None:
    """Return the reference a variant had under its former name, if there is one and none under its name.

    The former name is :attr:`hzval.techniques.registry.Variant.formerly`; this is the case of a reference
    folder of an earlier release.
    """
    if entry is None or not entry[0].formerly:
        return None
    old = reference_file(references, scene, frame, entry[0].formerly)
    return old if old.is_file() else None


def _check_only(only: list[str] | None, names: list[str]) -> None:
    """Refuse, in one line naming ``--only``, a name that is no scene's: a check of nothing passes."""
    for name in only or ():
        if name not in names:
            near = difflib.get_close_matches(name, names, n=1)
            hint = f"did you mean {near[0]!r}? " if near else ""
            raise InputError("--only", f"no scene is named {name!r} ({hint}the scenes: {', '.join(names)})")


def load_scenes(scenes_dir: str | Path) -> list:

    found = sorted(Path(scenes_dir).glob("*.toml"))
    if not found:
        raise InputError(scenes_dir, "no scene files (*.toml)")
    return [scene_files.load_scene(p) for p in found]


def run(
    *,
    scenes_dir: str | Path | None = None,
    references: str | Path | None = None,
    update: bool = False,
    seed: int | None = None,
    progress: bool = False,
    only: list[str] | None = None,
) -> CheckResult:
    """Render the shipped scenes and compare them with ``references``.

    With ``update``, rewrite the references that are missing or failing.
    """
    t0 = time.perf_counter()
    scenes_dir = Path(scenes_dir) if scenes_dir else repository_path("scenes")
    references = Path(references) if references else repository_path("reference")
    loaded = load_scenes(scenes_dir)
    _check_only(only, [s.name for s in loaded])
    scenes = [check_scene(s) for s in loaded if not only or s.name in only]
    for s in scenes:  # each name is a folder of reference/, which --update writes
        paths.file_name(s.name, s.source or s.name, "name")
        # every tolerance read and checked before the first render
        Tiers.of(s, "truth")
        for kind, (_, name) in _variants(s).items():
            Tiers.of(s, kind, name)
    result = CheckResult(images=[])
    here = backend_name(backend.variant())
    for scene in tqdm(scenes, desc="check", unit="scene", disable=not progress, leave=False):
        scale = shading.exposure(scene)
        rendered = render_references(scene, seed=seed)
        variants = _variants(scene)
        for (frame, kind), new in rendered.items():
            path = reference_file(references, scene.name, frame, kind)
            old = _former_reference(references, scene.name, frame, variants.get(kind))
            tiers = Tiers.of(scene, kind, variants[kind][1] if kind in variants else None)
            if old is not None and not path.is_file():
                path = old
            r = ImageResult(scene.name, frame, kind, "new", tiers=tiers, new=new, scale=scale)
            if path.is_file():
                try:
                    ref = codecs.read_exr(path)
                except Exception as exc:  # a corrupt reference fails its image, not the run
                    r.status, r.reasons = "fail", [f"{path}: unreadable reference ({errors.first_line(exc)})"]
                else:
                    r.reference = ref
                    made_on = reference_backend(path)
                    if made_on != here and kind != "truth":
                        r.other_backend, r.tiers = made_on, across_backends(tiers)
                    r.status, r.reasons, r.numbers, r.maps = compare_image(
                        new, ref, kind, r.tiers, scale, scene.spp
                    )
            else:
                r.reasons = [f"no reference at {path}"]
            if update and (r.status in ("new", "fail") or path == old):
                target = reference_file(references, scene.name, frame, kind)
                codecs.write_exr(target, new, attributes={BACKEND_ATTRIBUTE: here})
                if path == old:
                    old.unlink()  # renamed: the reference now has its variant's name
                result.updated.append(str(target))
            result.images.append(r)
    result.seconds = time.perf_counter() - t0
    return result


def summary(result: CheckResult) -> str:
    """Failures first, then warnings and new images; a last line with the counts."""
    lines = []
    order = {"fail": 0, "new": 1, "warn": 2, "pass": 3}
    for r in sorted(result.images, key=lambda r: order[r.status]):
        if r.status == "pass":
            continue
        lines.append(f"{r.status.upper():4}  {r.name}: {'; '.join(r.reasons)}")
    other = sorted({r.other_backend for r in result.images if r.other_backend})
    if other:
        lines.append(
            f"{sum(bool(r.other_backend) for r in result.images)} technique images have references "
            f"rendered on {', '.join(other)}: compared at the cross-backend tiers "
            f"(fail {CROSS_BACKEND_TIERS.fail:g}, fail_percent {CROSS_BACKEND_TIERS.fail_percent:g}%, "
            f"hard_fail {CROSS_BACKEND_TIERS.hard_fail:g})"
        )
    lines.append(
        f"{len(result.images)} images: {result.count('pass')} pass, {result.count('warn')} warn, "
        f"{result.count('fail')} fail, {result.count('new')} new ({result.seconds:.1f} s)"
    )
    return "\n".join(lines)


# --------------------------------------------------------------------------
# The failure report
# --------------------------------------------------------------------------


def write_report(result: CheckResult, out: str | Path, *, command: str = "", force: bool = False) -> Path:
    """Write ``out/index.html``: reference | new | difference for every image, failures first.

    The folder is held while it is written (:func:`hzval.io.staging.output_folder`, ``force`` as there).
    """
    out = Path(out)
    with staging.output_folder(out, force=force):
        return _write_report(result, out, staging.portable_command(command))


def _write_report(result: CheckResult, out: Path, command: str) -> Path:

    order = {"fail": 0, "new": 1, "warn": 2, "pass": 3}
    items = []
    for i, r in enumerate(sorted(result.images, key=lambda r: (order[r.status], r.name))):
        stem = f"img/{i:03d}"
        entry = {
            "name": r.name,
            "status": r.status,
            "reasons": r.reasons,
            "kind": r.kind,
            "numbers": _fmt_numbers(r.numbers),
            "tiers": dataclasses.asdict(r.tiers) if r.tiers else {},
            "ref": None,
            "new": None,
            "diff": None,
            "diff_caption": "",
        }
        if r.new is not None:
            entry["new"] = _write_preview(out, f"{stem}-new.png", r.new, r.scale)
        if r.reference is not None:
            entry["ref"] = _write_preview(out, f"{stem}-ref.png", r.reference, r.scale)
        score = r.maps.get("score")
        if score is not None:
            if r.kind == "truth":
                top = max(-math.log10(r.maps["alpha"]), 1e-9)
                entry["diff_caption"] = (
                    f"-log10 p of each pixel or of its 8x8 block, whichever is smaller; "
                    f"white at the failing level p = {r.maps['alpha']:.2g}"
                )
            else:
                top = r.tiers.hard_fail
                entry["diff_caption"] = f"largest |new - ref| per pixel; white at hard_fail = {top:g}"
            codecs.write_png(out / f"{stem}-diff.png", images.magma(score / top))
            entry["diff"] = f"{stem}-diff.png"
        items.append(entry)
    html = (
        report.environment()
        .get_template("check.html.j2")
        .render(
            items=items,
            passed=result.passed,
            counts={s: result.count(s) for s in order},
            updated=result.updated,
            seconds=result.seconds,
            command=command,
            versions=backend.versions(),
        )
    )
    index = out / "index.html"
    with atomic.atomic_path(index) as tmp:
        tmp.write_text(html, encoding="utf-8")
    return index


def _write_preview(out: Path, rel: str, ch: dict, scale: float) -> str:
    rgb = np.stack([ch["R"], ch["G"], ch["B"]], -1)
    codecs.write_png(out / rel, codecs.unit_to_u8(compare.display(rgb, scale)))
    return rel


def _fmt_numbers(n: dict) -> list[tuple[str, str]]:
    def g(v):
        return f"{v:.4g}" if isinstance(v, float) else str(v)

    labels = {
        "failing_percent": "failing pixels %",
        "failing_pixels": "failing pixels",
        "max_abs": "max |diff|",
        "mean_abs": "mean |diff|",
        "mean_diff": "mean diff",
        "bias": "largest channel bias",
        "min_p": "smallest p",
        "alpha": "failing level (Sidak)",
        "failing_blocks": "failing blocks",
        "blocks": "blocks",
        "pixels": "pixels",
    }
    return [(labels.get(k, k), g(v)) for k, v in n.items()]
