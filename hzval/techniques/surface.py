"""The flat surface's shading, which every technique builds on, in Dr.Jit.

The truth (:mod:`hzval.truth.plane`) ray-traces the displaced mesh; the techniques
shade the flat plane ``z = 0`` from the bake's textures alone, as a real-time
renderer would, and compute only the effects that the scene declares
(docs/ARCHITECTURE.md, "Effects"). This module owns that shading:

The design in full: docs/internals.md, "hzval.techniques.surface".
"""

from __future__ import annotations

import time

import numpy as np
from typing_extensions import override

from hzval.bake.maps import normals_only
from hzval.core import backend, shading
from hzval.core import conventions as cv
from hzval.core.backend import dr, mi
from hzval.core.errors import InputError
from hzval.scene import lookup
from hzval.scene.spec import EFFECTS, Frame, Scene, image_shape, load_albedo
from hzval.techniques.registry import Context, Technique, replace_effects

__all__ = ["FlatShading", "Unshadowed", "unshadowed", "HeightFieldShadow", "NOT_MODELLED"]

#: Declarable effects that no flat-surface shading models.
NOT_MODELLED: tuple[str, ...] = ("interreflection",)


class FlatShading:
    """The flat surface shaded from the bake's textures at the scene's samples (module docstring).

    ``scene``: camera, light, declared effects, samples; ``bake``: the
    textures (its boundary sets their wrap mode, its shape the image's, times
    the camera's supersampling); ``albedo``: linear ``(rows, cols, 3)``, or
    ``None`` for the scene's (:func:`hzval.scene.spec.load_albedo`), read only by
    ``diffuse`` and ``ambient`` (a uniform one enters the kernel as a
    constant); ``ambient``: which ambient map (``"mean_cos2"`` or
    ``"mean_cos"``); ``samples``: where to read (:func:`hzval.scene.lookup.samples_for`).

    ``simulated``: the effects computed, in :data:`hzval.scene.spec.EFFECTS` order;
    ``shape``: ``(height, width)`` of every image rendered.
    """

    not_modelled: tuple[str, ...] = NOT_MODELLED

    def __init__(
        self,
        scene: Scene,
        bake,
        albedo: np.ndarray | None = None,
        *,
        ambient: str = "mean_cos2",
        height: np.ndarray | None = None,
        samples: lookup.Samples | None = None,
    ):
        backend.variant()
        self.scene, self.bake, self.ambient = scene, bake, ambient
        rows, cols = bake.normal.shape[:2]
        self.rows, self.cols = rows, cols
        self.shape = image_shape(rows, cols, scene.camera)
        self.simulated = tuple(e for e in EFFECTS if scene.declares(e) and e not in self.not_modelled)
        eff = set(self.simulated)
        self._shadow = "shadow" in eff
        self._diffuse = "diffuse" in eff
        self._specular = "specular" in eff
        self._ambient = "ambient" in eff
        self._reflection = "reflection_occlusion" in eff
        samples = samples if samples is not None else lookup.samples_for(scene, rows, cols, height)
        self._upload_textures(albedo, samples)
        self._upload_constants()
        self._upload_samples(samples)

    # -- hooks of a technique shaded in this kernel ---------------------------------------------

    def _extra_planes(self) -> list[tuple[str, np.ndarray]]:
        """Texture planes packed before the shading's own, ``(name, (rows, cols[, C]))``."""
        return []

    def _max_channels(self) -> slice | None:
        """Return the packed channels a ``max`` mip chain takes the maximum of, and a storage quantises.

        See :func:`hzval.scene.lookup.mip_chain`.
        """
        return None

    def _mip_quantise(self):
        """Return what the storage of :meth:`_max_channels` makes of each mip level; ``None``: float."""
        return None

    def _extra_uniforms(self, uni: dict, shadows: bool, overrides: dict) -> None:
        """Add a technique's per-frame uniforms to ``uni`` (``overrides``: :meth:`render`'s keywords)."""
        if overrides:
            raise TypeError(f"unexpected render settings {', '.join(overrides)}")

    def _shadowed(self, direct, tex: dict, uni: dict, out: dict, shadows: bool, probe: bool):
        """Return the direct term times the technique's factor (none here), its layers into ``out``."""
        return direct

    def _extra_layers(self, tex: dict, n, out: dict, uni: dict) -> None:
        """Add a technique's layers after the ambient term.

        ``n`` is the normal map's normal; ``uni`` is the frame's uniforms, on a model the sample's own
        (:meth:`_lane_uniforms`).
        """

    def _factor_layers(self) -> tuple[str, ...]:
        """Return the layers that are shadow factors.

        On a model the base mesh's shadow ``M`` multiplies them.
        """
        return ("factor",)

    def _extra_layout(self, shadows: bool) -> tuple[list, list]:
        """Return the technique's layers of :meth:`_shade`, ``(name, channels)``.

        They are those before the ambient term's layer (its factor) and those after (:meth:`_extra_layers`).
        """
        return [], []

    # -- set-up ---------------------------------------------------------------------------------

    def _upload_textures(self, albedo, samples: lookup.Samples) -> None:
        """Upload one packed texture holding only the channels needed.

        Each sample thus computes one set of bilinear indices, filtered as the scene's lookup says
        (:class:`hzval.scene.lookup.Filtered`).
        """
        bake, rows, cols = self.bake, self.rows, self.cols
        planes: list[np.ndarray] = []
        self._slots: dict[str, slice] = {}

        def add(name: str, data: np.ndarray) -> None:
            data = np.asarray(data, dtype=np.float32)
            data = data[..., None] if data.ndim == 2 else data
            start = sum(p.shape[-1] for p in planes)
            self._slots[name] = slice(start, start + data.shape[-1])
            planes.append(data)

        for name, data in self._extra_planes():
            add(name, data)
        if self._diffuse or self._specular or self._reflection:
            add("normal", bake.normal)
        self._albedo_const = None
        if self._diffuse or self._ambient:
            a = (
                load_albedo(self.scene.material, rows, cols)
                if albedo is None
                else np.asarray(albedo, np.float32)
            )
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
            self._texture = lookup.Filtered(
                np.concatenate(planes, axis=-1),
                bake.params.boundary,
                self.scene.lookup,
                samples,
                max_channels=self._max_channels(),
                aligned=lookup.aligned,
                quantise=self._mip_quantise(),
            )

    def _upload_constants(self) -> None:
        """Per-object constants, opaque so that objects share kernels."""
        # toward the (orthographic) camera; a perspective one is refused with the effects that read it
        self._view = mi.Vector3f(*(self.scene.camera.toward_eye() or (0.0, 0.0, 1.0)))
        self._E = dr.opaque(mi.Float, float(self.scene.light.irradiance))

    def _upload_samples(self, samples: lookup.Samples) -> None:
        """Sample positions as texture coordinates.

        One sample per pixel: two plain arrays. More: (u, v) pairs in the scene's pixel-major order, which the
        per-pixel loop gathers as one packet per sample; a pixel's samples share cache lines (a sample-major
        layout, with its stride of a power-of-two number of pixels, thrashed the caches: 2x slower).
        """
        spp = int(self.scene.spp)
        self.spp, self.pixels = spp, self.shape[0] * self.shape[1]
        if spp == 1:
            u, v = cv.tangent_to_uv(samples.x, samples.y, self.rows, self.cols)
            self._u, self._v, self._uv = mi.Float(lookup.aligned(u)), mi.Float(lookup.aligned(v)), None
        else:
            self._u = self._v = None
            self._uv = samples.uv()
        # on a model: each sample's tangent frame and the base mesh's shadow (lookup.Samples)
        self._frames, self._macro = samples.frame_array(), samples.macro
        dr.eval(self._u, self._v, self._uv, self._albedo_const, self._frames)

    # -- frames ---------------------------------------------------------------------------------

    def render(
        self,
        azimuth_deg: float,
        *,
        shadows: bool = True,
        elevation_deg: float | None = None,
        dark: bool = False,
        **overrides,
    ) -> Frame:
        """Return the frame of the light at ``azimuth_deg`` (degrees).

        ``elevation_deg`` defaults to the scene light's. ``shadows=False`` leaves out a technique's factor;
        ``overrides``: a technique's per-frame settings (:meth:`_extra_uniforms`); ``dark``: no direct light
        at all (the ambient term alone; on a model a light below the world's horizon still lights the samples
        that face down). ``seconds`` is the frame's wall time, kernels synchronised and images read back.
        """
        t0 = time.perf_counter()
        elevation = self.scene.light.elevation_deg if elevation_deg is None else float(elevation_deg)
        uni = self._uniforms(azimuth_deg, elevation, shadows, overrides)
        uni["dark"] = bool(dark)
        if self.spp == 1:
            pixel = dr.arange(mi.UInt32, self.pixels)
            out = self._shade(self._u, self._v, uni, shadows, pixel=pixel, index=pixel)
        else:
            out = self._shade_samples(uni, shadows)
        dr.eval(out)
        H, W = self.shape

        def plane(v):
            # a term that does not vary (e.g. unshadowed grey light, 1 spp) is a width-1 array
            return np.broadcast_to(np.asarray(v, dtype=np.float32), (H * W,)).reshape(H, W)

        image = np.stack([plane(c) for c in out.pop("image")], axis=-1)
        layers = {name: plane(val) for name, val in out.items()}
        return Frame(float(azimuth_deg), elevation, image, layers, seconds=time.perf_counter() - t0)

    def _shade_samples(self, uni: dict, shadows: bool) -> dict:
        """Return the pixel means of :meth:`_shade` over each pixel's samples, in one kernel."""
        names, zeros = self._output_layout(shadows)
        P, spp = self.pixels, self.spp
        pixel = dr.arange(mi.UInt32, P)

        def body(i, *acc):
            uv = dr.gather(mi.Point2f, self._uv, pixel * spp + i)
            o = self._shade(uv.x, uv.y, uni, shadows, pixel=pixel, index=pixel * spp + i)
            return (i + 1, *[a + b for a, b in zip(acc, _flatten(o, names))])

        state = dr.while_loop(
            state=(dr.zeros(mi.UInt32, P), *[dr.zeros(mi.Float, P) for _ in range(zeros)]),
            cond=lambda i, *acc: i < spp,
            body=body,
        )
        inv = 1.0 / spp
        return _unflatten([a * inv for a in state[1:]], names)

    def sample(
        self,
        x,
        y,
        azimuth_deg: float,
        elevation_deg: float | None = None,
        *,
        shadows: bool = True,
        **overrides,
    ) -> dict[str, np.ndarray]:
        """Return per-point values at tangent-space points ``(x, y)`` (texel units), no averaging.

        The keys are as :meth:`render`'s layers, plus ``image`` ``(n, 3)`` (at ``x = col + 0.5``, ``y = rows -
        row - 0.5`` the bilinear filter returns that texel exactly).
        """
        if self._frames is not None:
            raise NotImplementedError(
                "per-point probes are of the plane; a model's samples have their own frames"
            )
        u, v = (mi.Float(c.ravel()) for c in cv.tangent_to_uv(x, y, self.rows, self.cols))
        elevation = self.scene.light.elevation_deg if elevation_deg is None else float(elevation_deg)
        uni = self._uniforms(azimuth_deg, elevation, shadows, overrides)
        out = self._shade(u, v, uni, shadows, probe=True)
        dr.eval(out)
        image = np.stack([np.asarray(c, dtype=np.float32) for c in out.pop("image")], axis=-1)
        res = {name: np.asarray(val, dtype=np.float32) for name, val in out.items()}
        res["image"] = image
        return res

    # -- kernels --------------------------------------------------------------------------------

    def _uniforms(self, azimuth_deg: float, elevation_deg: float, shadows: bool, overrides: dict) -> dict:
        """Return the frame's uniforms, evaluated in a one-lane kernel from an opaque ``L``.

        What is the same for every sample (the half vector, a technique's light weights) is computed once a
        frame.
        """
        L = dr.opaque(mi.Vector3f, [float(c) for c in cv.light_direction(azimuth_deg, elevation_deg)])
        uni = {"L": L}
        if self._frames is not None:
            # a model: L is the world's; each sample turns it into its own frame (_lane_uniforms)
            self._lane = (shadows, dict(overrides))
            if self._macro is not None and self._shadow and shadows:
                uni["M"] = self._macro(cv.light_direction(azimuth_deg, elevation_deg))
            dr.eval(uni)
            return uni
        self._extra_uniforms(uni, shadows, dict(overrides))
        if self._specular:
            uni["h"] = dr.normalize(L + self._view)
        dr.eval(uni)
        return uni

    # -- what a fit reads (hzval.techniques.fitted.textures) -------------------------------------

    @property
    def slots(self) -> dict[str, slice]:
        """The packed texture's channels of each plane, by name."""
        return dict(self._slots)

    def texture_level(self):
        """Return the packed texture's top level, whose tensor a fit replaces.

        It is a :class:`mitsuba.Texture2f`.
        """
        return self._texture.levels[0]

    def positions(self, sample):
        """Return ``(u, v)``, the texture coordinates of the samples ``sample``.

        ``sample`` holds indices into the image's samples, pixel-major.
        """
        if self.spp == 1:
            return dr.gather(mi.Float, self._u, sample), dr.gather(mi.Float, self._v, sample)
        uv = dr.gather(mi.Point2f, self._uv, sample)
        return uv.x, uv.y

    def fetch(self, u, v) -> dict:
        """Return the filtered top-level texture values at ``(u, v)``, by plane name."""
        return self._fetch(u, v)

    def _fetch(self, u, v, pixel=None) -> dict:
        """Fetch the filtered texture values at texture coordinates ``(u, v)``.

        The lanes are in the pixels ``pixel``, whose footprints a mip filter reads (``None``: level 0).
        """
        if self._texture is None:
            return {}
        vals = self._texture.eval(mi.Point2f(u, v), pixel)
        return {name: vals[s] for name, s in self._slots.items()}

    def _lane_uniforms(self, uni: dict, index) -> tuple[dict, object]:
        """Return the uniforms of the samples ``index`` on a model.

        They are the world's light in each sample's tangent frame (:func:`hzval.scene.lookup.to_tangent`),
        what a technique derives from it, the sample's own view ``v`` toward the camera in that frame and the
        half vector toward it, and the base mesh's shadow ``M`` (``None``: none).
        """
        frame = lookup.frame_of(self._frames, index)
        shadows, overrides = self._lane
        lane = {"L": lookup.to_tangent(frame, uni["L"]), "dark": uni.get("dark", False)}
        self._extra_uniforms(lane, shadows, dict(overrides))
        if self._specular or self._reflection:
            lane["v"] = lookup.to_tangent(frame, frame[3])
        if self._specular:
            lane["h"] = dr.normalize(lane["L"] + lane["v"])
        M = dr.gather(mi.Float, uni["M"], index) if "M" in uni else None
        return lane, M

    def _shade(self, u, v, uni: dict, shadows: bool, probe: bool = False, pixel=None, index=None) -> dict:
        """Return the per-sample outputs: ``image`` (Color3f) and the declared layers.

        ``index`` is the samples' place in the image's samples (on a model, where their frames are).
        """
        tex = self._fetch(u, v, pixel)
        M = None
        if self._frames is not None:
            uni, M = self._lane_uniforms(uni, index)
        L, E = uni["L"], self._E
        out = {}
        lit = L.z > 0.0  # the flat surface's tangent plane (module docstring)

        n = dr.normalize(mi.Vector3f(*tex["normal"])) if "normal" in tex else None
        albedo = None
        if self._diffuse or self._ambient:
            albedo = self._albedo_const if self._albedo_const is not None else mi.Color3f(*tex["albedo"])
        direct = shading.direct(
            n, L, None, albedo, E, diffuse=self._diffuse, specular=self._specular, h=uni.get("h")
        )
        direct = dr.select(lit, direct, 0.0)
        if uni.get("dark"):
            direct = mi.Color3f(0.0)
        if M is not None:
            direct = direct * M  # the base mesh's shadow, part of the technique's factor
        image = self._shadowed(direct, tex, uni, out, shadows, probe)
        if M is not None:
            for key in self._factor_layers():
                if key in out:
                    out[key] = out[key] * M
        if self._ambient:
            A = tex["ambient"][0]
            image = image + shading.sky(albedo, A, E)
            out["ambient"] = A
        self._extra_layers(tex, n, out, uni)
        out["image"] = image
        return out

    def _output_layout(self, shadows: bool) -> tuple[list[tuple[str, int]], int]:
        """Return the loop state of :meth:`render`: a flat list of Floats, ``(name, channels)`` in order."""
        before, after = self._extra_layout(shadows)
        names = [("image", 3), *before]
        if self._ambient:
            names.append(("ambient", 1))
        names += after
        return names, sum(n for _, n in names)


