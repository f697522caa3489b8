"""Raudins' terrain shadows: a per-light sweep of the shadow-boundary height.

The third technique on the sweep. Source:
``shared/seeds/raudins-terrain-horizon-mapping.txt`` (Glenn Raudins,
"Horizon Mapping: Fast Terrain Lighting"): for the current sun position, one
sweep across the height map "maintains a horizon contour" and stores, per
texel, the *height of the shadow boundary*; a fragment program compares the
pixel's own height with it (hard shadows), and the soft version ramps
between lit and shadowed "when the pixel height was within a specific range
of the shadow height" with "a clamped linear expression". Unlike the horizon
map it is recomputed for every light (that cost is the point of the
comparison) and needs only the height map.

The design in full: docs/internals.md, "hzval.techniques.terrain".
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from typing_extensions import override

from hzval.core import backend
from hzval.core import conventions as cv
from hzval.core.backend import dr, mi  # Dr.Jit loads at first use, once the LLVM is chosen
from hzval.core.errors import InputError
from hzval.scene import lookup
from hzval.scene.spec import Frame, Scene, image_shape
from hzval.techniques import surface
from hzval.techniques.registry import Variant

__all__ = [
    "TerrainShadow",
    "SweepPlan",
    "plan_sweep",
    "boundaries_numpy",
    "factor_numpy",
    "DEFAULT_RAMP",
    "FLOOR_ELEVATION_DEG",
    "MAX_ELEVATION_DEG",
    "MAX_PRIME_TILES",
    "IMPLS",
]

#: Extra ramp width ``r`` in texel height units (module docstring).
DEFAULT_RAMP = 0.02
#: Floor of the soft light's lower elevation ``e - rho``, degrees: at 0 the
#: contour would never fall and a wrap sweep would never end. (Not the
#: truth's wrap-margin elevation, :data:`hzval.geometry.tile.MIN_ELEVATION_DEG`.)
FLOOR_ELEVATION_DEG = 0.05
#: Cap of ``e + rho``, degrees (``tan`` stays finite).
MAX_ELEVATION_DEG = 89.9
#: Most tile lengths a ``wrap`` sweep primes before it records.
MAX_PRIME_TILES = 64
#: The two implementations of the sweep.
IMPLS: tuple[str, ...] = ("drjit", "numpy")
#: "Nothing here": finite (so that differences of it stay 0, not NaN) and far
#: below any height, so that it loses every max and lights what it bounds.
NOTHING = -1.0e30
#: Effects the technique does not model: interreflection, as the horizon map,
#: and the horizon map's own reflection fade.
NOT_MODELLED: tuple[str, ...] = ("interreflection", "reflection_occlusion")


# --------------------------------------------------------------------------
# Geometry of one light's sweep
# --------------------------------------------------------------------------


@dataclass(frozen=True)
class SweepPlan:
    """How the sweep walks the map for one light (module docstring, "Lines").

    The sweep runs on the array ``A`` (``n`` scanlines of ``m`` texels):
    the height map, transposed when the light's azimuth is closer to the
    y axis, and flipped so that the light is toward column 0 of ``A``: the
    up-light neighbour of ``A``'s column ``c`` is column ``c - 1``.
    ``A[i, c]`` is ``H.flat[off + i * si + c * sj]``. Line ``l`` (lane,
    ``0 <= l < lanes``) is at row ``l + first + j * slope`` of ``A`` at step
    ``j``; step ``j`` is column ``j`` (``open``) or ``j mod m`` (``wrap``),
    recorded for ``j >= steps - m``. ``step``: texels along the ray per step.
    """

    n: int
    m: int
    off: int
    si: int
    sj: int
    slope: float
    step: float
    lanes: int
    first: int
    steps: int
    wrap: bool

    @property
    def record_from(self) -> int:
        """Return the first step whose column is recorded, ``steps - m`` (the class docstring)."""
        return self.steps - self.m

    def step_of_column(self, c: np.ndarray) -> np.ndarray:
        """Return the recording step ``j`` of ``A``'s column ``c``."""
        if not self.wrap:
            return c
        r0 = self.record_from
        return r0 + np.mod(c - r0, self.m)


