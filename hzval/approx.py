"""The approximation: horizon-map shading of the *flat* surface, in Dr.Jit.

The truth (:mod:`hzval.truth`) ray-traces the displaced mesh; this module
shades the flat plane ``z = 0`` from the baked textures alone, as a real-time
renderer would, and computes only the effects that the scene declares
(docs/ARCHITECTURE.md, "Effects"). Both read the same :class:`hzval.scene.Scene`: the
same sample positions, the same light, the same units, so that every
difference between them is the technique's.

Conventions (:mod:`hzval.conventions`): tangent space in texel units, +x
right, +y up the image, +z out of the surface; the light's azimuth ``phi``
counterclockwise from +x and elevation ``e`` give
``L = (cos e cos phi, cos e sin phi, sin e)``, toward the light; the view is
``v`` toward the camera: ``+z`` for the ``top`` view, an orthographic
camera's direction otherwise (:mod:`hzval.camera`). Every sample is read
where :mod:`hzval.lookup` puts it (the top view: the scene's sample
positions; another view: where its ray meets the base plane, after any
parallax mapping), filtered as the lookup says. Radiance is linear; the
light's ``irradiance`` ``E`` is the irradiance on a surface facing it.

Per sample, with every texture filtered bilinearly between texel centres
(texel ``(row, col)`` at ``x = col + 0.5``, ``y = rows - row - 0.5``; ``wrap``
repeats, ``open`` clamps to the edge):

``shadow``
    ``F = clamp(k (Lz - s) + 1, 0, 1)`` (Lengyel, GPU Zen 2, eq. 5.4), ``s``
    the horizon sine toward the light's azimuth, interpolated between the two
    adjacent channels (section 5.3). ``k`` is the technique's only softness:
    it has no area light, so the light's centre direction is used.
``diffuse``
    ``albedo / pi * E * max(0, n.L)``, ``n`` the normal map's (renormalised)
    normal (FGED2 ch. 7, Lambert).
``specular``
    ``KS * E * max(0, n.h)^ALPHA * [n.L > 0]``, ``h = normalize(L + v)``
    (FGED2 ch. 7, Blinn-Phong with its ``float(nl > 0.0)`` gate).
``ambient``
    ``+ albedo * A * E / pi``: a uniform sky of radiance ``E / pi`` seen
    through the ambient map ``A`` (``mean_cos2``, the exact cosine-weighted
    unoccluded fraction, or ``mean_cos``, Lengyel's term; docs/ARCHITECTURE.md).
``reflection_occlusion``
    Toolbag's horizon fade (Russell, "Horizon Occlusion for Normal Mapped
    Reflections"): ``o = saturate(1 + fade * dot(r, n_vertex))^2`` with
    ``r = reflect(-v, n)``. On the flat surface ``dot(r, n_vertex) = r_z``,
    and we measure it against the *baked* horizon instead of the tangent
    plane: ``o = saturate(1 + fade * (r_z - s_r))^2``, ``s_r`` the
    interpolated horizon sine toward ``r``'s azimuth. With no occluders
    (``s_r = 0``) this is exactly Toolbag's term. The scene has no
    environment map to reflect, so ``o`` is output as its own layer and does
    not change the image.
``interreflection``
    Not modelled; it never appears in :attr:`Approximation.simulated`.

The image is ``D * F + ambient`` where ``D`` is the sum of the declared
direct terms, or ``E`` (grey) when neither ``diffuse`` nor ``specular`` is
declared. Every direct term is gated by ``[Lz > 0]``: the flat surface
cannot be lit from below its tangent plane, yet eq. 5.4 leaves ``F > 0`` for
a light up to ``1/k`` in sine below the horizon (``F = 0`` only when
``Lz <= s - 1/k``), so without the gate a light just below the horizon would
still light the plane.

Two paths:

``exact``
    float textures; the channel weights are the exact linear interpolation
    (:func:`hzval.conventions.channel_weights`), computed in the kernel.
``gpu``
    what a GPU running Lengyel's Listing 5.1 computes: the horizon layers
    quantised to 8 bits (:func:`hzval.files.unit_to_u8` / 255), the 16x16
    8-bit weight cube map of :func:`hzval.bake.weight_cube` sampled
    bilinearly (OpenGL face selection, :func:`hzval.conventions.cube_lookup`;
    filtering stays *within* the face, clamped to its edge, where a GPU with
    seamless cube maps would blend across the seam: a difference only within
    half a cube texel of an edge), and the shader's arithmetic:
    ``f0 = clamp(2f - 1, 0, 1)``, ``f1 = clamp(-2f + 1, 0, 1)``,
    ``s = dot(h0, f0) + dot(h1, f1)``, ``F = clamp((Lz - s) k + 1, 0, 1)``.
    Normal and albedo maps stay float on both paths, so the two paths differ
    only in the horizon technique. The 8-bit cube cannot store a zero weight
    (127.5): it stores 128, which decodes to a weight of ``1/255`` on layer 0
    and to 0 on layer 1 (:func:`hzval.conventions.encode_signed_weight`).

    What the GPU path costs (``tests/test_approx.py`` derives and asserts it
    per light): ``s_gpu - s_exact = sum w^ (h^ - h) + sum (w^ - w) h``, so
    ``|F_gpu - F_exact| <= k (0.5/255 * sum(w^) + sum |w^_c - w_c| max h_c)``.
    Over all directions ``sum(w^) <= 1 + 3/255`` (the leaks); for elevations
    up to 45 degrees (the cube's side faces, where the weights depend on the
    azimuth only) ``sum |w^ - w| <= 0.169``, largest at the channel azimuths,
    where the tent's peak falls between two cube texels 3.6 degrees either
    side (w^ = 0.92 instead of 1); on the +z face, near the zenith, the weights
    are arbitrary (up to 1.99) but ``Lz`` is large there. Because the +z
    face's weights differ from the side faces', ``F_gpu`` can *drop* as a
    light rises across that seam (elevation 35-45 degrees): it is not
    monotonic in elevation there, by design of the cube map, not of this
    emulation.

Directions: a bake may store 8 (the seed's) or 16 horizon directions
(:attr:`hzval.bake.BakeParams.directions`, channel ``c`` toward azimuth
``360 c / D``, :func:`hzval.conventions.channel_azimuth_deg`). The exact
path's weights interpolate between the two channels adjacent to the light's
azimuth for any ``D`` (the same tent in ``360 / D``-degree steps), and 8-bit
storage quantises any number of channels; the weight cube map, and so the
``gpu`` path, exists for 8 channels only (an :class:`InputError` otherwise).
With 8 channels every kernel is the one it was before ``D`` existed.

Textures are filtered in float32 arithmetic (``use_accel=False``) on every
backend: CUDA's texture units resolve the position within a texel to 1/256,
which would make the exact path inexact and the two backends disagree.

Speed: textures and sample positions are uploaded once, in the constructor.
Everything that changes per frame (``L``) and the per-object constants
(``k``, ``E``, ``fade``, a uniform albedo) enter kernels as opaque Dr.Jit
arrays, so a new light reuses the compiled kernels (docs/ARCHITECTURE.md, "Known pitfalls").
A frame is two kernels: a one-lane kernel for the light's channel weights
(which are uniform over the frame) and the shading kernel, one lane per
pixel, looping over the pixel's samples, so that no per-sample values go
through memory.
"""

