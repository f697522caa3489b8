"""Ray-marched height-field shadows, as parallax occlusion mapping casts them: the ``pom`` technique.

The fourth technique on the sweep, and the one engines weigh horizon
mapping against: instead of a baked horizon, each shaded point marches the
height map toward the light (Tatarchuk 2006, "Dynamic parallax occlusion
mapping with approximate soft shadows", ACM I3D; engines' screen-space
contact shadows march the depth buffer the same way). It needs only the
height map, like the terrain technique, but it is evaluated per pixel and
per light with no per-light precomputation, so its cost is its step count.

The design in full: docs/internals.md, "hzval.techniques.pom".
"""

from __future__ import annotations

import math
import time

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
    "RayMarchShadow",
    "VARIANTS",
    "DEFAULT_STEPS",
    "DEFAULT_SOFTNESS",
    "TRADEOFF_STEPS",
    "SKIP_RADIUS",
    "SkipTable",
]

#: The two shadow tests (module docstring).
VARIANTS: tuple[str, ...] = ("hard", "soft")
#: Linear steps of the march in a sweep. On the 512 x 512 bricks (hard light
#: at 30 degrees, 16 spp) |F - V| is 0.0465, 0.0255, 0.0159, 0.0119 and
#: 0.0104 at 4, 8, 16, 32 and 64 steps, for 2.0x, 2.7x, 6.1x, 9.2x and 18x the
#: horizon map's frame time: 32 is within 15% of 64's error at half its cost
#: (``benchmarks/bench_pom.py``).
DEFAULT_STEPS = 32
#: Tatarchuk's softness ``w`` for a hard light: a blocker 1/8 radian (7
#: degrees) above the ray casts full shadow.
DEFAULT_SOFTNESS = 8.0
#: How far, per texel of height, a sample must rise above the ray to block it:
#: bilinear filtering of a flat patch returns its height to a few float32 ulps
#: either side, which must not shadow it (32 ulps of the heights).
EPSILON_PER_HEIGHT = 2.0**-18
#: The step counts ``hzval tradeoff`` measures.
TRADEOFF_STEPS: tuple[int, ...] = (4, 8, 16, 32, 64)


def set_up_march(
    tech,
    scene: Scene,
    height: np.ndarray,
    steps: int,
    variant: str | None,
    softness,
    bake,
    albedo,
    unshadowed,
    samples,
):
    """Set up what every ray march of the height map sets up (this module's, and a GL shader's).

    Its settings are checked and kept on ``tech``; the image's shape, the heights in texels, their
    maximum and the unshadowed shading it multiplies are made.

    Parameters
    ----------
    tech : object
        The technique being built; the settings are kept on it.
    scene : hzval.scene.spec.Scene
        The scene.
    height : numpy.ndarray
        ``(rows, cols)`` the normalised height map.
    steps : int
        March steps.
    variant : str or None
        ``hard`` or ``soft`` (``None``: soft for a soft light).
    softness : float or None
        The soft variant's ``1 / tan(radius)`` (``None``: the light's).
    bake, albedo, unshadowed, samples
        The context's bake, albedo, shared unshadowed shading and sample positions.

    Returns
    -------
    tuple
        ``(heights in texels, samples)``.
    """
    variant = variant or ("soft" if scene.light.kind == "soft" else "hard")
    if softness is None:
        softness = (
            1.0 / math.tan(math.radians(scene.light.radius_deg))
            if scene.light.kind == "soft"
            else DEFAULT_SOFTNESS
        )
    _validate(steps, variant, softness)
    height = np.asarray(height, dtype=np.float32)
    if height.ndim != 2:
        raise InputError("height", f"expected a (rows, cols) height map, got shape {height.shape}")
    tech.scene, tech.steps, tech.variant, tech.softness = scene, int(steps), variant, float(softness)
    tech.rows, tech.cols = height.shape
    tech.shape = image_shape(tech.rows, tech.cols, scene.camera)
    tech.simulated = tech.simulates(scene)
    h = cv.heights_in_texels(height, scene.material.depth)
    tech.h_max = float(h.max())
    samples = samples if samples is not None else lookup.samples_for(scene, tech.rows, tech.cols, height)
    tech._unshadowed = tech.shading_for(scene, height, bake, albedo, unshadowed, samples)
    return h, samples