def plan_sweep(
    rows: int, cols: int, azimuth_deg: float, boundary: str, *, relief: float = 0.0, tan_low: float = 1.0
) -> SweepPlan:
    """How Raudins' sweep crosses a map for one light.

    Parameters
    ----------
    rows, cols : int
        The map's size.
    azimuth_deg : float
        The light's azimuth.
    boundary : {"wrap", "open"}
    relief : float
        ``max h - min h`` in texels.
    tan_low : float
        Tangent of the lowest elevation the sweep traces: ``wrap`` primes
        ``ceil(relief / (tan_low * step)) + 1`` steps, at most :data:`MAX_PRIME_TILES` tiles.

    Returns
    -------
    SweepPlan
    """
    if boundary not in cv.BOUNDARIES:
        raise ValueError(f"unknown boundary {boundary!r}")
    phi = math.radians(azimuth_deg)
    drow, dcol = cv.tangent_to_pixel_offset(math.cos(phi), math.sin(phi))  # toward the light, per texel
    if abs(dcol) >= abs(drow):
        n, m, major, minor = rows, cols, dcol, drow
        si = cols
        sj, off = (1, 0) if major < 0 else (-1, cols - 1)
    else:
        n, m, major, minor = cols, rows, drow, dcol
        si = 1
        sj, off = (cols, 0) if major < 0 else (-cols, (rows - 1) * cols)
    # down-light, one column of A moves the ray by -minor/|major| scanlines
    slope = -minor / abs(major)
    # cos and sin of an axis azimuth are 1e-16, not 0: a slope that small would
    # start the open sweep one line early and mix in that line's "nothing"
    slope = 0.0 if abs(slope) < 1e-12 else slope
    step = 1.0 / abs(major)
    wrap = boundary == "wrap"
    if wrap:
        prime = 0
        if relief > 0:
            prime = min(math.ceil(relief / (tan_low * step)) + 1, MAX_PRIME_TILES * m)
        lanes, first, steps = n, 0, prime + m
    else:
        # enough lines that two bracket every scanline at every column
        first = math.floor(-(m - 1) * max(slope, 0.0))
        lanes = n + math.ceil((m - 1) * abs(slope)) + 2
        steps = m
    return SweepPlan(n, m, off, si, sj, slope, step, lanes, first, steps, wrap)


# --------------------------------------------------------------------------
# NumPy reference
# --------------------------------------------------------------------------


def _line_heights_numpy(A: np.ndarray, y: np.ndarray, col: int, wrap: bool) -> np.ndarray:
    """Heights of ``A``'s column ``col`` at fractional scanline positions ``y`` (linear)."""
    n = A.shape[0]
    if wrap:
        yw = np.mod(y, n)
        r0 = np.minimum(np.floor(yw).astype(np.int64), n - 1)
        f = yw - r0
        r1 = (r0 + 1) % n
        return A[r0, col] * (1 - f) + A[r1, col] * f
    yc = np.clip(y, 0, n - 1)
    r0 = np.floor(yc).astype(np.int64)
    f = yc - r0
    r1 = np.minimum(r0 + 1, n - 1)
    h = A[r0, col] * (1 - f) + A[r1, col] * f
    inside = (y >= -0.5) & (y <= n - 0.5)  # the open mesh's half-texel skirt
    return np.where(inside, h, NOTHING)


