"""The bake: height map -> normal map, horizon map, ambient map, weight cube map, in a folder.

:func:`bake` runs the normal map (:func:`normal_map`), the horizon map of the chosen method
(``seed``: :func:`hzval.bake.horizon.horizon_map`; ``exact``:
:func:`hzval.bake.exact.exact_horizon_map`) and the ambient map, whose two averages over the
horizon angles ``alpha`` are ``mean_cos``, Lengyel's term (the seed's ``sum * kAngleCount`` means
an average), and ``mean_cos2``, the exact cosine-weighted unoccluded fraction of the hemisphere
for a horizon at ``alpha`` in every direction. :func:`write_bake`, :func:`read_bake` and
:func:`cached_bake` keep it in a folder (``bake.json`` records the parameters and the input's
digest; the exact method records ``radius`` and ``angles`` as ``null``).
"""

from __future__ import annotations

import dataclasses
import json
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from hzval.bake import occlusion as directional
from hzval.bake.exact import exact_horizon_map
from hzval.bake.horizon import horizon_map
from hzval.core import backend, budget, resources
from hzval.core import conventions as cv
from hzval.core import cube as cube_layout
from hzval.core.conventions import normal_map  # re-exported: the bake's first map
from hzval.core.errors import InputError
from hzval.io import codecs, documents, paths, staging

__all__ = [
    "CUBE_SIZE",
    "BakeParams",
    "METHODS",
    "Bake",
    "normals_only",
    "normal_map",
    "weight_cube",
    "estimate_bytes",
    "check_fits",
    "METHOD_NOTES",
    "CONTENTS",
    "needs_horizon",
    "needs_occlusion",
    "OCCLUSION",
    "bake",
    "write_bake",
    "read_bake",
    "cached_bake",
]


#: Edge length in texels of a face of the weight cube map (Lengyel: 16 x 16
#: is sufficient); the GPU path of :mod:`hzval.techniques.horizon` samples it.
CUBE_SIZE = 16


#: Valve's lift of the self-shadowed bump map's ray origins, texels (``height2ssbump``).
SSBUMP_LIFT = 0.55
#: The largest lift accepted: a rise of a texel's whole search radius would open every texel.
MAX_SSBUMP_LIFT = 16.0