from __future__ import annotations

import dataclasses
import math
import time
from pathlib import Path

import numpy as np

from hzval import backend, external, lookup, shading
from hzval import storage as hz_storage
from hzval import conventions as cv
from hzval.bake import CUBE_SIZE, normals_only, weight_cube
from hzval.errors import InputError
from hzval.scene import Frame, Scene, image_shape, load_albedo
from hzval.shading import SPECULAR_EXPONENT, SPECULAR_KS
from hzval.technique import Context, Technique, Variant, replace_effects

__all__ = ["Approximation", "Unshadowed", "unshadowed", "PATHS", "STORAGES", "WEIGHTS", "AMBIENT_TERMS",
           "DEFAULT_K", "DEFAULT_FADE", "CUBE_SIZE", "CUBE_BYTES", "NOT_MODELLED"]

#: The two ways of evaluating the technique (module docstring).
PATHS: tuple[str, ...] = ("exact", "gpu")
#: How the horizon map is stored (:mod:`hzval.storage`): as baked, 8-bit, or block-compressed.
STORAGES: tuple[str, ...] = tuple(hz_storage.names())
#: How the channel weights are computed: exactly, or from the 8-bit weight cube map.
WEIGHTS: tuple[str, ...] = ("analytic", "cube")
#: The ambient map's two definitions (:class:`hzval.bake.Bake` attributes).
AMBIENT_TERMS: tuple[str, ...] = ("mean_cos2", "mean_cos")
#: Lengyel's shadow hardness (Listing 5.1 ``kShadowHardness``): F falls from 1
#: to 0 over a horizon-sine range of 1/k.
DEFAULT_K = 8.0
#: Toolbag's per-material horizon fade constant. The post leaves it to the
#: artist ("best left as a per-material setting"); 1.3 is this project's
#: default: a reflection 1/1.3 = 0.77 in sine below the horizon is fully
#: occluded, one at the horizon is not occluded. The report should vary it.
DEFAULT_FADE = 1.3
#: The weight cube map's texture memory: 6 faces of two 8-bit RGBA layers.
CUBE_BYTES = 6 * CUBE_SIZE * CUBE_SIZE * 4 * 2
#: Declarable effects that the technique does not model.
NOT_MODELLED: tuple[str, ...] = ("interreflection",)