def boundaries_numpy(
    h: np.ndarray, plan: SweepPlan, tan_hi_el: float, tan_lo_el: float
) -> tuple[np.ndarray, np.ndarray]:
    """Return the shadow boundaries of every texel, in NumPy (the reference for the Dr.Jit sweep).

    Parameters
    ----------
    h : numpy.ndarray
        ``(rows, cols)`` heights in texels.
    plan : SweepPlan
        :func:`plan_sweep`'s.
    tan_hi_el, tan_lo_el : float
        Tangents of the elevations of ``B_hi`` (the lower one, ``e - rho``) and of ``B_lo``.

    Returns
    -------
    tuple of numpy.ndarray
        ``(B_hi, B_hi - B_lo)``, each ``(rows, cols)`` float64.
    """
    h = np.asarray(h, dtype=np.float64)
    flat = h.ravel()
    i, c = np.mgrid[0 : plan.n, 0 : plan.m]
    A = flat[plan.off + i * plan.si + c * plan.sj]
    lane = np.arange(plan.lanes, dtype=np.float64) + plan.first
    drop_hi, drop_lo = tan_hi_el * plan.step, tan_lo_el * plan.step
    mx_hi = np.full(plan.lanes, NOTHING)
    mx_lo = np.full(plan.lanes, NOTHING)
    rec_hi = np.empty((plan.m, plan.lanes))
    rec_w = np.empty((plan.m, plan.lanes))
    for j in range(plan.steps):
        b_hi, b_lo = mx_hi - drop_hi, mx_lo - drop_lo
        col = j % plan.m if plan.wrap else j
        if j >= plan.record_from:
            rec_hi[col], rec_w[col] = b_hi, b_hi - b_lo
        hj = _line_heights_numpy(A, lane + j * plan.slope, col, plan.wrap)
        mx_hi, mx_lo = np.maximum(hj, b_hi), np.maximum(hj, b_lo)
    # texel (i, c) of A lies between lines l0 and l0 + 1
    jr = plan.step_of_column(c)
    u = i - jr * plan.slope - plan.first
    l0 = np.floor(u).astype(np.int64)
    f = u - l0
    if plan.wrap:
        l0 %= plan.lanes
        l1 = (l0 + 1) % plan.lanes
    else:
        l0 = np.clip(l0, 0, plan.lanes - 2)
        l1 = l0 + 1
    b0, b1 = rec_hi[c, l0], rec_hi[c, l1]
    # a line that saw nothing (open) does not dilute its neighbour's boundary
    b0, b1 = np.where(b0 <= NOTHING / 2, b1, b0), np.where(b1 <= NOTHING / 2, b0, b1)
    b = b0 * (1 - f) + b1 * f
    w = rec_w[c, l0] * (1 - f) + rec_w[c, l1] * f
    B, W = np.empty(h.size), np.empty(h.size)
    idx = plan.off + i * plan.si + c * plan.sj
    B[idx], W[idx] = b, w
    return B.reshape(h.shape), W.reshape(h.shape)


def factor_numpy(
    gap: np.ndarray,
    ramp: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    boundary: str,
    spp: int,
    shape: tuple[int, int],
) -> np.ndarray:
    """Pixel means of the terrain factor ``F = clamp(gap / ramp + 1, 0, 1)`` at samples.

    Parameters
    ----------
    gap, ramp : numpy.ndarray
        ``(rows, cols)`` per texel: ``h - B_hi`` and the ramp, filtered bilinearly between texel
        centres (``wrap`` repeats, ``open`` clamps).
    x, y : numpy.ndarray
        Sample positions in tangent texel units, pixel-major with ``spp`` samples a pixel
        (:func:`hzval.scene.camera.sample_positions`).
    boundary : {"wrap", "open"}
    spp : int
    shape : tuple of int
        ``(H, W)``.

    Returns
    -------
    numpy.ndarray
        ``shape`` float32.
    """
    rows, cols = gap.shape
    cx = np.asarray(x, np.float64) - 0.5
    ry = rows - np.asarray(y, np.float64) - 0.5
    c0, r0 = np.floor(cx).astype(np.int64), np.floor(ry).astype(np.int64)
    fx, fy = cx - c0, ry - r0
    if boundary == "wrap":
        c0, r0 = c0 % cols, r0 % rows
        c1, r1 = (c0 + 1) % cols, (r0 + 1) % rows
    else:
        c1, r1 = np.clip(c0 + 1, 0, cols - 1), np.clip(r0 + 1, 0, rows - 1)
        c0, r0 = np.clip(c0, 0, cols - 1), np.clip(r0, 0, rows - 1)

    def bilinear(t):
        top = t[r0, c0] * (1 - fx) + t[r0, c1] * fx
        bottom = t[r1, c0] * (1 - fx) + t[r1, c1] * fx
        return top * (1 - fy) + bottom * fy

    F = np.clip(bilinear(gap) / bilinear(ramp) + 1.0, 0.0, 1.0)
    return F.reshape(-1, spp).mean(axis=1).reshape(shape).astype(np.float32)


# --------------------------------------------------------------------------
# The technique
# --------------------------------------------------------------------------