@dataclass(frozen=True)
class BakeParams:
    """Parameters of a bake (``hzval bake``'s options).

    ``depth``: world height of ``H = 1`` in units of the image width.
    ``radius``: search radius in texels; neighbours with ``r < radius`` count.
    ``angles``: number of angular bins; a multiple of ``2 * directions``
    (each channel averages ``angles/directions + 1`` bins centred on its
    direction, module docstring).
    ``boundary``: ``wrap`` or ``open`` (:mod:`hzval.core.conventions`).
    ``method``: ``seed`` (the seed algorithm above, :func:`horizon_map`) or
    ``exact`` (exact horizons toward the 8 channel directions with unlimited
    radius, :func:`exact_horizon_map`; ``radius`` and ``angles`` are ignored
    and not validated, and :meth:`record` writes them as ``None``).
    ``directions``: stored horizon directions, 8 (the seed's) or 16
    (:data:`hzval.core.conventions.DIRECTION_COUNTS`); channel ``c`` looks toward
    azimuth ``360 c / directions`` degrees. ``exact`` supports 8 only: along
    the odd multiples of 22.5 degrees a ray from a texel centre meets no
    texel centres, so the exact sweeps would need interpolated heights
    (not implemented; :meth:`validate` says so).
    ``ssbump_lift``: texels the self-shadowed bump map's rays start above each texel (Valve's
    ``height2ssbump``, ``surf_pnt.z += 0.55``): the seed's sweep at this radius and these bins
    with the origin raised (:func:`horizon_map`'s ``lift``), whatever ``method``; 0 reads the
    horizon map itself.
    """

    depth: float = 0.05
    radius: int = 16
    angles: int = 32
    boundary: str = "wrap"
    method: str = "seed"
    directions: int = cv.CHANNEL_COUNT
    ssbump_lift: float = SSBUMP_LIFT

    def validate(self) -> "BakeParams":
        """Return these parameters, each in its range, else raise one line naming the flag."""
        cv.check_depth(self.depth, "--depth", self.boundary)
        lift = self.ssbump_lift
        if isinstance(lift, bool) or not isinstance(lift, (int, float)) or not 0.0 <= lift <= MAX_SSBUMP_LIFT:
            raise InputError(
                "--ssbump-lift", f"must be a number of texels in [0, {MAX_SSBUMP_LIFT:g}], got {lift}"
            )
        if self.method not in METHODS:
            raise InputError(
                "--method", f"unknown bake method {self.method!r}; available: {', '.join(METHODS)}"
            )
        if (
            isinstance(self.directions, bool)
            or not isinstance(self.directions, (int, np.integer))
            or self.directions not in cv.DIRECTION_COUNTS
        ):
            raise InputError(
                "--directions",
                f"must be one of {', '.join(map(str, cv.DIRECTION_COUNTS))}, got {self.directions}",
            )
        if self.method == "exact" and self.directions != cv.CHANNEL_COUNT:
            raise InputError(
                "--directions",
                f"the exact method stores {cv.CHANNEL_COUNT} directions only: along "
                "22.5-degree directions a ray meets no texel centres, and the exact "
                "sweeps do not interpolate heights; use --method seed",
            )
        if self.method == "seed":
            if self.radius is None or int(self.radius) != self.radius or self.radius < 2:
                raise InputError("--radius", f"must be an integer of at least 2 texels, got {self.radius}")
            m = 2 * int(self.directions)
            if self.angles is None or int(self.angles) != self.angles or self.angles < m or self.angles % m:
                raise InputError(
                    "--angles",
                    f"must be a multiple of {m} ({m}, {2 * m}, {3 * m}, ...) with "
                    f"{self.directions} directions, got {self.angles}",
                )
        if self.boundary not in cv.BOUNDARIES:
            raise InputError(
                "--boundary", f"must be one of {', '.join(cv.BOUNDARIES)}, got {self.boundary!r}"
            )
        return self

    def record(self) -> dict:
        """Return the parameters as ``bake.json`` records them (and the bake cache compares).

        The ``exact`` method has no search radius and no angular bins: it
        records ``radius`` and ``angles`` as ``None`` rather than values it
        did not use, so two exact bakes that differ only there share a cache.
        """
        d = asdict(self)
        if self.method == "exact":
            d.update(radius=None, angles=None)
        return d

    @classmethod
    def from_record(cls, record: dict) -> "BakeParams":
        """Return the inverse of :meth:`record` (``None`` entries take the defaults).

        A record without ``directions`` (written before it existed) is a
        bake of the seed's 8 directions.
        """
        return cls(**{k: v for k, v in record.items() if v is not None})

    @staticmethod
    def normalise_record(record: dict) -> dict:
        """Return ``record`` as :meth:`record` writes it now.

        A missing ``directions`` is 8 and a missing ``ssbump_lift`` 0.

        The bake cache compares records, and a ``bake.json`` from before either existed holds an
        8-direction bake whose self-shadowed bump map was not lifted.
        """
        return {"directions": cv.CHANNEL_COUNT, "ssbump_lift": 0.0, **record}


#: Horizon bake methods (``BakeParams.method``, ``--method``).
METHODS: tuple[str, ...] = ("seed", "exact")