class Approximation(Technique):
    """Horizon-map shading of one material's flat surface, frame by frame: the ``horizon`` technique.

    Parameters
    ----------
    scene
        Camera, light (elevation, irradiance), declared effects, samples.
    bake
        The material's textures (:func:`hzval.bake.bake`); its boundary
        (``wrap``/``open``) sets the textures' wrap mode and its shape the
        image's (times the camera's supersampling).
    albedo
        Linear albedo ``(rows, cols, 3)``; ``None`` reads the scene's
        (:func:`hzval.scene.load_albedo`). Only used by ``diffuse`` and
        ``ambient``; a uniform albedo enters the kernel as a constant.
    path
        ``"exact"`` or ``"gpu"`` (module docstring): the defaults of the two
        settings below.
    storage
        How the horizon map is stored (:data:`hzval.storage.STORAGES`):
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
        The effects this object computes, in :data:`hzval.scene.EFFECTS`
        order: the declared ones less :data:`NOT_MODELLED`
        (``metrics.json``'s ``simulated.approx``).
    shape
        ``(height, width)`` of every image it renders.
    """

    name = "horizon"
    label = "horizon map"
    summary = "Lengyel's horizon mapping: 8 horizon sines in two RGBA textures, F = clamp(k (Lz - s) + 1)"
    file_stem = "approx"
    needs = ()                      # it also shades (and fades reflections) without shadows
    not_modelled = NOT_MODELLED

    def __init__(self, scene: Scene, bake, albedo: np.ndarray | None = None, *,
                 path: str = "exact", k: float = DEFAULT_K, ambient: str = "mean_cos2",
                 fade: float = DEFAULT_FADE, storage: str | None = None, weights: str | None = None,
                 height: np.ndarray | None = None, samples: lookup.Samples | None = None):
        backend.variant()
        storage = storage or ("u8" if path == "gpu" else "float")
        weights = weights or ("cube" if path == "gpu" else "analytic")
        directions = int(bake.horizon.shape[-1]) if bake.horizon is not None else cv.CHANNEL_COUNT
        _validate(path, storage, weights, directions, ambient, k, fade)
        self.scene, self.bake = scene, bake
        self.path, self.k, self.ambient, self.fade = path, float(k), ambient, float(fade)
        self.storage, self.weights = storage, weights
        self.directions = directions
        rows, cols = bake.normal.shape[:2]
        self.rows, self.cols = rows, cols
        self.shape = image_shape(rows, cols, scene.camera)
        self.simulated = self.simulates(scene)
        eff = set(self.simulated)
        self._shadow = "shadow" in eff
        self._diffuse = "diffuse" in eff
        self._specular = "specular" in eff
        self._ambient = "ambient" in eff
        self._reflection = "reflection_occlusion" in eff
        self.external: list[str] | None = None       # the external bake's layers, when one is used
        samples = samples if samples is not None else lookup.samples_for(scene, rows, cols, height)
        self._upload_textures(albedo, samples)
        self._upload_constants()
        self._upload_samples(samples)

    def _upload_textures(self, albedo, samples: lookup.Samples) -> None:
        """One packed texture holding only the channels needed, so that each sample
        computes one set of bilinear indices, filtered as the scene's lookup says
        (:class:`hzval.lookup.Filtered`); the weight cube map for ``weights="cube"``."""
        import drjit as dr
        import mitsuba as mi

        bake, rows, cols = self.bake, self.rows, self.cols
        need_horizon = self._shadow or self._reflection
        planes: list[np.ndarray] = []
        self._slots: dict[str, slice] = {}

        def add(name: str, data: np.ndarray) -> None:
            data = np.asarray(data, dtype=np.float32)
            data = data[..., None] if data.ndim == 2 else data
            start = sum(p.shape[-1] for p in planes)
            self._slots[name] = slice(start, start + data.shape[-1])
            planes.append(data)

        if need_horizon:
            add("horizon", hz_storage.get(self.storage).roundtrip(bake.horizon))
        if self._diffuse or self._specular or self._reflection:
            add("normal", bake.normal)
        self._albedo_const = None
        if self._diffuse or self._ambient:
            a = load_albedo(self.scene.material, rows, cols) if albedo is None else np.asarray(albedo, np.float32)
            if a.shape != (rows, cols, 3):
                raise InputError("albedo", f"expected shape {(rows, cols, 3)}, got {a.shape}")
            if np.all(a == a[:1, :1]):
                self._albedo_const = dr.opaque(mi.Color3f, [float(c) for c in a[0, 0]])
            else:
                add("albedo", a)
        if self._ambient:
            add("ambient", getattr(bake, self.ambient))
        self._texture = None
        if planes:
            self._texture = lookup.Filtered(np.concatenate(planes, axis=-1), bake.params.boundary,
                                            self.scene.lookup, samples, max_channels=self._slots.get("horizon"),
                                            aligned=_aligned)
        self._cube = None
        if need_horizon and self.weights == "cube":
            cube = weight_cube(CUBE_SIZE).astype(np.float32) / np.float32(255.0)
            self._cube = mi.Float(_aligned(cube).ravel())

    def _upload_constants(self) -> None:
        """Per-object constants, opaque so that objects share kernels."""
        import drjit as dr
        import mitsuba as mi

        self._k = dr.opaque(mi.Float, self.k)
        # toward the (orthographic) camera; a perspective one is refused with the effects that read it
        self._view = mi.Vector3f(*(self.scene.camera.toward_eye() or (0.0, 0.0, 1.0)))
        self._fade = dr.opaque(mi.Float, self.fade)
        self._E = dr.opaque(mi.Float, float(self.scene.light.irradiance))

    def _upload_samples(self, samples: lookup.Samples) -> None:
        """Sample positions as texture coordinates. One sample per pixel: two plain
        arrays. More: (u, v) pairs in the scene's pixel-major order, which the
        per-pixel loop gathers as one packet per sample; a pixel's samples share
        cache lines (a sample-major layout, with its stride of a power-of-two
        number of pixels, thrashed the caches: 2x slower)."""
        import drjit as dr
        import mitsuba as mi

        scene = self.scene
        spp = int(scene.spp)
        self.spp, self.pixels = spp, self.shape[0] * self.shape[1]
        if spp == 1:
            u, v = cv.tangent_to_uv(samples.x, samples.y, self.rows, self.cols)
            self._u, self._v, self._uv = mi.Float(_aligned(u)), mi.Float(_aligned(v)), None
        else:
            self._u = self._v = None
            self._uv = samples.uv()
        dr.eval(self._u, self._v, self._uv, self._cube, self._albedo_const)

    # ------------------------------------------------------------------
    # The Technique interface (hzval.technique)
    # ------------------------------------------------------------------

    @classmethod
    def build(cls, ctx: Context, *, horizon_map=None, encoding=None, **settings) -> "Approximation":
        """From a context; ``horizon_map`` (layer paths) and ``encoding``
        (:class:`hzval.external.Encoding`) replace the bake's horizon map by an external one, whose
        convention is checked against hzval's exact bake (:func:`hzval.external.detect`)."""
        if not horizon_map:
            return cls(ctx.scene, ctx.bake, ctx.albedo, samples=ctx.samples(), **settings)
        raw = external.read_layers(list(horizon_map))
        enc = (encoding or external.Encoding()).validate()
        if raw.shape[:2] != ctx.height.shape:
            raise InputError(horizon_map[0], f"is {raw.shape[1]}x{raw.shape[0]}, the height map "
                                             f"{ctx.height.shape[1]}x{ctx.height.shape[0]}")
        sines = external.to_hzval(raw, enc)
        found = external.detect(raw, _reference_horizons(ctx, enc.channels), enc)
        own = cls(ctx.scene, dataclasses.replace(ctx.bake, horizon=sines), ctx.albedo, samples=ctx.samples(),
                  **settings)
        own.external = [str(p) for p in horizon_map]
        own.extras = {"external_bake": {**found, "paths": own.external}}
        own.warnings = tuple(w for w in (external.advice(found),) if w)
        return own

    @classmethod
    def add_arguments(cls, parser) -> None:
        parser.add_argument("--k", type=float, default=DEFAULT_K,
                            help=f"horizon map: shadow hardness k of F = clamp(k (Lz - s) + 1) (default {DEFAULT_K:g})")
        parser.add_argument("--path", choices=PATHS, default="exact",
                            help="horizon map: exact float math, or emulate the GPU's 8-bit textures and weight "
                                 "cube map (default exact)")
        parser.add_argument("--ambient", choices=AMBIENT_TERMS, default="mean_cos2",
                            help="horizon map: which ambient-map definition to shade with (default mean_cos2)")
        parser.add_argument("--horizon-map", default=None, metavar="P0,P1",
                            help="horizon map: your own bake's RGBA layers (8/16-bit PNG or EXR), in place of "
                                 "hzval's; its encoding from --horizon-encoding or the --horizon-* options "
                                 "(default: hzval's layout)")
        parser.add_argument("--horizon-encoding", type=Path, default=None, metavar="FILE.toml",
                            help="horizon map: a TOML file of channels, azimuth0, direction, y, values")
        d = external.Encoding()
        parser.add_argument("--horizon-channels", type=int, default=None, help=f"(default {d.channels})")
        parser.add_argument("--horizon-azimuth0", type=float, default=None, metavar="DEG",
                            help=f"azimuth of channel 0 (default {d.azimuth0:g})")
        parser.add_argument("--horizon-direction", choices=["ccw", "cw"], default=None,
                            help=f"which way channels turn (default {d.direction})")
        parser.add_argument("--horizon-y", choices=["up", "down"], default=None,
                            help=f"the baker's +y on screen (default {d.y})")
        parser.add_argument("--horizon-values", choices=external.VALUES, default=None,
                            help=f"what a channel holds (default {d.values})")
        parser.add_argument("--storage", choices=STORAGES, default=None,
                            help="horizon map: how its textures are stored: float, 8-bit or block-compressed "
                                 "(BC7, BC3, BC1, BC4; -sqrt stores square-root sines) (default float, u8 with "
                                 "--path gpu)")

    @classmethod
    def settings_from_args(cls, args) -> dict:
        if not (math.isfinite(args.k) and args.k > 0):
            raise InputError("--k", f"must be a positive number, got {args.k}")
        out = {"k": args.k, "path": args.path, "ambient": args.ambient,
               **({"storage": args.storage} if args.storage else {})}
        if args.horizon_map:
            enc = external.Encoding.from_toml(args.horizon_encoding) if args.horizon_encoding else external.Encoding()
            given = {"channels": args.horizon_channels, "azimuth0": args.horizon_azimuth0,
                     "direction": args.horizon_direction, "y": args.horizon_y, "values": args.horizon_values}
            enc = dataclasses.replace(enc, **{k: v for k, v in given.items() if v is not None}).validate()
            out.update(horizon_map=tuple(p.strip() for p in args.horizon_map.split(",") if p.strip()),
                       encoding=enc)
        return out

    @classmethod
    def check_settings(cls, bake_params, settings: dict) -> None:
        if settings.get("path") == "gpu" and bake_params.directions != cv.CHANNEL_COUNT:
            raise InputError("--path", f"the gpu path emulates Lengyel's {cv.CHANNEL_COUNT}-channel weight cube map; "
                                       f"a bake of {bake_params.directions} directions needs --path exact")

    @classmethod
    def check_variants(cls) -> list[Variant]:
        return [Variant("approx", {"path": "exact"}), Variant("approx_gpu", {"path": "gpu"})]

    @classmethod
    def tradeoff_variants(cls) -> list[Variant]:
        v = [Variant("8-bit horizon map", {"storage": "u8"}, kind="approx")]
        v += [Variant(f"{name} horizon map ({hz_storage.get(name).label})", {"storage": name}, kind="approx")
              for name in ("u8-sqrt", "bc7", "bc7-sqrt", "bc3", "bc1", "bc4")]
        v += [Variant("cube-map weights", {"weights": "cube"}, kind="approx"),
              Variant("GPU path: 8-bit map + cube weights", {"storage": "u8", "weights": "cube"}, kind="approx")]
        v += [Variant(f"k = {k:g}", {"k": float(k)}, kind="approx") for k in (2, 4, 16, 32)]
        v.append(Variant("k fitted to the truth", {"k": "fit"}, kind="approx"))
        return v

    @classmethod
    def fit(cls, ctx: Context, settings: dict, visibility: list[np.ndarray], azimuths) -> dict:
        """``settings`` with ``k = "fit"`` replaced by the k that minimises the sweep's mean ``|F - V|``
        against ``visibility`` (one layer per azimuth): a golden-section search on ``log k`` in [1, 128]."""
        if settings.get("k") != "fit":
            return settings
        ap = cls.build(ctx, **{**settings, "k": DEFAULT_K})

        def cost(logk: float) -> float:
            k = math.exp(logk)
            return float(np.mean([np.mean(np.abs(ap.render(az, k=k).layers["factor"] - V))
                                  for az, V in zip(azimuths, visibility)]))

        return {**settings, "k": _golden_section(cost, math.log(1.0), math.log(128.0))}

    def storage_bytes(self) -> int:
        """The horizon map as stored (:meth:`hzval.storage.Storage.bytes`) and the weight cube map."""
        rows, cols, ch = self.bake.horizon.shape
        return hz_storage.get(self.storage).bytes(rows, cols, ch) + (CUBE_BYTES if self.weights == "cube" else 0)

    # ------------------------------------------------------------------
    # Public
    # ------------------------------------------------------------------

    @property
    def parameters(self) -> dict:
        """The technique's settings, for ``metrics.json``."""
        out = {"path": self.path, "storage": self.storage, "weights": self.weights, "k": self.k,
               "bake": "external: " + ", ".join(self.external) if self.external else "hzval",
               "simulated": list(self.simulated)}
        if self.directions != cv.CHANNEL_COUNT:
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
            out.update(cube_size=CUBE_SIZE, cube_bits=8,
                       cube_filter="bilinear within the face, clamped to its edge")
        return out

    def render(self, azimuth_deg: float, *, shadows: bool = True,
               elevation_deg: float | None = None, k: float | None = None) -> Frame:
        """Render the frame for the light at ``azimuth_deg`` (degrees).

        ``elevation_deg`` defaults to the scene light's, ``k`` to the
        object's (a sweep over k reuses the textures and kernels). ``shadows=False``
        leaves out the horizon factor (plain normal mapping, the report's
        comparison column); the other declared effects stay. Layers:
        ``factor`` (pixel mean of F, when shadowing), ``ambient`` (A) and
        ``reflection_occlusion`` (o), each where declared. ``seconds`` is the
        wall time of the frame, kernels synchronised and images read back.
        """
        import drjit as dr
        import mitsuba as mi

        t0 = time.perf_counter()
        elevation = self.scene.light.elevation_deg if elevation_deg is None else float(elevation_deg)
        uni = self._uniforms(azimuth_deg, elevation, shadows, k)
        if self.spp == 1:
            out = self._shade(self._u, self._v, uni, shadows, pixel=dr.arange(mi.UInt32, self.pixels))
        else:
            names, zeros = self._output_layout(shadows)
            P, spp = self.pixels, self.spp
            pixel = dr.arange(mi.UInt32, P)

            def body(i, *acc):
                uv = dr.gather(mi.Point2f, self._uv, pixel * spp + i)
                o = self._shade(uv.x, uv.y, uni, shadows, pixel=pixel)
                return (i + 1, *[a + b for a, b in zip(acc, self._flatten(o, names))])

            state = dr.while_loop(state=(dr.zeros(mi.UInt32, P), *[dr.zeros(mi.Float, P) for _ in range(zeros)]),
                                  cond=lambda i, *acc: i < spp, body=body)
            inv = 1.0 / spp
            out = self._unflatten([a * inv for a in state[1:]], names)
        dr.eval(out)
        H, W = self.shape

        def plane(v):
            # a term that does not vary (e.g. unshadowed grey light, 1 spp) is a width-1 array
            return np.broadcast_to(np.asarray(v, dtype=np.float32), (H * W,)).reshape(H, W)

        image = np.stack([plane(c) for c in out.pop("image")], axis=-1)
        layers = {name: plane(val) for name, val in out.items()}
        return Frame(float(azimuth_deg), elevation, image, layers, seconds=time.perf_counter() - t0)

    def sample(self, x, y, azimuth_deg: float, elevation_deg: float | None = None, *,
               shadows: bool = True, k: float | None = None) -> dict[str, np.ndarray]:
        """Per-point values at tangent-space points ``(x, y)`` (texel units), no averaging.

        For probing single texels (at ``x = col + 0.5``, ``y = rows - row - 0.5``
        the bilinear filter returns that texel exactly). Keys as in
        :meth:`render`'s layers plus ``image`` ``(n, 3)`` and, when
        shadowing, ``horizon_sine`` (``s`` of eq. 5.3/5.4).
        """
        import drjit as dr
        import mitsuba as mi

        u, v = (mi.Float(c.ravel()) for c in cv.tangent_to_uv(x, y, self.rows, self.cols))
        elevation = self.scene.light.elevation_deg if elevation_deg is None else float(elevation_deg)
        uni = self._uniforms(azimuth_deg, elevation, shadows, k)
        out = self._shade(u, v, uni, shadows, probe=True)
        dr.eval(out)
        image = np.stack([np.asarray(c, dtype=np.float32) for c in out.pop("image")], axis=-1)
        res = {name: np.asarray(val, dtype=np.float32) for name, val in out.items()}
        res["image"] = image
        return res

    # ------------------------------------------------------------------
    # Kernels
    # ------------------------------------------------------------------

    def _uniforms(self, azimuth_deg: float, elevation_deg: float, shadows: bool,
                  k: float | None = None) -> dict:
        """The frame's uniforms, evaluated in a one-lane kernel from an opaque ``L``.

        The light's channel weights and half vector are the same for every
        sample; computing them once per frame keeps the shading kernel lean.
        """
        import drjit as dr
        import mitsuba as mi

        L = dr.opaque(mi.Vector3f, [float(c) for c in cv.light_direction(azimuth_deg, elevation_deg)])
        uni = {"L": L, "k": self._k}
        if k is not None:
            if not (math.isfinite(k) and k > 0):
                raise InputError("k", f"the shadow hardness must be a positive number, got {k}")
            uni["k"] = dr.opaque(mi.Float, float(k))
        if self._shadow and shadows:
            uni["w"] = self._channel_weights(L)
        if self._specular:
            uni["h"] = dr.normalize(L + self._view)
        dr.eval(uni)
        return uni

    def _channel_weights(self, d) -> list:
        """The ``D`` channel weights toward the azimuth of directions ``d`` (path-specific)."""
        return self._exact_weights(d, self.directions) if self.weights == "analytic" else self._cube_weights(d)

    @staticmethod
    def _exact_weights(d, directions: int = cv.CHANNEL_COUNT) -> list:
        """Exact linear interpolation between the two channels adjacent to ``atan2(dy, dx)``.

        Channel ``c`` of ``D = directions`` gets the tent ``max(0, 1 - dist(t,
        c))`` with ``t`` the azimuth in channel units (``360 / D`` degrees)
        and ``dist`` the circular distance modulo ``D``:
        :func:`hzval.conventions.channel_weights` without a per-lane channel
        index. ``t`` in [0, D]: azimuths of 360 deg or -0 deg land on D or 0,
        both of which give channel 0 all the weight.
        """
        import drjit as dr

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

        Face and face coordinates follow OpenGL (table 8.19, ties to x, then
        y, then z, as :func:`hzval.conventions.cube_lookup`); bilinear within
        the face, clamped to its edge texels. Returns ``f0`` (layer 0) then
        ``f1`` (layer 1) of Listing 5.1: ``clamp(+-(2f - 1), 0, 1)`` applied
        to the *filtered* 8-bit values, as the shader does.
        """
        import drjit as dr
        import mitsuba as mi

        x, y, z = d.x, d.y, d.z
        ax, ay, az = dr.abs(x), dr.abs(y), dr.abs(z)
        use_x = (ax >= ay) & (ax >= az)
        use_y = ~use_x & (ay >= az)
        face = dr.select(use_x, dr.select(x >= 0, mi.UInt32(0), mi.UInt32(1)),
                         dr.select(use_y, dr.select(y >= 0, mi.UInt32(2), mi.UInt32(3)),
                                   dr.select(z >= 0, mi.UInt32(4), mi.UInt32(5))))
        ma = dr.select(use_x, ax, dr.select(use_y, ay, az))
        sc = dr.select(use_x, dr.select(x >= 0, -z, z), dr.select(use_y | (z >= 0), x, -x))
        tc = dr.select(use_y, dr.select(y >= 0, z, -z), -y)
        inv = dr.rcp(ma)
        n = CUBE_SIZE
        # texel space: centres at integers 0..n-1; clamp to the edge centres
        ps = dr.clip(dr.fma(sc * inv, 0.5 * n, 0.5 * n - 0.5), 0.0, n - 1.0)
        pt = dr.clip(dr.fma(tc * inv, 0.5 * n, 0.5 * n - 0.5), 0.0, n - 1.0)
        c0 = dr.minimum(mi.UInt32(ps), n - 2)   # ps >= 0: truncation is floor
        r0 = dr.minimum(mi.UInt32(pt), n - 2)
        fs, ft = ps - mi.Float(c0), pt - mi.Float(r0)
        base = (face * n + r0) * n + c0
        t00 = dr.gather(mi.Vector4f, self._cube, base)
        t01 = dr.gather(mi.Vector4f, self._cube, base + 1)
        t10 = dr.gather(mi.Vector4f, self._cube, base + n)
        t11 = dr.gather(mi.Vector4f, self._cube, base + n + 1)
        f = dr.lerp(dr.lerp(t00, t01, fs), dr.lerp(t10, t11, fs), ft)
        f0 = [dr.clip(dr.fma(f[i], 2.0, -1.0), 0.0, 1.0) for i in range(4)]
        f1 = [dr.clip(dr.fma(f[i], -2.0, 1.0), 0.0, 1.0) for i in range(4)]
        return f0 + f1

    def _fetch(self, u, v, pixel=None) -> dict:
        """Filtered texture values at texture coordinates ``(u, v)`` of lanes in the pixels ``pixel``
        (whose footprints a mip filter reads; ``None``: level 0)."""
        import mitsuba as mi

        if self._texture is None:
            return {}
        vals = self._texture.eval(mi.Point2f(u, v), pixel)
        return {name: vals[s] for name, s in self._slots.items()}

    def _shade(self, u, v, uni: dict, shadows: bool, probe: bool = False, pixel=None) -> dict:
        """Per-sample outputs: ``image`` (Color3f) and the declared layers."""
        import drjit as dr
        import mitsuba as mi

        tex = self._fetch(u, v, pixel)
        L, E = uni["L"], self._E
        out = {}
        lit = L.z > 0.0   # the flat surface's tangent plane (module docstring)

        n = dr.normalize(mi.Vector3f(*tex["normal"])) if "normal" in tex else None
        albedo = None
        if self._diffuse or self._ambient:
            albedo = self._albedo_const if self._albedo_const is not None else mi.Color3f(*tex["albedo"])
        direct = shading.direct(n, L, None, albedo, E, diffuse=self._diffuse, specular=self._specular,
                                h=uni.get("h"))
        direct = dr.select(lit, direct, 0.0)

        if self._shadow and shadows:
            F, s = shadow_factor(tex["horizon"], uni["w"], L.z, uni["k"])
            image = direct * F
            out["factor"] = F
            if probe:
                out["horizon_sine"] = s
        else:
            image = direct

        if self._ambient:
            A = tex["ambient"][0]
            image = image + shading.sky(albedo, A, E)
            out["ambient"] = A

        if self._reflection:
            # r = reflect(-v, n) = 2 (n.v) n - v (the top view's v = +z: (2 nz nx, 2 nz ny, 2 nz^2 - 1))
            if self.scene.camera.kind == "top":
                r = mi.Vector3f(2.0 * n.z * n.x, 2.0 * n.z * n.y, dr.fma(2.0 * n.z, n.z, -1.0))
            else:
                r = 2.0 * dr.dot(n, self._view) * n - self._view
            s_r = _dot(tex["horizon"], self._channel_weights(r))
            o = dr.clip(dr.fma(r.z - s_r, self._fade, 1.0), 0.0, 1.0)
            out["reflection_occlusion"] = o * o

        out["image"] = image
        return out

    # the loop state of render() is a flat list of Floats
    def _output_layout(self, shadows: bool) -> tuple[list[tuple[str, int]], int]:
        names = [("image", 3)]
        if self._shadow and shadows:
            names.append(("factor", 1))
        if self._ambient:
            names.append(("ambient", 1))
        if self._reflection:
            names.append(("reflection_occlusion", 1))
        return names, sum(n for _, n in names)

    @staticmethod
    def _flatten(out: dict, names) -> list:
        flat = []
        for name, n in names:
            if n == 3:
                flat.extend(out[name][i] for i in range(3))
            else:
                flat.append(out[name])
        return flat

    @staticmethod
    def _unflatten(flat: list, names) -> dict:
        import mitsuba as mi

        out, i = {}, 0
        for name, n in names:
            out[name] = mi.Color3f(*flat[i:i + 3]) if n == 3 else flat[i]
            i += n
        return out


#: Samples per chunk of :func:`interleaved`.
_CHUNK = 1 << 22


def interleaved(x: np.ndarray, y: np.ndarray, convert=None):
    """``mi.Float`` of ``convert(x, y)`` (default: ``(x, y)``) interleaved pair by pair, float32,
    made in Dr.Jit kernels on every core, :data:`_CHUNK` samples at a time so that no full-size
    temporary is made (the output alone: 2.1 GB at 4096 x 4096 x 16). ``convert`` takes and
    returns ``mi.Float`` arrays (e.g. :func:`hzval.conventions.tangent_to_uv`). Each value is a
    gather from a copy of its chunk (a contiguous load from mapped NumPy memory would compile
    one kernel per alignment); the result is Dr.Jit's own, aligned, memory. 67M pairs at 2048 x
    2048 x 16: 0.2 s against 1.5 s in NumPy chunks, the same bits."""
    import drjit as dr
    import mitsuba as mi

    n = int(np.size(x))
    out = dr.empty(mi.Float, 2 * n)
    for a in range(0, n, _CHUNK):
        b = min(n, a + _CHUNK)
        j = dr.arange(mi.UInt32, 2 * (b - a))
        i = j >> 1
        first = dr.gather(mi.Float, mi.Float(np.ascontiguousarray(x[a:b], np.float32)), i)
        second = dr.gather(mi.Float, mi.Float(np.ascontiguousarray(y[a:b], np.float32)), i)
        if convert is not None:
            first, second = convert(first, second)
        # the chunk's offset is opaque: one kernel for every chunk
        dr.scatter(out, dr.select((j & 1) == 1, second, first), j + dr.opaque(mi.UInt32, 2 * a))
        dr.eval(out)
    return out


def _aligned_empty(size: int, alignment: int = 64) -> np.ndarray:
    """An uninitialised float32 array of ``size`` that starts on an ``alignment``-byte boundary."""
    buf = np.empty(size + alignment // 4, dtype=np.float32)
    start = (-buf.ctypes.data % alignment) // 4
    return buf[start:start + size]


def _aligned(a, alignment: int = 64) -> np.ndarray:
    """A C-contiguous float32 copy of ``a`` that starts on an ``alignment``-byte boundary.

    On the LLVM backend Dr.Jit maps NumPy memory without copying it, and it
    reads a texel's channels as one packet (vector loads) only from aligned
    memory; from NumPy's 16-byte-aligned buffers it fell back to one scalar
    gather per channel and lane: 2-4x slower frames, varying from run to run
    with where NumPy's allocation happened to land. (CUDA copies anyway.)
    """
    a = np.asarray(a, dtype=np.float32)
    out = _aligned_empty(a.size, alignment).reshape(a.shape)
    out[...] = a
    return out


def _dot(h: list, w: list):
    """``sum_c w_c h_c`` over the channels, as one RGBA dot product per layer, summed
    in layer order (eq. 5.3: two layers for 8 channels, four for 16)."""
    import drjit as dr

    n = cv.CHANNELS_PER_LAYER
    total = None
    for first in range(0, len(h), n):
        s = h[first] * w[first]
        for c in range(first + 1, first + n):
            s = dr.fma(h[c], w[c], s)
        total = s if total is None else total + s
    return total


def shadow_factor(h: list, w: list, Lz, k, *, straight_through: bool = False):
    """``(F, s)``: eq. 5.4's ``F = clamp(k (Lz - s) + 1, 0, 1)`` of the filtered channels ``h`` and the
    channel weights ``w`` (``s = sum_c w_c h_c``, :func:`_dot`); the shading kernel's own arithmetic.

    ``straight_through``: for the fit (:mod:`hzval.fit`), ``F``'s value is the same but its gradient
    is that of the unclamped ``k (Lz - s) + 1`` (a straight-through clamp), so that a texel whose
    factor is saturated on the wrong side (0 where the truth is lit) still learns which way to move."""
    import drjit as dr

    s = _dot(h, w)
    z = dr.fma(Lz - s, k, 1.0)
    F = dr.clip(z, 0.0, 1.0)
    return (dr.replace_grad(F, z) if straight_through else F), s


def _reference_horizons(ctx: Context, directions: int) -> np.ndarray:
    """hzval's own horizons of the context's height map to detect an external bake's convention by:
    the exact bake for 8 directions, a wide seed bake (radius 32, 64 bins) for 16."""
    from hzval.bake import BakeParams, bake

    p = ctx.bake.params
    params = BakeParams(depth=p.depth, boundary=p.boundary, method="exact") if directions == cv.CHANNEL_COUNT \
        else BakeParams(depth=p.depth, boundary=p.boundary, radius=32, angles=64, directions=directions)
    return bake(ctx.height, params.validate()).horizon


def _validate(path: str, storage: str, weights: str, directions: int, ambient: str, k: float, fade: float) -> None:
    """Every setting of :class:`Approximation`, checked before anything is uploaded."""
    for what, value, allowed in (("path", path, PATHS), ("storage", storage, STORAGES),
                                 ("weights", weights, WEIGHTS), ("ambient", ambient, AMBIENT_TERMS)):
        if value not in allowed:
            raise InputError(what, f"must be one of {', '.join(allowed)}, got {value!r}")
    if weights == "cube" and directions != cv.CHANNEL_COUNT:
        raise InputError("weights", f"the weight cube map (and so the gpu path) holds {cv.CHANNEL_COUNT} "
                                    f"channel weights; this bake stores {directions} directions: use "
                                    "path='exact' / weights='analytic'")
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


# --------------------------------------------------------------------------
# The unshadowed shading that per-pixel techniques build on
# --------------------------------------------------------------------------

class Unshadowed:
    """The flat surface's shading without any technique's shadow, split as a factor needs it.

    Techniques whose shadow factor ``F`` is computed per pixel (terrain,
    pom) shade with :func:`hzval.shading.compose`: ``direct * F + ambient``.
    ``render`` gives the frame of plain normal mapping (the report's
    "normal mapping only" column), its ``direct`` part and the ``ambient``
    image, which is the same for every light (the sky is not shadowed by
    the light's horizon), rendered once: an ambient-only render with the
    light below the horizon, where the direct term is 0. The horizon map's
    reflection fade is no other technique's, so it is left out. The last
    frame is kept: every technique of a sweep frame shares one render.
    """

    def __init__(self, scene: Scene, bake, albedo: np.ndarray | None = None, *, ambient: str = "mean_cos2",
                 samples: lookup.Samples | None = None):
        effects = tuple(e for e in scene.effects if e not in ("shadow", "reflection_occlusion"))
        self.scene = scene
        self._grey = not effects            # shadows alone: the direct term is E, grey
        self._plain = None if self._grey else Approximation(replace_effects(scene, effects), bake, albedo,
                                                            ambient=ambient, samples=samples)
        self.ambient_image = None
        if "ambient" in effects:
            self.ambient_image = Approximation(replace_effects(scene, ("ambient",)), bake, albedo, ambient=ambient,
                                               samples=samples).render(0.0, elevation_deg=-90.0).image
        self.shape = image_shape(*bake.normal.shape[:2], scene.camera)
        self._last: tuple | None = None

    def render(self, azimuth_deg: float, elevation_deg: float | None = None) -> tuple[Frame, np.ndarray]:
        """``(frame, direct)``: the unshadowed frame and its direct part ``(H, W, 3)``."""
        e = self.scene.light.elevation_deg if elevation_deg is None else float(elevation_deg)
        key = (float(azimuth_deg), e)
        if self._last is None or self._last[0] != key:
            if self._grey:
                t0 = time.perf_counter()
                E = float(self.scene.light.irradiance) if e > 0 else 0.0
                frame = Frame(float(azimuth_deg), e, np.full((*self.shape, 3), E, np.float32),
                              seconds=time.perf_counter() - t0)
            else:
                frame = self._plain.render(azimuth_deg, shadows=False, elevation_deg=e)
            direct = frame.image if self.ambient_image is None else frame.image - self.ambient_image
            self._last = (key, frame, direct)
        return self._last[1], self._last[2]

    def shade(self, azimuth_deg: float, elevation_deg: float | None, factor: np.ndarray, seconds: float,
              layers: dict | None = None) -> Frame:
        """The frame of a technique whose per-pixel factor is ``factor``, found in ``seconds``:
        the unshadowed render's time counts toward it, as an engine would pay it."""
        frame, direct = self.render(azimuth_deg, elevation_deg)
        image = shading.compose(direct, factor, self.ambient_image)
        out = {k: v for k, v in frame.layers.items() if k != "reflection_occlusion"}
        out.update(layers or {}, factor=np.asarray(factor, np.float32))
        return Frame(frame.azimuth_deg, frame.elevation_deg, image, out, seconds=seconds + frame.seconds)


def unshadowed(ctx: Context) -> Unshadowed:
    """The :class:`Unshadowed` shading of a context, built once and shared by its techniques."""
    return ctx.shared("unshadowed", lambda: Unshadowed(ctx.scene, ctx.bake, ctx.albedo, samples=ctx.samples()))


class HeightFieldShadow(Technique):
    """Base of the techniques that read the height map and multiply the :class:`Unshadowed`
    shading by a per-pixel factor (terrain, pom): they are built as ``cls(scene, height,
    bake=..., albedo=..., unshadowed=..., **settings)``."""

    @classmethod
    def build(cls, ctx: Context, **settings) -> "HeightFieldShadow":
        return cls(ctx.scene, ctx.height, bake=ctx.bake, albedo=ctx.albedo, unshadowed=unshadowed(ctx),
                   samples=ctx.samples(), **settings)

    @staticmethod
    def shading_for(scene: Scene, height: np.ndarray, bake, albedo, shared: Unshadowed | None,
                    samples: lookup.Samples | None = None) -> Unshadowed:
        """``shared``, or the unshadowed shading of a technique built on its own: from ``bake``, or
        without one from the normal map alone (:func:`hzval.bake.normals_only`), which serves
        ``diffuse`` and ``specular``; ``ambient`` needs the bake's ambient map."""
        if shared is not None:
            return shared
        if bake is None:
            if scene.declares("ambient"):
                raise InputError("bake", "ambient needs the bake's textures")
            bake = normals_only(height, scene.material.depth, scene.material.boundary)
        return Unshadowed(scene, bake, albedo, samples=samples)