def _flatten(out: dict, names) -> list:
    flat = []
    for name, n in names:
        if n == 3:
            flat.extend(out[name][i] for i in range(3))
        else:
            flat.append(out[name])
    return flat


def _unflatten(flat: list, names) -> dict:
    out, i = {}, 0
    for name, n in names:
        out[name] = mi.Color3f(*flat[i : i + 3]) if n == 3 else flat[i]
        i += n
    return out


# --------------------------------------------------------------------------
# The unshadowed shading that per-pixel techniques build on
# --------------------------------------------------------------------------


class Unshadowed:
    """The flat surface's shading without any technique's shadow, split as a factor needs it.

    Techniques whose shadow factor ``F`` is computed per pixel (terrain,
    pom) shade with :func:`hzval.core.shading.compose`: ``direct * F + ambient``.
    ``render`` gives the frame of plain normal mapping (the report's
    "normal mapping only" column), its ``direct`` part and the ``ambient``
    image, which is the same for every light (the sky is not shadowed by
    the light's horizon), rendered once: an ambient-only render with the
    light below the horizon, where the direct term is 0. The last
    frame is kept: every technique of a sweep frame shares one render.
    """

    def __init__(
        self,
        scene: Scene,
        bake,
        albedo: np.ndarray | None = None,
        *,
        ambient: str = "mean_cos2",
        samples: lookup.Samples | None = None,
    ):
        effects = tuple(e for e in scene.effects if e not in ("shadow", "reflection_occlusion"))
        self.scene = scene
        # shadows alone: the direct term is E, grey (on a model, where each sample's plane faces the light)
        self._grey = not effects and (samples is None or samples.frames is None)
        self._plain = (
            None
            if self._grey
            else FlatShading(replace_effects(scene, effects), bake, albedo, ambient=ambient, samples=samples)
        )
        self.ambient_image = None
        if "ambient" in effects:
            self.ambient_image = (
                FlatShading(
                    replace_effects(scene, ("ambient",)), bake, albedo, ambient=ambient, samples=samples
                )
                .render(0.0, elevation_deg=-90.0, dark=True)
                .image
            )
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
                frame = Frame(
                    float(azimuth_deg),
                    e,
                    np.full((*self.shape, 3), E, np.float32),
                    seconds=time.perf_counter() - t0,
                )
            else:
                frame = self._plain.render(azimuth_deg, shadows=False, elevation_deg=e)
            direct = frame.image if self.ambient_image is None else frame.image - self.ambient_image
            self._last = (key, frame, direct)
        return self._last[1], self._last[2]

    def shade(
        self,
        azimuth_deg: float,
        elevation_deg: float | None,
        factor: np.ndarray,
        seconds: float,
        layers: dict | None = None,
    ) -> Frame:
        """Return the frame of a technique whose per-pixel factor is ``factor``, found in ``seconds``.

        The unshadowed render's time counts toward it, as an engine would pay it.
        """
        frame, direct = self.render(azimuth_deg, elevation_deg)
        image = shading.compose(direct, factor, self.ambient_image)
        out = {k: v for k, v in frame.layers.items() if k != "reflection_occlusion"}
        out.update(layers or {}, factor=np.asarray(factor, np.float32))
        return Frame(frame.azimuth_deg, frame.elevation_deg, image, out, seconds=seconds + frame.seconds)