@dataclass
class Bake:
    """The textures of the technique, as float32 arrays indexed ``[row, col]``.

    ``horizon``: ``(rows, cols, D)`` sines of the horizon angle, channel ``k``
    toward azimuth ``360 k / D`` degrees (``D = params.directions``, 8 or 16). ``normal``: ``(rows, cols,
    3)`` unit
    tangent-space normals. ``mean_cos``, ``mean_cos2``: ``(rows, cols)``
    ambient terms. ``timings``: seconds per stage. ``bent_normal``, ``ssbump``: ``(rows, cols, 3)``,
    the directional occlusion of :mod:`hzval.bake.occlusion` (``None`` in a bake without a horizon map,
    or one made without them: :func:`bake`'s ``occlusion``).
    """

    params: BakeParams
    horizon: np.ndarray
    normal: np.ndarray
    mean_cos: np.ndarray
    mean_cos2: np.ndarray
    timings: dict[str, float] = field(default_factory=dict)
    bent_normal: np.ndarray | None = None
    ssbump: np.ndarray | None = None

    @property
    def directions(self) -> int:
        """Stored horizon directions (channels), 8 or 16 (a bake without a horizon map: the parameters')."""
        return int(self.horizon.shape[-1]) if self.horizon is not None else int(self.params.directions)

    @property
    def contents(self) -> tuple[str, ...]:
        """What the bake holds (:data:`CONTENTS`)."""
        if self.horizon is None:
            return ("normal",)
        return CONTENTS if self.bent_normal is not None else _without_occlusion()

    @property
    def layers(self) -> tuple[np.ndarray, ...]:
        """The ``D / 4`` RGBA layers: layer ``l`` holds channels ``4 l .. 4 l + 3``."""
        n = cv.CHANNELS_PER_LAYER
        return tuple(self.horizon[..., n * i : n * (i + 1)] for i in range(cv.layer_count(self.directions)))

    def checked(self) -> "Bake":
        """Return this bake once every map is finite and every normal a unit vector.

        Otherwise the error is one line naming the map, how many texels are wrong, and ``--depth``. No bake
        with a NaN, an infinity or a zero normal is used or written.
        """
        maps = {  # by the files they are written to
            "horizon*.exr": self.horizon,
            "normal.exr": self.normal,
            "ambient.exr mean_cos": self.mean_cos,
            "ambient.exr mean_cos2": self.mean_cos2,
            "bent_normal.exr": self.bent_normal,
            "ssbump.exr": self.ssbump,
        }
        for name, values in maps.items():
            if values is None:
                continue
            bad = ~np.isfinite(values)
            if name in ("normal.exr", "bent_normal.exr"):
                with np.errstate(invalid="ignore", over="ignore"):
                    bad = bad.any(-1) | ~(np.abs(np.linalg.norm(values, axis=-1) - 1.0) <= 1e-3)
            if bad.any():
                raise InputError(
                    "--depth",
                    f"the bake at depth {self.params.depth:g} made {int(bad.sum())} of {bad.size} values "
                    f"of {name} non-finite or not unit length; nothing was written",
                )
        return self


def normals_only(height: np.ndarray, depth: float, boundary: str) -> "Bake":
    """Return a :class:`Bake` of the normal map alone (``horizon`` and the ambient maps ``None``).

    It is the unshadowed shading of a technique that reads no horizon map, built without the horizon bake's
    cost. ``height`` is normalised, ``(rows, cols)``.
    """
    h = cv.heights_in_texels(height, depth)
    return Bake(
        params=BakeParams(depth=depth, boundary=boundary),
        horizon=None,
        normal=normal_map(h, boundary),
        mean_cos=None,
        mean_cos2=None,
    )


# --------------------------------------------------------------------------
# Normal map
# --------------------------------------------------------------------------


# --------------------------------------------------------------------------
# Weight cube map
# --------------------------------------------------------------------------


def weight_cube(size: int | None = None) -> np.ndarray:
    """Return the 8-bit channel-weight cube map, ``(6, size, size, 4)`` uint8, OpenGL face order.

    Component ``c`` of a texel holds the weight of channel ``c`` (positive)
    or of channel ``c + 4`` (negative: at most one of the two is non-zero),
    remapped from [-1, 1] to [0, 255] (Lengyel, eq. 5.3). The weights are the
    exact linear interpolation of :func:`hzval.core.conventions.channel_weights`
    at each texel's centre direction.
    """
    size = CUBE_SIZE if size is None else int(size)
    d = cube_layout.cube_texel_directions(size)
    w = cv.channel_weights(d[..., 0], d[..., 1])
    n = cv.CHANNELS_PER_LAYER
    signed = w[..., :n] - w[..., n:]
    return cube_layout.encode_signed_weight(signed)


# --------------------------------------------------------------------------
# The whole bake
# --------------------------------------------------------------------------