class RayMarchShadow(surface.HeightFieldShadow):
    """Per-pixel height-field ray marching toward the light, frame by frame: the ``pom`` technique.

    Parameters: ``scene`` and ``height`` (normalised ``(rows, cols)``) as
    :class:`hzval.techniques.terrain.TerrainShadow`; ``steps`` (``N``, >= 1);
    ``variant`` (``"hard"`` or ``"soft"``; default ``"soft"`` for a soft
    light, else ``"hard"``); ``softness`` (``w`` of the soft variant, > 0;
    default from the light, module docstring); ``bake``, ``albedo``,
    ``unshadowed`` for the shading, as the terrain technique takes them.
    """

    name = "pom"
    label = "ray-marched shadows"
    summary = "parallax occlusion mapping's shadows: N linear steps through the height map toward the light"
    file_stem = "pom"
    not_modelled = ("interreflection", "reflection_occlusion")

    def __init__(
        self,
        scene: Scene,
        height: np.ndarray,
        *,
        steps: int = DEFAULT_STEPS,
        variant: str | None = None,
        softness: float | None = None,
        bake=None,
        albedo: np.ndarray | None = None,
        unshadowed: surface.Unshadowed | None = None,
        samples=None,
    ):
        backend.variant()
        h, samples = set_up_march(
            self, scene, height, steps, variant, softness, bake, albedo, unshadowed, samples
        )
        self._upload(h, samples)

    def _upload(self, h: np.ndarray, samples) -> None:
        """Upload the height texture (texel units) and the samples' texture coordinates, once."""
        scene = self.scene
        wrap = dr.WrapMode.Repeat if scene.material.boundary == "wrap" else dr.WrapMode.Clamp
        # float32 filtering on every backend (CUDA's texture units resolve a texel to 1/256)
        self._height = mi.Texture2f(
            mi.TensorXf(np.ascontiguousarray(h[..., None], np.float32)),
            use_accel=False,
            migrate=False,
            filter_mode=dr.FilterMode.Linear,
            wrap_mode=wrap,
        )
        self.spp = int(scene.spp)
        self._uv = samples.uv()  # shared
        self._frames, self._macro = samples.frame_array(), samples.macro  # a model's (lookup.Samples)
        self._skip = None if SKIP_RADIUS is None else SkipTable(h, SKIP_RADIUS, scene.material.boundary)
        self._c = {
            "steps": dr.opaque(mi.UInt32, self.steps),
            "w": dr.opaque(mi.Float, self.softness),
            "h_max": dr.opaque(mi.Float, self.h_max),
            "eps": dr.opaque(mi.Float, EPSILON_PER_HEIGHT * max(1.0, abs(self.h_max))),
        }
        dr.eval(self._uv)

    # -- the Technique interface (hzval.techniques.registry) --------------------------

    @classmethod
    @override
    def add_arguments(cls, parser) -> None:
        parser.add_argument(
            "--pom-steps",
            type=int,
            default=DEFAULT_STEPS,
            metavar="N",
            help=f"ray-marched shadows: linear steps toward the light (default {DEFAULT_STEPS})",
        )
        parser.add_argument(
            "--pom-variant",
            choices=VARIANTS,
            default=None,
            help="ray-marched shadows: hard test, or Tatarchuk's soft penumbra "
            "(default: soft for a soft light, else hard)",
        )
        parser.add_argument(
            "--pom-softness",
            type=float,
            default=None,
            metavar="W",
            help=f"ray-marched shadows: softness w of the soft variant (default {DEFAULT_SOFTNESS:g}, "
            "or 1 / tan(light radius) for a soft light)",
        )

    #: The command line's flag of each setting (errors name the flag,
    # :func:`hzval.techniques.registry.flag_errors`).
    flags = {"steps": "--pom-steps", "variant": "--pom-variant", "softness": "--pom-softness"}

    @classmethod
    @override
    def settings_from_args(cls, args) -> dict:
        return {"steps": args.pom_steps, "variant": args.pom_variant, "softness": args.pom_softness}

    @classmethod
    @override
    def check_settings(cls, bake_params, settings: dict) -> None:
        _validate(
            settings.get("steps", DEFAULT_STEPS),
            settings.get("variant") or VARIANTS[0],
            DEFAULT_SOFTNESS if settings.get("softness") is None else settings["softness"],
        )

    @classmethod
    @override
    def tradeoff_variants(cls) -> list[Variant]:
        v = [
            Variant(f"pom, {n} steps", {"steps": n, "variant": "hard"}, {"steps": n, "variant": "hard"})
            for n in TRADEOFF_STEPS
        ]
        v += [
            Variant(
                f"pom soft (w = {DEFAULT_SOFTNESS:g}), {n} steps",
                {"steps": n, "variant": "soft"},
                {"steps": n, "variant": "soft", "softness": DEFAULT_SOFTNESS},
            )
            for n in (16, 64)
        ]
        return v

    def storage_bytes(self) -> int:
        """Return the storage in bytes: the height map alone, 16-bit.

        The skip table is hzval's acceleration of its march, not a texture the technique needs.
        """
        return self.rows * self.cols * 2

    @property
    @override
    def parameters(self) -> dict:
        out = {
            "technique": "height-field ray march (parallax occlusion mapping's shadows)",
            "steps": self.steps,
            "variant": self.variant,
            "simulated": list(self.simulated),
        }
        if self.variant == "soft":
            out["softness"] = self.softness
        return out

    # -- rendering -------------------------------------------------------------

    def render(self, azimuth_deg: float, *, elevation_deg: float | None = None) -> Frame:
        """Return the frame for the light at ``azimuth_deg`` (degrees).

        The image is the unshadowed shading times the pixel mean of ``F`` (``layers["factor"]``); ``seconds``
        is its wall time, the unshadowed shading's included.
        """
        t0 = time.perf_counter()
        e = self.scene.light.elevation_deg if elevation_deg is None else float(elevation_deg)
        F = self.factor(azimuth_deg, e)
        return self._unshadowed.shade(azimuth_deg, e, F, time.perf_counter() - t0)

    def factor(self, azimuth_deg: float, elevation_deg: float) -> np.ndarray:
        """Pixel means of ``F``, ``shape`` float32 in [0, 1]."""
        if self._frames is not None:
            return self._factor_on_model(azimuth_deg, elevation_deg)
        if elevation_deg >= 90.0:
            return np.ones(self.shape, np.float32)
        if elevation_deg <= 0.0:
            return np.zeros(self.shape, np.float32)
        phi, e = math.radians(azimuth_deg), math.radians(elevation_deg)
        # one texel toward the light in texture coordinates (v runs down the image)
        du = dr.opaque(mi.Float, math.cos(phi) / self.cols)
        dv = dr.opaque(mi.Float, -math.sin(phi) / self.rows)
        tan_e = dr.opaque(mi.Float, math.tan(e))
        P, spp = self.shape[0] * self.shape[1], self.spp
        pixel = dr.arange(mi.UInt32, P)

        def body(k, acc):
            uv = dr.gather(mi.Point2f, self._uv, pixel * spp + k)
            return k + 1, acc + self._march(uv, du, dv, tan_e)

        _, acc = dr.while_loop(
            state=(dr.zeros(mi.UInt32, P), dr.zeros(mi.Float, P)), cond=lambda k, acc: k < spp, body=body
        )
        F = acc * (1.0 / spp)
        dr.eval(F)
        backend.sync()
        return np.asarray(F, dtype=np.float32).reshape(self.shape)

    def _factor_on_model(self, azimuth_deg: float, elevation_deg: float) -> np.ndarray:
        """Return the pixel means of ``F`` on a model.

        Each sample marches toward the world's light in its own tangent frame
        (:class:`hzval.scene.lookup.Samples`), times the base mesh's shadow. A light below a sample's tangent
        plane gives 0, one along its normal 1, as on the plane.
        """
        direction = cv.light_direction(azimuth_deg, elevation_deg)
        Lw = dr.opaque(mi.Vector3f, [float(c) for c in direction])
        M = self._macro(direction) if self._macro is not None else None
        P, spp = self.shape[0] * self.shape[1], self.spp
        pixel = dr.arange(mi.UInt32, P)
        cols, rows = dr.opaque(mi.Float, float(self.cols)), dr.opaque(mi.Float, float(self.rows))

        def body(k, acc):
            index = pixel * spp + k
            uv = dr.gather(mi.Point2f, self._uv, index)
            L = lookup.to_tangent(lookup.frame_of(self._frames, index), Lw)
            run = dr.sqrt(dr.fma(L.x, L.x, L.y * L.y))
            across = dr.maximum(run, 1e-12)
            # one texel toward the light in texture coordinates (v runs down the image)
            F = self._march(uv, L.x / across / cols, -L.y / across / rows, dr.maximum(L.z / across, 1e-6))
            F = dr.select(L.z <= 0.0, 0.0, dr.select(run < 1e-6, 1.0, F))
            if M is not None:
                F = F * dr.gather(mi.Float, M, index)
            return k + 1, acc + F

        _, acc = dr.while_loop(
            state=(dr.zeros(mi.UInt32, P), dr.zeros(mi.Float, P)), cond=lambda k, acc: k < spp, body=body
        )
        F = acc * (1.0 / spp)
        dr.eval(F)
        backend.sync()
        return np.asarray(F, dtype=np.float32).reshape(self.shape)

    def _march(self, uv, du, dv, tan_e):
        """``F`` of the samples at texture coordinates ``uv`` (module docstring, "March")."""
        c = self._c
        open_tile = self.scene.material.boundary == "open"
        h0 = self._height.eval(uv)[0]
        t_max = dr.maximum(c["h_max"] - h0, 0.0) / tan_e
        dt = t_max / mi.Float(c["steps"])
        soft = self.variant == "soft"
        # the steps a sample above its skip table's maximum passes over: those within the table's
        # reach of it along the ray, whose heights that maximum bounds (SkipTable)
        if self._skip is not None:
            reach = self._skip.radius
            jump = mi.UInt32(dr.minimum(reach / dr.maximum(dt, 1e-30), mi.Float(c["steps"]))) + 1

        def body(i, blocked, rise):
            t = dt * mi.Float(i)
            p = mi.Point2f(dr.fma(du, t, uv.x), dr.fma(dv, t, uv.y))
            z = dr.fma(t, tan_e, h0)
            # this sample and the next jump - 1 cannot block
            clear = mi.Bool(False) if self._skip is None else self._skip.at(p) <= z
            above = self._height.eval(p, active=~clear)[0] - z - c["eps"]  # H_i - z_i
            if open_tile:
                outside = (p.x < 0.0) | (p.x > 1.0) | (p.y < 0.0) | (p.y > 1.0)
                above = dr.select(outside, -1.0, above)  # nothing beyond the border
            if soft:
                rise = dr.select(clear, rise, dr.maximum(rise, above / t))
            else:
                blocked |= ~clear & (above > 0.0)
            return (i + 1 if self._skip is None else dr.select(clear, i + jump, i + 1)), blocked, rise

        _, blocked, rise = dr.while_loop(
            state=(mi.UInt32(1), mi.Bool(False), mi.Float(0.0)),
            cond=lambda i, blocked, rise: (i <= c["steps"]) & ~blocked,
            body=body,
        )
        if soft:
            return dr.clip(1.0 - c["w"] * rise, 0.0, 1.0)
        return dr.select(blocked, 0.0, 1.0)