def unshadowed(ctx: Context) -> Unshadowed:
    """Return the unshadowed shading of a context, built once and shared by its techniques.

    Parameters
    ----------
    ctx : Context

    Returns
    -------
    Unshadowed
    """
    return ctx.shared(
        "unshadowed", lambda: Unshadowed(ctx.scene, ctx.bake, ctx.albedo, samples=ctx.samples())
    )


class HeightFieldShadow(Technique):
    """Base of the techniques that multiply the :class:`Unshadowed` shading by a per-pixel factor.

    These techniques (terrain, pom) read the height map and are built as ``cls(scene, height, bake=...,
    albedo=..., unshadowed=..., **settings)``. Their bake needs are the normal map (and the ambient map where
    the scene declares ``ambient``).
    """

    @classmethod
    @override
    def bake_needs(cls, scene: Scene) -> frozenset[str]:
        return frozenset({"normal", "height"} | ({"ambient"} if scene.declares("ambient") else set()))

    @classmethod
    @override
    def build(cls, ctx: Context, **settings) -> "HeightFieldShadow":
        return cls(
            ctx.scene,
            ctx.height,
            bake=ctx.bake,
            albedo=ctx.albedo,
            unshadowed=unshadowed(ctx),
            samples=ctx.samples(),
            **settings,
        )

    @staticmethod
    def shading_for(
        scene: Scene,
        height: np.ndarray,
        bake,
        albedo,
        shared: Unshadowed | None,
        samples: lookup.Samples | None = None,
    ) -> Unshadowed:
        """Return ``shared``, or the unshadowed shading of a technique built on its own.

        That shading comes from ``bake``, or without one from the normal map alone
        (:func:`hzval.bake.maps.normals_only`), which serves ``diffuse`` and ``specular``; ``ambient`` needs
        the bake's ambient map.
        """
        if shared is not None:
            return shared
        if bake is None:
            if scene.declares("ambient"):
                raise InputError("bake", "ambient needs the bake's textures")
            bake = normals_only(height, scene.material.depth, scene.material.boundary)
        return Unshadowed(scene, bake, albedo, samples=samples)
