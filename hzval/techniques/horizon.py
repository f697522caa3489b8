"""The horizon map (Lengyel): horizon-map shading of the *flat* surface, in Dr.Jit: the ``horizon`` technique.

The truth (:mod:`hzval.truth.plane`) ray-traces the displaced mesh; this module
shades the flat plane ``z = 0`` from the baked textures alone, as a real-time
renderer would, and computes only the effects that the scene declares
(docs/ARCHITECTURE.md, "Effects"). Both read the same :class:`hzval.scene.spec.Scene`: the
same sample positions, the same light, the same units, so that every
difference between them is the technique's.

The design in full: docs/internals.md, "hzval.techniques.horizon".
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from pathlib import Path

import numpy as np
from typing_extensions import override

from hzval.bake.maps import CUBE_SIZE, BakeParams, bake, weight_cube
from hzval.core import conventions as cv
from hzval.core.backend import dr, mi
from hzval.core.errors import InputError
from hzval.core.shading import SPECULAR_EXPONENT, SPECULAR_KS
from hzval.io import external
from hzval.io import storage as hz_storage
from hzval.scene import lookup
from hzval.scene.spec import Frame, Scene
from hzval.techniques import cubemap
from hzval.techniques.registry import Context, Technique, Variant
from hzval.techniques.surface import NOT_MODELLED, FlatShading

__all__ = [
    "Horizon",
    "PATHS",
    "STORAGES",
    "WEIGHTS",
    "AMBIENT_TERMS",
    "DEFAULT_K",
    "DEFAULT_FADE",
    "CUBE_SIZE",
    "CUBE_BYTES",
]

#: The two ways of evaluating the technique (module docstring).
PATHS: tuple[str, ...] = ("exact", "gpu")
#: How the horizon map is stored (:mod:`hzval.io.storage`): as baked, 8-bit, or block-compressed.
STORAGES: tuple[str, ...] = tuple(hz_storage.names())
#: How the channel weights are computed: exactly, or from the 8-bit weight cube map.
WEIGHTS: tuple[str, ...] = ("analytic", "cube")
#: The ambient map's two definitions (:class:`hzval.bake.maps.Bake` attributes).
AMBIENT_TERMS: tuple[str, ...] = ("mean_cos2", "mean_cos")
#: Lengyel's shadow hardness (Listing 5.1 ``kShadowHardness``): F falls from 1
#: to 0 over a horizon-sine range of 1/k.
DEFAULT_K = 8.0
#: Toolbag's per-material horizon fade constant. The post leaves it to the
#: artist ("best left as a per-material setting"); 1.3 is this project's
#: default: a reflection 1/1.3 = 0.77 in sine below the horizon is fully
#: occluded, one at the horizon is not occluded. The report should vary it.
DEFAULT_FADE = 1.3
#: The horizon map's slot in the packed texture (:meth:`hzval.techniques.surface.FlatShading._extra_planes`).
HORIZON_SLOT = "horizon"
#: The weight cube map's texture memory: 6 faces of two 8-bit RGBA layers.
CUBE_BYTES = 6 * CUBE_SIZE * CUBE_SIZE * 4 * 2


class Horizon(FlatShading, Technique):
    """Horizon-map shading of one material's flat surface, frame by frame: the ``horizon`` technique.

    Parameters
    ----------
    scene
        Camera, light (elevation, irradiance), declared effects, samples.
    bake
        The material's textures (:func:`hzval.bake.maps.bake`); its boundary
        (``wrap``/``open``) sets the textures' wrap mode and its shape the
        image's (times the camera's supersampling).
    albedo
        Linear albedo ``(rows, cols, 3)``; ``None`` reads the scene's
        (:func:`hzval.scene.spec.load_albedo`). Only used by ``diffuse`` and
        ``ambient``; a uniform albedo enters the kernel as a constant.
    path
        ``"exact"`` or ``"gpu"`` (module docstring): the defaults of the two
        settings below.
    storage
        How the horizon map is stored (:data:`hzval.io.storage.STORAGES`):
        ``"float"`` as baked, ``"u8"`` quantised to 8 bits as an engine stores
        it, or block-compressed (``"bc7"``, ``"bc3"``, ``"bc1"``, ``"bc4"``,
        each also ``-sqrt``), decoded as a GPU decodes it. Default: ``"u8"``
        on the ``gpu`` path, else ``"float"``.
    weights
        ``"analytic"`` (the exact interpolation) or ``"cube"`` (the 8-bit
        weight cube map). Default: ``"cube"`` on the ``gpu`` path. The two
        settings separate the costs of the GPU path (``hzval tradeoff``).
    k
        Shadow hardness of eq. 5.4, > 0.
    ambient
        Which ambient map: ``"mean_cos2"`` or ``"mean_cos"``.
    fade
        Toolbag's reflection-occlusion constant, >= 0 (:data:`DEFAULT_FADE`).

    Attributes
    ----------
    simulated
        The effects this object computes, in :data:`hzval.scene.spec.EFFECTS`
        order: the declared ones less :data:`NOT_MODELLED`
        (``metrics.json``'s ``techniques.horizon.simulated``).
    shape
        ``(height, width)`` of every image it renders.
    """

    name = "horizon"
    label = "horizon map"
    summary = "Lengyel's horizon mapping: 8 horizon sines in two RGBA textures, F = clamp(k (Lz - s) + 1)"
    file_stem = "horizon"
    needs = ()  # it also shades (and fades reflections) without shadows
    not_modelled = NOT_MODELLED

    def __init__(
        self,
        scene: Scene,
        bake,
        albedo: np.ndarray | None = None,
        *,
        path: str = "exact",
        k: float = DEFAULT_K,
        ambient: str = "mean_cos2",
        fade: float = DEFAULT_FADE,
        storage: str | None = None,
        weights: str | None = None,
        height: np.ndarray | None = None,
        samples: lookup.Samples | None = None,
    ):
        storage = storage or ("u8" if path == "gpu" else "float")
        weights = weights or ("cube" if path == "gpu" else "analytic")
        directions = int(bake.horizon.shape[-1]) if bake.horizon is not None else cv.CHANNEL_COUNT
        _validate(path, storage, weights, directions, ambient, k, fade)
        self.path, self.k, self.fade = path, float(k), float(fade)
        self.storage, self.weights = storage, weights
        self.directions = directions
        self.external: list[str] | None = None  # the external bake's layers, when one is used
        super().__init__(scene, bake, albedo, ambient=ambient, height=height, samples=samples)

    # -- the hooks of the flat shading (hzval.techniques.surface.FlatShading) ----------------------------

    @property
    def _needs_horizon(self) -> bool:
        return self._shadow or self._reflection

    def _extra_planes(self) -> list[tuple[str, np.ndarray]]:
        """Return the horizon map as stored (:mod:`hzval.io.storage`), first in the packed texture."""
        return (
            [(HORIZON_SLOT, hz_storage.get(self.storage).roundtrip(self.bake.horizon))]
            if self._needs_horizon
            else []
        )

    def _max_channels(self) -> slice | None:
        return self._slots.get(HORIZON_SLOT)

    def _mip_quantise(self):
        """Return what the horizon map's storage makes of each mip level.

        This is ``None`` for float, else the storage's round trip (:func:`hzval.scene.lookup.mip_chain`), as a
        GPU's chain of an RGBA8 (or BC7) texture is RGBA8 (BC7).
        """
        if self.storage == "float" or HORIZON_SLOT not in self._slots:
            return None
        return hz_storage.get(self.storage).roundtrip

    def _upload_constants(self) -> None:
        """``k``, the fade and the weight cube map for ``weights="cube"``, beside the shading's."""
        super()._upload_constants()
        self._k = dr.opaque(mi.Float, self.k)
        self._fade = dr.opaque(mi.Float, self.fade)
        self._cube = None
        if self._needs_horizon and self.weights == "cube":
            cube = weight_cube(CUBE_SIZE).astype(np.float32) / np.float32(255.0)
            self._cube = mi.Float(lookup.aligned(cube).ravel())
            dr.eval(self._cube)

    def _extra_uniforms(self, uni: dict, shadows: bool, overrides: dict) -> None:
        """Set ``k`` and the light's channel weights, the same for every sample of the frame.

        ``k`` is ``overrides["k"]`` for a sweep over k that reuses textures and kernels.
        """
        k = overrides.pop("k", None)
        super()._extra_uniforms(uni, shadows, overrides)
        uni["k"] = self._k
        if k is not None:
            if not (math.isfinite(k) and k > 0):
                raise InputError("k", f"the shadow hardness must be a positive number, got {k}")
            uni["k"] = dr.opaque(mi.Float, float(k))
        if self._shadow and shadows:
            uni["w"] = self._channel_weights(uni["L"])

    def _shadowed(self, direct, tex: dict, uni: dict, out: dict, shadows: bool, probe: bool):
        """``direct * F``, ``F = clamp(k (Lz - s) + 1, 0, 1)`` (eq. 5.4), ``s`` by eq. 5.3."""
        if not (self._shadow and shadows):
            return direct
        F, s = shadow_factor(tex[HORIZON_SLOT], uni["w"], uni["L"].z, uni["k"])
        out["factor"] = F
        if probe:
            out["horizon_sine"] = s
        return direct * F

    def _extra_layers(self, tex: dict, n, out: dict, uni: dict) -> None:
        """Toolbag's reflection fade ``o`` against the baked horizon toward ``r`` (module docstring).

        On a model ``uni["v"]`` is the sample's own view in its tangent frame ``(t, b, n_vertex)``
        (:meth:`hzval.techniques.surface.FlatShading._lane_uniforms`; ``n_vertex`` the base mesh's
        interpolated
        vertex normal), so ``r`` is the world's reflection about the shading normal in that frame:
        ``r.z = dot(r, n_vertex)``, Toolbag's own dot product, and ``r``'s azimuth the horizon lookup's.
        """
        if not self._reflection:
            return
        # r = reflect(-v, n) = 2 (n.v) n - v (the top view's v = +z: (2 nz nx, 2 nz ny, 2 nz^2 - 1))
        if "v" in uni:
            r = 2.0 * dr.dot(n, uni["v"]) * n - uni["v"]
        elif self.scene.camera.kind == "top":
            r = mi.Vector3f(2.0 * n.z * n.x, 2.0 * n.z * n.y, dr.fma(2.0 * n.z, n.z, -1.0))
        else:
            r = 2.0 * dr.dot(n, self._view) * n - self._view
        s_r = _dot(tex[HORIZON_SLOT], self._channel_weights(r))
        o = dr.clip(dr.fma(r.z - s_r, self._fade, 1.0), 0.0, 1.0)
        out["reflection_occlusion"] = o * o

    def _extra_layout(self, shadows: bool) -> tuple[list, list]:
        before = [("factor", 1)] if self._shadow and shadows else []
        return before, [("reflection_occlusion", 1)] if self._reflection else []

    # ------------------------------------------------------------------
    # The Technique interface (hzval.techniques.registry)
    # ------------------------------------------------------------------

    @classmethod
    def bake_needs(cls, scene: Scene) -> frozenset[str]:
        """Return the horizon map and the normal and ambient maps.

        An external horizon map replaces the baked one, but hzval's own is what it is checked against.
        """
        return frozenset({"horizon_map", "normal", "ambient"})

    @classmethod
    def build(cls, ctx: Context, *, horizon_map=None, encoding=None, **settings) -> "Horizon":
        """Build the horizon technique from a context.

        ``horizon_map`` (layer paths) and ``encoding`` (:class:`hzval.io.external.Encoding`) replace the
        bake's horizon map by an external one, whose convention is checked against hzval's exact bake
        (:func:`hzval.io.external.detect`).
        """
        if not horizon_map:
            return cls(ctx.scene, ctx.bake, ctx.albedo, samples=ctx.samples(), **settings)
        raw = external.read_layers(list(horizon_map))
        enc = (encoding or external.Encoding()).validate()
        external.check_layers(raw, enc, horizon_map)
        if raw.shape[:2] != ctx.height.shape:
            raise InputError(
                horizon_map[0],
                f"is {raw.shape[1]}x{raw.shape[0]}, the height map "
                f"{ctx.height.shape[1]}x{ctx.height.shape[0]}",
            )
        sines = external.to_hzval(raw, enc)
        found = external.detect(
            raw, _reference_horizons(ctx, enc.channels), enc, k=float(settings.get("k") or DEFAULT_K)
        )
        own = cls(
            ctx.scene,
            dataclasses.replace(ctx.bake, horizon=sines),
            ctx.albedo,
            samples=ctx.samples(),
            **settings,
        )
        own.external = [str(p) for p in horizon_map]
        own.warnings = tuple(
            external.repeated_layers(raw, own.external)
            + external.warnings(found, own.external, ctx.scene.material.height)
        )
        own.extras = {"external_bake": {**found, "paths": own.external, "warnings": list(own.warnings)}}
        return own

    #: The command line's flag of each setting (errors name the flag,
    # :func:`hzval.techniques.registry.flag_errors`).
    input_flags = ("--horizon-map", "--horizon-encoding")
    flags = {
        "k": "--horizon-k",
        "path": "--horizon-path",
        "ambient": "--horizon-ambient",
        "storage": "--horizon-storage",
        "weights": "--horizon-path",
        "fade": "--horizon-k",
    }
    #: The flags' names before they had the technique's prefix, hidden aliases for one release.
    FORMER_FLAGS = {
        "--horizon-k": "--k",
        "--horizon-path": "--path",
        "--horizon-ambient": "--ambient",
        "--horizon-storage": "--storage",
    }

    @classmethod
    @override
    def add_arguments(cls, parser) -> None:
        def add(flag: str, **kw) -> None:
            parser.add_argument(flag, **kw)
            hidden = {k: v for k, v in kw.items() if k not in ("help", "metavar")}
            parser.add_argument(
                cls.FORMER_FLAGS[flag],
                dest=flag[2:].replace("-", "_"),
                **{**hidden, "default": argparse.SUPPRESS},
                help=argparse.SUPPRESS,
            )

        add(
            "--horizon-k",
            type=float,
            default=DEFAULT_K,
            help=f"horizon map: shadow hardness k of F = clamp(k (Lz - s) + 1) (default {DEFAULT_K:g})",
        )
        add(
            "--horizon-path",
            choices=PATHS,
            default=PATHS[0],
            help=f"horizon map: exact float math, or emulate the GPU's 8-bit textures and weight cube map "
            f"(default {PATHS[0]})",
        )
        add(
            "--horizon-ambient",
            choices=AMBIENT_TERMS,
            default=AMBIENT_TERMS[0],
            help=f"horizon map: which ambient-map definition to shade with (default {AMBIENT_TERMS[0]})",
        )
        parser.add_argument(
            "--horizon-map",
            default=None,
            metavar="P0,P1",
            help="horizon map: your own bake's RGBA layers (8/16-bit PNG or EXR), in place of "
            "hzval's; its encoding from --horizon-encoding or the --horizon-* options "
            "(default: hzval's layout)",
        )
        parser.add_argument(
            "--horizon-encoding",
            type=Path,
            default=None,
            metavar="FILE.toml",
            help="horizon map: a TOML file of channels, azimuth0, direction, y, values",
        )
        d = external.Encoding()
        parser.add_argument("--horizon-channels", type=int, default=None, help=f"(default {d.channels})")
        parser.add_argument(
            "--horizon-azimuth0",
            type=float,
            default=None,
            metavar="DEG",
            help=f"azimuth of channel 0 (default {d.azimuth0:g})",
        )
        parser.add_argument(
            "--horizon-direction",
            choices=["ccw", "cw"],
            default=None,
            help=f"which way channels turn (default {d.direction})",
        )
        parser.add_argument(
            "--horizon-y",
            choices=["up", "down"],
            default=None,
            help=f"the baker's +y on screen (default {d.y})",
        )
        parser.add_argument(
            "--horizon-values",
            choices=external.VALUES,
            default=None,
            help=f"what a channel holds (default {d.values})",
        )
        add(
            "--horizon-storage",
            choices=STORAGES,
            default=None,
            help="horizon map: how its textures are stored: float, 8-bit or block-compressed (BC7, BC3, BC1, "
            "BC4; -sqrt stores square-root sines) (default float, u8 with --horizon-path gpu)",
        )

    @classmethod
    @override
    def settings_from_args(cls, args) -> dict:
        out = {
            "k": args.horizon_k,
            "path": args.horizon_path,
            "ambient": args.horizon_ambient,
            **({"storage": args.horizon_storage} if args.horizon_storage else {}),
        }
        _validate(
            out["path"],
            out.get("storage", "float"),
            "analytic",
            cv.CHANNEL_COUNT,
            out["ambient"],
            out["k"],
            DEFAULT_FADE,
        )
        if args.horizon_map:
            enc = (
                external.Encoding.from_toml(args.horizon_encoding)
                if args.horizon_encoding
                else external.Encoding()
            )
            given = {
                "channels": args.horizon_channels,
                "azimuth0": args.horizon_azimuth0,
                "direction": args.horizon_direction,
                "y": args.horizon_y,
                "values": args.horizon_values,
            }
            enc = dataclasses.replace(enc, **{k: v for k, v in given.items() if v is not None}).validate()
            out.update(
                horizon_map=tuple(p.strip() for p in args.horizon_map.split(",") if p.strip()), encoding=enc
            )
        return out

    @classmethod
    @override
    def check_settings(cls, bake_params, settings: dict) -> None:
        if settings.get("path") == "gpu" and bake_params.directions != cv.CHANNEL_COUNT:
            raise InputError(
                "path",
                f"the gpu path emulates Lengyel's {cv.CHANNEL_COUNT}-channel weight cube map; "
                f"a bake of {bake_params.directions} directions needs the exact path",
            )

    @classmethod
    @override
    def check_variants(cls) -> list[Variant]:
        # the references of hzval 0.1 (metrics.json schema 1) were named after "the approximation"
        return [
            Variant("horizon", {"path": "exact"}, formerly="approx"),
            Variant("horizon_gpu", {"path": "gpu"}, formerly="approx_gpu"),
        ]

    @classmethod
    @override
    def tradeoff_variants(cls) -> list[Variant]:
        v = [Variant("8-bit horizon map", {"storage": "u8"})]
        v += [
            Variant(f"{name} horizon map ({hz_storage.get(name).label})", {"storage": name})
            for name in ("u8-sqrt", "bc7", "bc7-sqrt", "bc3", "bc1", "bc4")
        ]
        v += [
            Variant("cube-map weights", {"weights": "cube"}),
            Variant("GPU path: 8-bit map + cube weights", {"storage": "u8", "weights": "cube"}),
        ]
        v += [Variant(f"k = {k:g}", {"k": float(k)}) for k in (2, 4, 16, 32)]
        v.append(Variant("k fitted to the truth", {"k": "fit"}))
        return v

    @classmethod
    def fit(cls, ctx: Context, settings: dict, visibility: list[np.ndarray], azimuths) -> dict:
        """Return ``settings`` with ``k = "fit"`` replaced by the k that minimises the sweep's error.

        The error is the sweep's mean ``|F - V|`` against ``visibility`` (one layer per azimuth), minimised by
        a golden-section search on ``log k`` in [1, 128].
        """
        if settings.get("k") != "fit":
            return settings
        ap = cls.build(ctx, **{**settings, "k": DEFAULT_K})

        def cost(logk: float) -> float:
            k = math.exp(logk)
            return float(
                np.mean(
                    [
                        np.mean(np.abs(ap.render(az, k=k).layers["factor"] - V))
                        for az, V in zip(azimuths, visibility)
                    ]
                )
            )

        return {**settings, "k": _golden_section(cost, math.log(1.0), math.log(128.0))}

    def storage_bytes(self) -> int:
        """Return the bytes of the horizon map as stored and of the weight cube map.

        The horizon map's are :meth:`hzval.io.storage.Storage.bytes`.
        """
        rows, cols, ch = self.bake.horizon.shape
        return hz_storage.get(self.storage).bytes(rows, cols, ch) + (
            CUBE_BYTES if self.weights == "cube" else 0
        )

    # ------------------------------------------------------------------
    # Public
    # ------------------------------------------------------------------

    @property
    def parameters(self) -> dict:
        """The technique's settings, for ``metrics.json``."""
        out = {
            "path": self.path,
            "storage": self.storage,
            "weights": self.weights,
            "k": self.k,
            "bake": "external: " + ", ".join(self.external) if self.external else "hzval",
            "simulated": list(self.simulated),
        }
        if not self.external:
            record = self.bake.params.record()
            out.update(
                bake_method=record["method"], bake_radius=record["radius"], bake_angles=record["angles"]
            )
        out["directions"] = self.directions
        if self._ambient:
            out["ambient"] = self.ambient
        if self._reflection:
            out["fade"] = self.fade
        if self._specular:
            out.update(specular_ks=SPECULAR_KS, specular_alpha=SPECULAR_EXPONENT)
        if self.storage != "float":
            out.update(storage_bytes=self.storage_bytes())
        if self.weights == "cube":
            out.update(cube_size=CUBE_SIZE, cube_bits=8, cube_filter="seamless bilinear")
        return out

    def render(
        self,
        azimuth_deg: float,
        *,
        shadows: bool = True,
        elevation_deg: float | None = None,
        k: float | None = None,
    ) -> Frame:
        """Return the frame of the light at ``azimuth_deg`` (degrees).

        See :meth:`hzval.techniques.surface.FlatShading.render`.

        ``k`` defaults to the object's. ``shadows=False`` leaves out the
        horizon factor (plain normal mapping); the other declared effects stay.
        Layers: ``factor`` (pixel mean of F, when shadowing), ``ambient`` (A)
        and ``reflection_occlusion`` (o), each where declared.
        """
        return super().render(
            azimuth_deg, shadows=shadows, elevation_deg=elevation_deg, **({} if k is None else {"k": k})
        )

    def sample(
        self,
        x,
        y,
        azimuth_deg: float,
        elevation_deg: float | None = None,
        *,
        shadows: bool = True,
        k: float | None = None,
    ) -> dict[str, np.ndarray]:
        """Return per-point values (:meth:`hzval.techniques.surface.FlatShading.sample`).

        When shadowing, they include ``horizon_sine`` too (``s`` of eq. 5.3/5.4).
        """
        return super().sample(
            x, y, azimuth_deg, elevation_deg, shadows=shadows, **({} if k is None else {"k": k})
        )

    # ------------------------------------------------------------------
    # Kernels
    # ------------------------------------------------------------------

    def _channel_weights(self, d) -> list:
        """Return the ``D`` channel weights toward the azimuth of directions ``d`` (path-specific)."""
        return (
            self._exact_weights(d, self.directions) if self.weights == "analytic" else self._cube_weights(d)
        )

    @staticmethod
    def _exact_weights(d, directions: int = cv.CHANNEL_COUNT) -> list:
        """Exact linear interpolation between the two channels adjacent to ``atan2(dy, dx)``.

        Channel ``c`` of ``D = directions`` gets the tent ``max(0, 1 - dist(t,
        c))`` with ``t`` the azimuth in channel units (``360 / D`` degrees)
        and ``dist`` the circular distance modulo ``D``:
        :func:`hzval.core.conventions.channel_weights` without a per-lane channel
        index. ``t`` in [0, D]: azimuths of 360 deg or -0 deg land on D or 0,
        both of which give channel 0 all the weight.
        """
        n = float(directions)
        t = dr.atan2(d.y, d.x) * cv.channels_per_radian(directions)
        t = dr.select(t < 0.0, t + n, t)
        weights = []
        for c in range(directions):
            dist = dr.abs(t - float(c))
            dist = dr.minimum(dist, n - dist)
            weights.append(dr.maximum(1.0 - dist, 0.0))
        return weights

    def _cube_weights(self, d) -> list:
        """Lengyel's channel factors from the 8-bit weight cube map, as a GPU computes them.

        The cube is sampled as OpenGL samples it with ``GL_TEXTURE_CUBE_MAP_SEAMLESS``
        (:func:`hzval.techniques.cubemap.bilinear`: table 8.19's faces, bilinear across the
        faces' seams, a corner's missing texel the mean of the other three). Returns
        ``f0`` (layer 0) then ``f1`` (layer 1) of Listing 5.1: ``clamp(+-(2f - 1), 0, 1)``
        applied to the *filtered* 8-bit values, as the shader does.
        """
        f = cubemap.bilinear(self._cube, CUBE_SIZE, d)
        f0 = [dr.clip(dr.fma(f[i], 2.0, -1.0), 0.0, 1.0) for i in range(4)]
        f1 = [dr.clip(dr.fma(f[i], -2.0, 1.0), 0.0, 1.0) for i in range(4)]
        return f0 + f1


def _dot(h: list, w: list):
    """``sum_c w_c h_c`` over the channels, as one RGBA dot product per layer, summed in layer order (eq.

    5.3: two layers for 8 channels, four for 16).
    """
    n = cv.CHANNELS_PER_LAYER
    total = None
    for first in range(0, len(h), n):
        s = h[first] * w[first]
        for c in range(first + 1, first + n):
            s = dr.fma(h[c], w[c], s)
        total = s if total is None else total + s
    return total


def shadow_factor(h: list, w: list, Lz, k, *, straight_through: bool = False):
    """Lengyel's shadow factor (eq. 5.4), ``F = clamp(k (Lz - s) + 1, 0, 1)``.

    ``s = sum_c w_c h_c`` is the horizon sine toward the light, from the filtered channels and their
    weights; the shading kernel's own arithmetic.

    Parameters
    ----------
    h : list of drjit.Float
        The filtered horizon channels (sines).
    w : list of drjit.Float
        The light's channel weights (:func:`hzval.core.conventions.channel_weights`).
    Lz : drjit.Float
        The light's sine of elevation in the tangent frame.
    k : float or drjit.Float
        The shadow's hardness.
    straight_through : bool
        For the fit: ``F``'s value is the same but its gradient is the unclamped ``k (Lz - s) + 1``'s,
        so a texel saturated on the wrong side still learns which way to move.

    Returns
    -------
    tuple
        ``(F, s)``.
    """
    s = _dot(h, w)
    z = dr.fma(Lz - s, k, 1.0)
    F = dr.clip(z, 0.0, 1.0)
    return (dr.replace_grad(F, z) if straight_through else F), s


def _reference_horizons(ctx: Context, directions: int) -> np.ndarray:
    """Return hzval's own horizons of the context's height map, to detect an external bake's convention.

    They are the exact bake for 8 directions, a wide seed bake (radius 32, 64 bins) for 16.
    """
    p = ctx.bake.params
    params = (
        BakeParams(depth=p.depth, boundary=p.boundary, method="exact")
        if directions == cv.CHANNEL_COUNT
        else BakeParams(depth=p.depth, boundary=p.boundary, radius=32, angles=64, directions=directions)
    )
    return bake(ctx.height, params.validate()).horizon


def _validate(
    path: str, storage: str, weights: str, directions: int, ambient: str, k: float, fade: float
) -> None:
    """Every setting of :class:`Horizon`, checked before anything is uploaded."""
    for what, value, allowed in (
        ("path", path, PATHS),
        ("storage", storage, STORAGES),
        ("weights", weights, WEIGHTS),
        ("ambient", ambient, AMBIENT_TERMS),
    ):
        if value not in allowed:
            raise InputError(what, f"must be one of {', '.join(allowed)}, got {value!r}")
    if weights == "cube" and directions != cv.CHANNEL_COUNT:
        raise InputError(
            "weights",
            f"the weight cube map (and so the gpu path) holds {cv.CHANNEL_COUNT} "
            f"channel weights; this bake stores {directions} directions: use "
            "path='exact' / weights='analytic'",
        )
    if not (math.isfinite(k) and k > 0):
        raise InputError("k", f"the shadow hardness must be a positive number, got {k}")
    if not (math.isfinite(fade) and fade >= 0):
        raise InputError("fade", f"the horizon fade must be a non-negative number, got {fade}")


def _golden_section(cost, a: float, b: float, iterations: int = 14) -> float:
    """``exp`` of the minimiser of a unimodal ``cost`` on ``[a, b]`` (a log-scale search)."""
    g = (math.sqrt(5) - 1) / 2
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