def estimate_bytes(rows: int, cols: int, params: BakeParams) -> int:
    """Return the peak memory in bytes that baking a ``rows x cols`` map needs.

    The figures are :func:`hzval.core.budget.bake_bytes`'s. The exact method pads nothing; its sweep scratch
    (8 bytes per sweep position, at most 2 per texel, reused across channels) is less than the seed's ten
    kernel outputs, so the seed's figure per texel bounds it.
    """
    pad = params.radius - 1 if params.method == "seed" else 0
    return budget.bake_bytes(rows, cols, params.directions, pad)


def check_fits(what: str, rows: int, cols: int, params: BakeParams) -> None:
    """Raise :class:`InputError` naming ``what`` if the bake would not fit in memory."""
    resources.refuse_over(what, estimate_bytes(rows, cols, params), f"a {cols}x{rows} bake", "a smaller map")


#: What each method's horizon and ambient maps are, for ``bake.json``.
METHOD_NOTES: dict[str, str] = {
    "seed": "seed (Lengyel): max tan over neighbours with r < radius in `angles` bins; "
    "each channel the mean sine of its angles/directions + 1 nearest bins; ambient over the bins",
    "exact": "exact: horizon toward each channel's azimuth with unlimited radius (wrap: one period "
    "along the line, which is exact; open: to the edge), by line sweeps with a convex-hull "
    "stack (Timonen and Westerholm 2010); radius and angles unused (null); ambient over "
    "the 8 channel directions",
}


#: What a bake can hold (:attr:`Bake.contents`): the normal map alone, or with the horizon map and the
#: ambient maps derived from it, and the directional occlusion made from its sines
#: (:mod:`hzval.bake.occlusion`). Techniques declare which they read
#: (:meth:`hzval.techniques.registry.Technique.bake_needs`); a sweep bakes what its techniques need.
CONTENTS: tuple[str, ...] = ("normal", "horizon_map", "ambient", "bent_normal", "ssbump_map")
#: The contents of the directional occlusion, baked only for the techniques that read them.
OCCLUSION: tuple[str, ...] = ("bent_normal", "ssbump_map")


def needs_occlusion(needs) -> bool:
    """Return whether ``needs``, the names of what the bake must hold, call for the directional occlusion.

    The directional occlusion is the bent normals and the self-shadowed bump map. At 2048 x 2048 they take 3.5
    s of a 4.4 s bake, so a sweep whose techniques read neither bakes without them.
    """
    return bool(set(OCCLUSION) & set(needs))


def _without_occlusion() -> tuple[str, ...]:
    return tuple(c for c in CONTENTS if c not in OCCLUSION)


def needs_horizon(needs) -> bool:
    """Return whether ``needs``, the names of what the bake must hold, call for the horizon bake.

    ``needs`` are names of :data:`CONTENTS`, ``"height"`` aside. The horizon bake is the horizon map, and the
    ambient maps and directional occlusion, which are made from its sines.
    """
    return bool({"horizon_map", "ambient", *OCCLUSION} & set(needs))


def bake(
    height: np.ndarray, params: BakeParams = BakeParams(), *, horizon: bool = True, occlusion: bool = True
) -> Bake:
    """Bake a normalised height map ``H[row, col]`` into the technique's textures.

    With ``horizon=False``, the normal map alone (:func:`normals_only`), without the horizon bake's cost; with
    ``occlusion=False``, without the directional occlusion (:func:`needs_occlusion`).
    """
    params.validate()
    cv.check_relief(height, params.depth, params.boundary)
    if not horizon:
        t0 = time.perf_counter()
        only = normals_only(height, params.depth, params.boundary)
        return dataclasses.replace(
            only, params=params, timings={"normal_s": time.perf_counter() - t0}
        ).checked()
    backend.variant()
    timings = {}
    t0 = time.perf_counter()
    h = cv.heights_in_texels(height, params.depth)
    normal = normal_map(h, params.boundary)
    t1 = time.perf_counter()
    timings["normal_s"] = t1 - t0
    if params.method == "exact":
        horizon, mean_cos, mean_cos2 = exact_horizon_map(h, params.boundary)
    else:
        horizon, mean_cos, mean_cos2 = horizon_map(
            h, params.radius, params.angles, params.boundary, directions=params.directions
        )
    t2 = time.perf_counter()
    timings["horizon_s"] = t2 - t1
    bent = ss = None
    if occlusion:
        # the bent normals and ssbump's three channels two at a time (NumPy's loops release the GIL),
        # each map the same as made alone; two, whatever the cores, is what budget.OCCLUSION_BYTES_PER_TEXEL
        # charges
        pool = backend.host_pool(2)
        bent = pool.submit(directional.bent_normal, horizon)
        ss = directional.self_shadowed_bump(_ssbump_horizon(h, horizon, params), normal, pool=pool)
        bent = bent.result()
        timings["occlusion_s"] = time.perf_counter() - t2
    return Bake(params, horizon, normal, mean_cos, mean_cos2, timings, bent_normal=bent, ssbump=ss).checked()