class TerrainShadow(surface.HeightFieldShadow):
    """Raudins' per-light terrain shadows of one material, frame by frame: the ``terrain`` technique.

    Parameters
    ----------
    scene
        Camera, light (elevation, kind, radius), declared effects, samples:
        the same as the truth's and the horizon map's.
    height
        The height map ``(rows, cols)`` in [0, 1] (``load_material_height(...).height``);
        ``scene.material.depth`` scales it to texels.
    bake
        The material's :class:`hzval.bake.maps.Bake` for the unshadowed shading
        (normal map, ambient map); ``None`` computes the normal map only
        (:func:`hzval.bake.maps.normals_only`), which serves ``diffuse`` and
        ``specular``; ``ambient`` needs a bake.
    albedo
        Linear albedo ``(rows, cols, 3)``; ``None`` reads the scene's.
    ramp
        ``r`` of the factor, texel height units, > 0 (:data:`DEFAULT_RAMP`).
    impl
        ``"drjit"`` (default) or ``"numpy"`` (the reference).
    unshadowed
        The :class:`hzval.techniques.surface.Unshadowed` shading to multiply (a sweep
        shares one between its techniques); by default one is built.

    Attributes: ``simulated`` (effects computed, :data:`hzval.scene.spec.EFFECTS`
    order), ``shape`` (image shape), ``parameters`` (for ``metrics.json``).
    """

    name = "terrain"
    label = "terrain shadows"
    summary = "Raudins' terrain shadows: a per-light sweep of the shadow-boundary height"
    file_stem = "terrain"
    not_modelled = NOT_MODELLED
    not_on_models = (
        "Raudins' sweep runs along lines of one light direction across the whole map (a terrain "
        "under the sun); on a model every sample's tangent-space light is its own"
    )

    def __init__(
        self,
        scene: Scene,
        height: np.ndarray,
        *,
        bake=None,
        albedo: np.ndarray | None = None,
        ramp: float = DEFAULT_RAMP,
        impl: str = "drjit",
        unshadowed: surface.Unshadowed | None = None,
        samples=None,
    ):
        backend.variant()
        if impl not in IMPLS:
            raise InputError("impl", f"must be one of {', '.join(IMPLS)}, got {impl!r}")
        self.check_settings(None, {"ramp": ramp})
        height = np.asarray(height, dtype=np.float32)
        if height.ndim != 2:
            raise InputError("height", f"expected a (rows, cols) height map, got shape {height.shape}")
        boundary = scene.material.boundary
        if bake is not None and bake.params.boundary != boundary:
            raise InputError("bake", f"baked for boundary {bake.params.boundary}, the scene says {boundary}")
        self.scene, self.ramp, self.impl, self.boundary = scene, float(ramp), impl, boundary
        self.rows, self.cols = rows, cols = height.shape
        self.shape = image_shape(rows, cols, scene.camera)
        self.h = cv.heights_in_texels(height, scene.material.depth).astype(np.float64)
        self.relief = float(self.h.max() - self.h.min())
        self.simulated = self.simulates(scene)
        self._shadow = "shadow" in self.simulated
        samples = samples if samples is not None else lookup.samples_for(scene, rows, cols, height)
        self._unshadowed = self.shading_for(scene, height, bake, albedo, unshadowed, samples)
        self._upload_samples(samples)

    def _upload_samples(self, samples) -> None:
        """Upload the scene's sample positions, as the truth and the horizon map use them."""
        scene = self.scene
        self.spp = int(scene.spp)
        x, y = samples.x, samples.y
        self._x = self._y = None
        if self.impl != "drjit":
            self._x, self._y = x, y
        else:
            self._h_dr = mi.Float(self.h.astype(np.float32).ravel())
            self._xy = lookup.interleaved(x, y)
            self._r_dr = dr.opaque(mi.Float, self.ramp)
            dr.eval(self._h_dr, self._xy)

    # -- the Technique interface (hzval.techniques.registry) --------------------------

    @classmethod
    @override
    def add_arguments(cls, parser) -> None:
        parser.add_argument(
            "--terrain-ramp",
            type=float,
            default=DEFAULT_RAMP,
            metavar="TEXELS",
            help=f"terrain shadows: extra ramp width in texel heights (default {DEFAULT_RAMP:g})",
        )

    #: The command line's flag of each setting (errors name the flag,
    # :func:`hzval.techniques.registry.flag_errors`).
    flags = {"ramp": "--terrain-ramp"}

    @classmethod
    @override
    def settings_from_args(cls, args) -> dict:
        return {"ramp": args.terrain_ramp}

    @classmethod
    @override
    def check_settings(cls, bake_params, settings: dict) -> None:
        ramp = settings.get("ramp", DEFAULT_RAMP)
        if isinstance(ramp, bool) or not (
            isinstance(ramp, (int, float)) and math.isfinite(ramp) and ramp > 0
        ):
            raise InputError("ramp", f"the terrain ramp must be a positive number of texels, got {ramp}")

    @classmethod
    @override
    def tradeoff_variants(cls) -> list[Variant]:
        return [Variant("terrain shadow map (Raudins)", params={"ramp_texels": DEFAULT_RAMP})]

    def storage_bytes(self) -> int:
        """Return the height map alone, 16-bit: the boundary is recomputed per light."""
        return self.rows * self.cols * 2

    @property
    def parameters(self) -> dict:
        """The technique's settings, for ``metrics.json``."""
        return {
            "technique": "terrain shadow boundary (Raudins)",
            "ramp_texels": self.ramp,
            "impl": self.impl,
            "light": self.scene.light.kind,
            "simulated": list(self.simulated),
        }

    # ------------------------------------------------------------------

    def elevations(self, elevation_deg: float) -> tuple[float, float]:
        """Elevations of ``(B_hi, B_lo)`` in degrees: ``e -+ rho`` for a soft light, else ``(e, e)``."""
        rho = self.scene.light.radius_deg if self.scene.light.kind == "soft" else 0.0
        lo = min(max(elevation_deg - rho, FLOOR_ELEVATION_DEG), MAX_ELEVATION_DEG)
        hi = min(max(elevation_deg + rho, FLOOR_ELEVATION_DEG), MAX_ELEVATION_DEG)
        return lo, hi

    def plan(self, azimuth_deg: float, elevation_deg: float) -> SweepPlan:
        """Return the sweep's plan for the light at ``azimuth_deg``, ``elevation_deg``."""
        low, _ = self.elevations(elevation_deg)
        return plan_sweep(
            self.rows,
            self.cols,
            azimuth_deg,
            self.boundary,
            relief=self.relief,
            tan_low=math.tan(math.radians(low)),
        )

    def factor(self, azimuth_deg: float, elevation_deg: float | None = None) -> np.ndarray:
        """Return the pixel means of the terrain factor ``F``, ``shape`` float32 in [0, 1]."""
        e = self.scene.light.elevation_deg if elevation_deg is None else float(elevation_deg)
        if e >= 90.0:
            return np.ones(self.shape, np.float32)
        if e <= 0.0:
            return np.zeros(self.shape, np.float32)
        el_hi, el_lo = self.elevations(e)
        plan = self.plan(azimuth_deg, e)
        t_hi, t_lo = math.tan(math.radians(el_hi)), math.tan(math.radians(el_lo))
        if self.impl == "numpy":
            B, W = boundaries_numpy(self.h, plan, t_hi, t_lo)
            return factor_numpy(
                self.h - B, W + self.ramp, self._x, self._y, self.boundary, self.spp, self.shape
            )
        return self._factor_drjit(plan, t_hi, t_lo)

    def render(self, azimuth_deg: float, *, elevation_deg: float | None = None) -> Frame:
        """Render the frame for the light at ``azimuth_deg`` (degrees).

        Layers: ``factor`` (pixel mean of ``F``, when ``shadow`` is
        declared) and the unshadowed render's others. ``seconds``: the
        frame's wall time, kernels synchronised, the unshadowed shading's
        included (an engine pays for it too, whoever rendered it first).
        """
        t0 = time.perf_counter()
        e = self.scene.light.elevation_deg if elevation_deg is None else float(elevation_deg)
        if not self._shadow:
            frame, _ = self._unshadowed.render(azimuth_deg, e)
            return frame
        F = self.factor(azimuth_deg, e)
        return self._unshadowed.shade(azimuth_deg, e, F, time.perf_counter() - t0)

    # ------------------------------------------------------------------
    # Dr.Jit
    # ------------------------------------------------------------------

    def _factor_drjit(self, plan: SweepPlan, tan_hi: float, tan_lo: float) -> np.ndarray:
        """Return the per-pixel factor from three kernels; every per-frame value is opaque.

        The kernels are the sweep (one lane per line, a symbolic loop over steps), the texels' ``(h - B_hi,
        ramp)``, and the samples' factor averaged per pixel.
        """
        rec = self._sweep_drjit(plan, tan_hi, tan_lo)
        F = self._sample(self._gap_ramp_drjit(plan, rec))
        return np.asarray(F, dtype=np.float32).reshape(self.shape)

    @staticmethod
    def _plan_constants(plan: SweepPlan) -> dict:
        """Return the plan's numbers as opaque Dr.Jit values (one kernel for every light and map)."""
        op, Float, Int32 = dr.opaque, mi.Float, mi.Int32
        return {
            "n": op(Int32, plan.n),
            "m": op(Int32, plan.m),
            "off": op(Int32, plan.off),
            "si": op(Int32, plan.si),
            "sj": op(Int32, plan.sj),
            "slope": op(Float, plan.slope),
            "first": op(Int32, plan.first),
            "steps": op(Int32, plan.steps),
            "rec0": op(Int32, plan.record_from),
            "n_lanes": op(Int32, plan.lanes),
        }

    def _sweep_drjit(self, plan: SweepPlan, tan_hi: float, tan_lo: float):
        """Return the sweep: per line and recorded column, ``(B_hi, B_hi - B_lo)`` pairs."""
        Float, Int32, UInt32 = mi.Float, mi.Int32, mi.UInt32
        op = dr.opaque
        k = self._plan_constants(plan)
        n, m, off, si, sj = k["n"], k["m"], k["off"], k["si"], k["sj"]
        slope, first, steps, rec0, n_lanes = k["slope"], k["first"], k["steps"], k["rec0"], k["n_lanes"]
        drop_hi, drop_lo = op(Float, tan_hi * plan.step), op(Float, tan_lo * plan.step)
        nl = plan.lanes
        wrap = plan.wrap
        h = self._h_dr
        rec = dr.zeros(Float, 2 * nl * plan.m)
        lane = dr.arange(Int32, nl)
        nf = Float(n)

        def line_height(j, col):
            y = Float(lane + first) + Float(j) * slope
            if wrap:
                yw = y - nf * dr.floor(y / nf)
                r0 = dr.minimum(Int32(dr.floor(yw)), n - 1)
                f = yw - Float(r0)
                r1 = dr.select(r0 + 1 >= n, 0, r0 + 1)
            else:
                yc = dr.clip(y, 0.0, nf - 1.0)
                r0 = Int32(dr.floor(yc))
                f = yc - Float(r0)
                r1 = dr.minimum(r0 + 1, n - 1)
            base = off + col * sj
            h0 = dr.gather(Float, h, UInt32(base + r0 * si))
            h1 = dr.gather(Float, h, UInt32(base + r1 * si))
            hv = dr.fma(h1 - h0, f, h0)
            if not wrap:
                hv = dr.select((y >= -0.5) & (y <= nf - 0.5), hv, NOTHING)
            return hv

        # the column is carried, not computed as j mod m: SIMD has no integer division
        def body(j, col, mx_hi, mx_lo):
            b_hi, b_lo = mx_hi - drop_hi, mx_lo - drop_lo
            slot = UInt32((col * n_lanes + lane) * 2)
            active = j >= rec0
            dr.scatter(rec, b_hi, slot, active)
            dr.scatter(rec, b_hi - b_lo, slot + 1, active)
            hv = line_height(j, col)
            col = dr.select(col + 1 >= m, 0, col + 1)
            return j + 1, col, dr.maximum(hv, b_hi), dr.maximum(hv, b_lo)

        zero = dr.zeros(Int32, nl)
        dr.while_loop(
            state=(zero, Int32(zero), dr.full(Float, NOTHING, nl), dr.full(Float, NOTHING, nl)),
            cond=lambda j, col, a, b: j < steps,
            body=body,
        )
        dr.eval(rec)
        return rec

    def _gap_ramp_drjit(self, plan: SweepPlan, rec):
        """Return the texels of ``A``, written to the height map's layout as ``(gap, ramp)`` pairs.

        The boundary is interpolated between the two lines that bracket each texel.
        """
        Float, Int32, UInt32 = mi.Float, mi.Int32, mi.UInt32
        op = dr.opaque
        k = self._plan_constants(plan)
        m, off, si, sj = k["m"], k["off"], k["si"], k["sj"]
        slope, first, rec0, n_lanes = k["slope"], k["first"], k["rec0"], k["n_lanes"]
        wrap, h = plan.wrap, self._h_dr
        # no integer division: float quotient, then corrected
        N = plan.n * plan.m
        t = dr.arange(Int32, N)
        i = Int32(dr.floor((Float(t) + 0.5) / Float(m)))
        c = t - i * m
        i, c = (
            dr.select(c < 0, i - 1, dr.select(c >= m, i + 1, i)),
            dr.select(c < 0, c + m, dr.select(c >= m, c - m, c)),
        )
        if wrap:  # the recording step of column c: rec0 + ((c - rec0) mod m)
            k0 = op(Int32, plan.record_from % plan.m)
            jr = rec0 + (c - k0) + dr.select(c < k0, m, 0)
        else:
            jr = c
        u = Float(i) - Float(jr) * slope - Float(first)
        if wrap:
            nlf = Float(n_lanes)
            u = u - nlf * dr.floor(u / nlf)
        l0 = Int32(dr.floor(u))
        f = u - Float(l0)
        if wrap:
            l0 = dr.clip(l0, 0, n_lanes - 1)
            l1 = dr.select(l0 + 1 >= n_lanes, 0, l0 + 1)
        else:
            l0 = dr.clip(l0, 0, n_lanes - 2)
            l1 = l0 + 1
        p0 = dr.gather(mi.Vector2f, rec, UInt32(c * n_lanes + l0))
        p1 = dr.gather(mi.Vector2f, rec, UInt32(c * n_lanes + l1))
        hidx = UInt32(off + i * si + c * sj)
        # a line that saw nothing (open) does not dilute its neighbour's boundary
        b0 = dr.select(p0.x <= NOTHING / 2, p1.x, p0.x)
        b1 = dr.select(p1.x <= NOTHING / 2, p0.x, p1.x)
        b = dr.fma(b1 - b0, f, b0)
        w = dr.fma(p1.y - p0.y, f, p0.y)
        gap_ramp = dr.zeros(Float, 2 * N)
        dr.scatter(gap_ramp, dr.gather(Float, h, hidx) - b, hidx * 2)
        dr.scatter(gap_ramp, w + self._r_dr, hidx * 2 + 1)
        dr.eval(gap_ramp)
        return gap_ramp

    def _sample(self, gap_ramp):
        """Pixel means of ``clamp(gap / ramp + 1, 0, 1)`` over the pixel's samples (bilinear)."""
        Float, Int32, UInt32 = mi.Float, mi.Int32, mi.UInt32
        rows, cols = self.rows, self.cols
        R, C = dr.opaque(Int32, rows), dr.opaque(Int32, cols)
        wrap = self.boundary == "wrap"
        P = self.shape[0] * self.shape[1]
        spp = self.spp
        pixel = dr.arange(UInt32, P)

        def fetch(r, c):
            return dr.gather(mi.Vector2f, gap_ramp, UInt32(r * C + c))

        def body(k, acc):
            p = dr.gather(mi.Point2f, self._xy, pixel * spp + k)
            cx = p.x - 0.5
            ry = Float(R) - p.y - 0.5
            fc, fr = dr.floor(cx), dr.floor(ry)
            fx, fy = cx - fc, ry - fr
            c0, r0 = Int32(fc), Int32(fr)
            if wrap:
                c0 = dr.select(c0 < 0, c0 + C, dr.select(c0 >= C, c0 - C, c0))
                r0 = dr.select(r0 < 0, r0 + R, dr.select(r0 >= R, r0 - R, r0))
                c1 = dr.select(c0 + 1 >= C, 0, c0 + 1)
                r1 = dr.select(r0 + 1 >= R, 0, r0 + 1)
            else:
                c1, r1 = dr.clip(c0 + 1, 0, C - 1), dr.clip(r0 + 1, 0, R - 1)
                c0, r0 = dr.clip(c0, 0, C - 1), dr.clip(r0, 0, R - 1)
            top = dr.lerp(fetch(r0, c0), fetch(r0, c1), fx)
            bottom = dr.lerp(fetch(r1, c0), fetch(r1, c1), fx)
            v = dr.lerp(top, bottom, fy)
            return k + 1, acc + dr.clip(v.x / v.y + 1.0, 0.0, 1.0)

        _, acc = dr.while_loop(
            state=(dr.zeros(UInt32, P), dr.zeros(Float, P)), cond=lambda k, acc: k < spp, body=body
        )
        return acc * (1.0 / spp)