#: The reach of the march's skip table, in texels (:class:`SkipTable`); ``None`` marches every step.
#: Short, because a wider window's maximum is a nearby crest the climbing rays have yet to clear
#: (benchmarks/README.md, ``bench_pom.py``, has the reaches measured).
SKIP_RADIUS: float | None = 2.0


class SkipTable:
    """The largest height near each texel, which lets the march pass over samples that cannot block.

    ``M[texel] = max H`` over the texels within ``ceil(radius) + 1`` of it (Chebyshev distance, in
    whole texels; the tile's boundary as the height texture's: wrapped, or clamped to the border).
    A sample ``j`` of the march within ``radius`` texels of sample ``i`` (``(j - i) dt <= radius``)
    reads the texels whose centres lie less than 1 from ``p_j`` on each axis (bilinear), so less
    than ``radius + 1.5`` from the centre of the texel that holds ``p_i``: at most ``ceil(radius) +
    1`` whole texels from it. Its height is at most ``M`` there, to a few float32 ulps. Where
    ``M <= z_i``, the ray's height at ``i``, which only rises, no sample up to ``j`` rises above
    the ray by more than those ulps, far inside the test's margin (:data:`EPSILON_PER_HEIGHT`): the
    hard test's ``blocked`` and the soft one's ``rise`` are bit for bit those of the full march.
    A maximum mipmap of one level (Tevs et al. 2008, "Maximum mipmaps for fast, accurate, and
    scalable dynamic height field rendering").
    """

    def __init__(self, h: np.ndarray, radius: float, boundary: str):
        # SciPy: 0.3-0.4 s to import, paid only where it is used
        from scipy import ndimage

        if not (math.isfinite(radius) and radius >= 0):
            raise ValueError(f"a skip table's reach is a number of texels >= 0, got {radius!r}")
        self.radius = float(radius)
        size = 2 * (int(math.ceil(radius)) + 1) + 1
        mode = "wrap" if boundary == "wrap" else "nearest"
        table = ndimage.maximum_filter(np.asarray(h, np.float32), size=size, mode=mode)
        self.rows, self.cols = table.shape
        self.wrap = boundary == "wrap"
        self.table = table
        self._values = mi.Float(np.ascontiguousarray(table).ravel())
        self._size = (dr.opaque(mi.Float, float(self.cols)), dr.opaque(mi.Float, float(self.rows)))
        self._ints = (dr.opaque(mi.Int32, self.cols), dr.opaque(mi.Int32, self.rows))

    def at(self, p):
        """Return ``M`` at the texel that holds texture coordinates ``p`` (``mi.Point2f``).

        ``p`` is wrapped into the tile (``p - floor(p)``, exact in float32: no division, which CUDA
        approximates), or clamped to its border. Where rounding puts ``p`` in a neighbour of its texel, ``p``
        lies within half a texel and an ulp of that neighbour's centre: inside the reach's spare half texel.
        """
        cols, rows = self._ints
        u, v = (p.x - dr.floor(p.x), p.y - dr.floor(p.y)) if self.wrap else (p.x, p.y)
        x = dr.clip(mi.Int32(dr.floor(u * self._size[0])), 0, cols - 1)
        y = dr.clip(mi.Int32(dr.floor(v * self._size[1])), 0, rows - 1)
        return dr.gather(mi.Float, self._values, mi.UInt32(y * cols + x))


def _validate(steps, variant: str, softness: float) -> None:
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
        raise InputError("steps", f"the ray march needs at least 1 step, got {steps!r}")
    if variant not in VARIANTS:
        raise InputError("variant", f"must be one of {', '.join(VARIANTS)}, got {variant!r}")
    if not (isinstance(softness, (int, float)) and math.isfinite(softness) and softness > 0):
        raise InputError("softness", f"must be a positive number, got {softness!r}")