def _ssbump_horizon(h: np.ndarray, horizon: np.ndarray, params: BakeParams) -> np.ndarray:
    """Return the horizons the self-shadowed bump map is made from.

    They are ``horizon`` itself without a lift, else the seed's sweep from origins raised by
    ``params.ssbump_lift`` texels (:class:`BakeParams`).
    """
    if params.ssbump_lift == 0.0:
        return horizon
    d = BakeParams()
    radius, angles = (params.radius, params.angles) if params.method == "seed" else (d.radius, d.angles)
    return horizon_map(
        h, radius, angles, params.boundary, directions=params.directions, lift=float(params.ssbump_lift)
    )[0]


def write_bake(result: Bake, out: str | Path, *, input_info: dict) -> list[Path]:
    """Write a bake's files into ``out`` (docs/ARCHITECTURE.md, ``hzval bake``), all or nothing.

    ``input_info`` describes the input (path, digest, source, shape) and goes
    into ``bake.json`` with the parameters, versions and timings. The
    horizon map goes into ``horizon0`` .. ``horizon{D/4 - 1}`` (``.exr`` and
    ``.png``), channels ``4 l .. 4 l + 3`` in layer ``l``; the weight cube
    map only for 8 directions (it holds Lengyel's 8 channel weights).
    """
    t0 = time.perf_counter()
    result.checked()
    layers = result.layers if result.horizon is not None else ()
    # the weight cube map holds Lengyel's 8 channel weights (2 RGBA layers):
    # a 16-direction map has no GPU cube path (hzval.techniques.horizon), so none is written
    full = result.horizon is not None
    cube = weight_cube() if full and result.directions == cv.CHANNEL_COUNT else None
    layers = layers if full else ()

    # Writing dominated a large bake, and compression gained little on horizon data: the outputs are
    # stored uncompressed, on a thread per core (the encoders release the GIL). docs/internals.md,
    # "Measurements the code rests on", has the figures.
    jobs = []

    def exr(name, channels):
        jobs.append(lambda: codecs.write_exr(stage.path(name), channels, atomic=False, compression="none"))

    def png(name, make, *args):
        jobs.append(lambda: codecs.write_png(stage.path(name), make(*args), atomic=False, compress_level=0))

    with staging.Staging(out) as stage:
        for i, layer in enumerate(layers):
            exr(f"horizon{i}.exr", {"RGBA": layer})
            png(f"horizon{i}.png", codecs.unit_to_u8, layer)
        exr("normal.exr", {"RGB": result.normal})
        png("normal.png", lambda n: codecs.unit_to_u8(0.5 + 0.5 * n), result.normal)
        if full:
            exr("ambient.exr", {"mean_cos": result.mean_cos, "mean_cos2": result.mean_cos2})
        if result.bent_normal is not None:
            exr("bent_normal.exr", {"RGB": result.bent_normal})
            png("bent_normal.png", lambda n: codecs.unit_to_u8(0.5 + 0.5 * n), result.bent_normal)
            exr("ssbump.exr", {"RGB": result.ssbump})
            png("ssbump.png", codecs.unit_to_u8, result.ssbump)
        if cube is not None:
            for i, face in enumerate(cube_layout.CUBE_FACES):
                png(f"cube/{face}.png", np.asarray, cube[i])
        codecs.run_writers(jobs)
        timings = dict(result.timings, write_s=time.perf_counter() - t0)
        digests = {
            p.relative_to(stage.dir).as_posix(): staging.file_digest(p)
            for p in sorted(stage.dir.rglob("*"))
            if p.is_file()
        }
        documents.write_json(
            stage.path("bake.json"),
            {
                "input": input_info,
                "contents": list(result.contents),
                "parameters": result.params.record() if full else _normal_record(result.params),
                **({"method": METHOD_NOTES[result.params.method]} if full else {}),
                "outputs": _output_notes(result.directions, full, result.bent_normal is not None),
                "conventions": "docs/ARCHITECTURE.md: +x right, +y up the image, "
                "azimuth counterclockwise from +x; "
                "heights in texel units are H * depth * cols",
                "timings_s": {k: round(v, 4) for k, v in timings.items()},
                "versions": backend.versions(),
                "files": digests,  # what cached_bake checks before it trusts the cache
            },
            atomic=False,
        )
        written = stage.commit()
    # a folder that held a bake with another number of directions keeps no
    # files of it that this bake.json does not describe (extra layers, a cube)
    stale = [
        f"horizon{i}.{ext}"
        for i in range(len(layers), cv.layer_count(max(cv.DIRECTION_COUNTS)))
        for ext in ("exr", "png")
    ] + ([] if full else ["ambient.exr"])
    if result.bent_normal is None:
        stale += ["bent_normal.exr", "bent_normal.png", "ssbump.exr", "ssbump.png"]
    if cube is None:
        stale += [f"cube/{face}.png" for face in cube_layout.CUBE_FACES]
    for name in stale:
        (Path(out) / name).unlink(missing_ok=True)
    if cube is None and (Path(out) / "cube").is_dir() and not any((Path(out) / "cube").iterdir()):
        (Path(out) / "cube").rmdir()
    return written


def _normal_record(params: BakeParams) -> dict:
    """``bake.json``'s parameters of a bake of the normal map alone: the horizon bake's are not its."""
    return {"depth": params.depth, "boundary": params.boundary}


def _output_notes(directions: int, full: bool = True, occluded: bool = True) -> dict:
    """Return ``bake.json``'s description of the files of a ``directions``-channel bake.

    With ``full``, the bake has the horizon and ambient maps, and with ``occluded`` also the directional
    occlusion; else it is the normal map alone.
    """
    n = cv.CHANNELS_PER_LAYER
    notes = {}
    if not full:
        return {"normal": "tangent-space unit normal (PNG: 0.5 + 0.5 n)"}
    for i in range(cv.layer_count(directions)):
        az = ", ".join(f"{cv.channel_azimuth_deg(c, directions):g}" for c in range(n * i, n * i + n))
        notes[f"horizon{i}"] = f"channels {n * i}-{n * i + n - 1} (azimuth {az} deg) as RGBA" + (
            ": sine of the horizon angle" if i == 0 else ""
        )
    notes["normal"] = "tangent-space unit normal (PNG: 0.5 + 0.5 n)"
    notes["ambient"] = "mean_cos (Lengyel) and mean_cos2 (cosine-weighted unoccluded fraction)"
    if occluded:
        notes["bent_normal"] = "cosine-weighted mean unoccluded direction, tangent space (PNG: 0.5 + 0.5 b)"
        notes["ssbump_map"] = (
            "Valve's self-shadowed bump map: max(0, n . b_c) times the open share about b_c, "
            "b_c Half-Life 2's basis, from horizons seen from ssbump_lift texels above the texel "
            "(docs/techniques.md)"
        )
    if directions == cv.CHANNEL_COUNT:
        notes["cube"] = (
            f"channel weights, {CUBE_SIZE}x{CUBE_SIZE} per face, OpenGL face order, 8-bit (w + 1) * 127.5"
        )
    else:
        notes["cube"] = (
            f"not written: the weight cube map holds {cv.CHANNEL_COUNT} channel weights; "
            f"{directions} directions use the analytic weights"
        )
    return notes


def read_bake(folder: str | Path) -> Bake:
    """Read a bake written by :func:`write_bake` back from its EXR files (exact float32).

    The number of horizon layers follows the recorded ``directions`` (8,
    i.e. ``horizon0``-``horizon1``, when ``bake.json`` predates it).
    """
    folder = Path(folder)
    record = json.loads((folder / "bake.json").read_text())
    params = BakeParams.from_record(BakeParams.normalise_record(record["parameters"]))
    if "horizon_map" not in record.get("contents", CONTENTS):
        n = codecs.read_exr(folder / "normal.exr")
        return Bake(
            params, None, np.stack([n[c] for c in "RGB"], axis=-1), None, None, dict(record["timings_s"])
        )
    layers = [codecs.read_exr(folder / f"horizon{i}.exr") for i in range(cv.layer_count(params.directions))]
    n, amb = codecs.read_exr(folder / "normal.exr"), codecs.read_exr(folder / "ambient.exr")
    horizon = np.stack([layer[c] for layer in layers for c in "RGBA"], axis=-1)
    normal = np.stack([n[c] for c in "RGB"], axis=-1)
    bent = ss = None
    if "bent_normal" in record.get("contents", CONTENTS):
        bent, ss = (
            np.stack([codecs.read_exr(folder / name)[c] for c in "RGB"], axis=-1)
            for name in ("bent_normal.exr", "ssbump.exr")
        )
    return Bake(
        params,
        horizon,
        normal,
        amb["mean_cos"],
        amb["mean_cos2"],
        dict(record["timings_s"]),
        bent_normal=bent,
        ssbump=ss,
    )


def cached_bake(
    height: np.ndarray,
    digest: str,
    params: BakeParams,
    folder: str | Path,
    input_info: dict,
    notices: list[str] | None = None,
    *,
    horizon: bool = True,
    occlusion: bool = True,
    write_to: str | Path | None = None,
) -> tuple[Bake, bool]:
    """Bake into ``folder``, or read the bake already there; return ``(bake, cached)``.

    The bake there is read if it was made from the same input (``digest``) with the same parameters, holds
    what is asked for (``horizon``: the horizon and ambient maps, and with ``occlusion`` the directional
    occlusion; else the normal map alone) and its files are intact.

    Every file of the cache must still have the SHA-256 that ``bake.json``
    recorded when it was written (:func:`write_bake`): a truncated or
    corrupted file, or a cache from before digests were recorded, is baked
    anew, with one line saying why appended to ``notices``. ``write_to``: where a new bake is
    written (default ``folder``): a sweep stages it, so that a failed run leaves the old bake.
    """
    folder = Path(folder)

    try:
        record = documents.read_json(folder / "bake.json")
        held = record.get("contents", CONTENTS)
        if horizon:
            wanted = CONTENTS if occlusion else _without_occlusion()
            same = (
                set(wanted) <= set(held)  # a bake from before a content was added is baked anew
                and BakeParams.normalise_record(record["parameters"]) == params.record()
            )
        else:  # any bake of the same surface holds its normal map
            same = {k: record["parameters"][k] for k in ("depth", "boundary")} == _normal_record(params)
        same = same and record["input"]["digest"] == digest
    except (InputError, ValueError, KeyError, TypeError, AttributeError):
        same = False  # no usable cache (a missing, damaged or hand-edited bake.json): bake anew
    if same:
        damaged = _damaged_file(folder, record.get("files"), staging.file_digest)
        if damaged is None:
            try:
                return read_bake(folder), True
            except (InputError, ValueError, KeyError, TypeError, AttributeError):
                damaged = str(folder / "bake.json")  # its files agree, its record does not: bake anew
        if notices is not None:
            notices.append(f"{damaged}: the cached bake is damaged; baked it anew")
    result = bake(height, params, horizon=horizon, occlusion=occlusion)
    write_bake(result, folder if write_to is None else write_to, input_info=input_info)
    return result, False


def _damaged_file(folder: Path, digests, digest_of) -> str | None:
    """Return the first cache file whose digest differs from the record (or is missing).

    It is ``None`` if all agree. A record without digests names ``bake.json`` itself.
    """
    if not isinstance(digests, dict) or not digests:
        return str(folder / "bake.json") + " (no file digests)"

    for name, want in digests.items():
        try:  # a name that leaves the bake's folder is damage too: nothing outside is read
            path = paths.inside(folder, name, folder / "bake.json", "files")
            if digest_of(path) != want:
                return str(path)
        except (InputError, OSError, TypeError):
            return str(folder / str(name))
    return None
