"""The shipped GLSL shaders on a real OpenGL pipeline: the ``horizon-gl`` and ``pom-gl`` techniques.

``horizon-gl`` runs ``hzval/techniques/gl/shaders/horizon_shadow.glsl`` (Lengyel's
Listing 5.1, corrected) through OpenGL (:mod:`hzval.techniques.gl.context`: moderngl on a
headless EGL context; Mesa's llvmpipe on a CPU). Its textures are real
texture units, as an engine would set them up:

``horizonMap``
    a 2-D array texture of two RGBA layers (channels 0-3, 4-7): RGBA8 for
    ``u8`` storage; for ``bc7`` BPTC, the encoder's blocks (``etcpak``) uploaded
    with ``glCompressedTexImage3D`` and decoded by the driver; for the other
    block formats (whose channels are not packed as two RGBA layers) the
    blocks as ``texture2ddecoder`` decodes them, in RGBA8 (a GPU decodes
    before it filters, so the filtered values are the same); RGBA32F for ``float``. Wrap mode from
    the boundary (``REPEAT``, ``CLAMP_TO_EDGE``); the filter the scene's
    lookup names (``nearest``, ``bilinear``, ``trilinear``; ``anisotropic``
    adds ``GL_TEXTURE_MAX_ANISOTROPY``). Mips are uploaded level by level
    from :func:`hzval.scene.lookup.mip_chain`, each quantised to the storage as the
    ``--path gpu`` emulation quantises them (``quantise`` of :func:`hzval.scene.lookup.mip_chain`),
    so that the two read the same texels and differ only in filtering.
``factorCube``
    the 16 x 16 RGBA8 weight cube map of :func:`hzval.bake.maps.weight_cube`,
    GL face order, filtered bilinearly and seamlessly across faces
    (``GL_TEXTURE_CUBE_MAP_SEAMLESS``).

Each frame computes ``F`` at every sample of the sweep
(:class:`hzval.techniques.gl.context.SamplePass`, with the pixel's footprint as
``textureGrad``'s derivatives) and shades like the per-pixel techniques:
:class:`hzval.techniques.surface.Unshadowed` times the pixel mean of ``F``, so the
image differs from ``horizon``'s only in ``F`` (no reflection fade).

``pom-gl`` runs ``hzval/techniques/gl/shaders/pom_shadow.glsl``, the ``pom`` technique's
march (:mod:`hzval.techniques.pom`), with the heights in an R32F texture.

Neither is on by default: name them in ``--techniques``. Where no GL
context can be made they raise :class:`hzval.techniques.registry.Unavailable` and the
sweep skips them with one line saying what to install.
"""

from __future__ import annotations

import ctypes
import math
import time

import numpy as np
from typing_extensions import override

from hzval.bake.maps import CUBE_SIZE, weight_cube
from hzval.core import conventions as cv
from hzval.core.errors import InputError
from hzval.io import storage as hz_storage
from hzval.io.codecs import unit_to_u8
from hzval.scene import lookup
from hzval.scene.spec import Frame, Scene, image_shape
from hzval.techniques import horizon, pom, surface
from hzval.techniques.gl import context as gl
from hzval.techniques.registry import Unavailable, Variant

__all__ = ["HorizonGL", "PomGL"]

_GL_NEAREST, _GL_LINEAR = 0x2600, 0x2601
_GL_LINEAR_MIPMAP_LINEAR = 0x2703
_GL_TEXTURE_2D_ARRAY = 0x8C1A
_GL_RGBA, _GL_UNSIGNED_BYTE, _GL_FLOAT = 0x1908, 0x1401, 0x1406
_GL_COMPRESSED_RGBA_BPTC_UNORM = 0x8E8C


class _GLTechnique(surface.HeightFieldShadow):
    """What the GL techniques share: opt-in, the GL record, the skip when there is no context."""

    by_default = False
    not_on_models = "the OpenGL pipeline draws the tile alone (no mesh's tangent frames yet)"
    not_modelled = ("interreflection", "reflection_occlusion")

    @classmethod
    def build(cls, ctx, **settings):
        try:
            gl.context()
        except gl.Unavailable as e:
            raise Unavailable(f"{cls.name}: skipped: {e}") from None
        return super().build(ctx, **settings)

    @classmethod
    def check_variants(cls) -> list[Variant]:
        return []  # ``hzval check`` guards the Dr.Jit techniques; these need a GL driver

    @classmethod
    def tradeoff_variants(cls) -> list[Variant]:
        return []

    def render(self, azimuth_deg: float, *, elevation_deg: float | None = None) -> Frame:
        """Return the unshadowed shading times the pixel mean of the shader's ``F``.

        ``seconds`` is the wall time.
        """
        t0 = time.perf_counter()
        e = self.scene.light.elevation_deg if elevation_deg is None else float(elevation_deg)
        F = self.factor(azimuth_deg, e)
        return self._unshadowed.shade(azimuth_deg, e, F, time.perf_counter() - t0)


class HorizonGL(_GLTechnique):
    """Listing 5.1 on OpenGL (module docstring).

    ``k``: the shadow hardness; ``storage``: the horizon map's (:data:`hzval.io.storage.STORAGES`, not the
    ``-sqrt`` ones: the shader samples sines).
    """

    name = "horizon-gl"
    label = "horizon map on OpenGL"
    summary = (
        "Lengyel's Listing 5.1 in GLSL (hzval/techniques/gl/shaders/horizon_shadow.glsl) "
        "on a real OpenGL pipeline"
    )
    file_stem = "horizon_gl"
    flags = {"k": "--horizon-k", "storage": "--horizon-storage"}

    @classmethod
    def bake_needs(cls, scene: Scene) -> frozenset[str]:
        """Return the horizon map and what the unshadowed shading reads.

        For the shading, see :class:`hzval.techniques.surface.HeightFieldShadow`.
        """
        return super().bake_needs(scene) | {"horizon_map"}

    def __init__(
        self,
        scene: Scene,
        height: np.ndarray,
        *,
        bake=None,
        albedo=None,
        unshadowed=None,
        samples=None,
        k: float = horizon.DEFAULT_K,
        storage: str = "u8",
    ):
        _validate(bake, k, storage)
        self.scene, self.bake, self.k, self.storage = scene, bake, float(k), storage
        self.rows, self.cols = bake.horizon.shape[:2]
        self.shape = image_shape(self.rows, self.cols, scene.camera)
        self.simulated = self.simulates(scene)
        samples = samples if samples is not None else lookup.samples_for(scene, self.rows, self.cols, height)
        self._unshadowed = self.shading_for(scene, height, bake, albedo, unshadowed, samples)
        self.gl = gl.info()
        self._pass = gl.SamplePass("horizon_shadow.glsl", "HORIZON", samples, self.shape)
        self._horizon = _horizon_texture(gl.context(), bake.horizon, storage, scene)
        self._cube = _cube_texture(gl.context())

    @classmethod
    @override
    def settings_from_args(cls, args) -> dict:
        return {"k": args.horizon_k, "storage": args.horizon_storage or "u8"}

    @classmethod
    @override
    def check_settings(cls, bake_params, settings: dict) -> None:
        if bake_params.directions != cv.CHANNEL_COUNT:
            raise InputError(
                "--techniques",
                f"horizon-gl runs Listing 5.1's {cv.CHANNEL_COUNT}-channel map; "
                f"this bake stores {bake_params.directions} directions",
            )
        storage = settings.get("storage", "u8")
        if storage.endswith("-sqrt"):
            raise InputError("storage", f"horizon-gl samples sines; {storage} stores square roots")

    @property
    @override
    def parameters(self) -> dict:
        return {
            "technique": "Listing 5.1 in GLSL on OpenGL",
            "shader": "hzval/techniques/gl/shaders/horizon_shadow.glsl",
            "k": self.k,
            "storage": self.storage,
            "cube_size": CUBE_SIZE,
            "cube_filter": "seamless bilinear",
            "gl": self.gl,
            "simulated": list(self.simulated),
        }

    @override
    def storage_bytes(self) -> int:
        rows, cols, ch = self.bake.horizon.shape
        return hz_storage.get(self.storage).bytes(rows, cols, ch) + horizon.CUBE_BYTES

    def factor(self, azimuth_deg: float, elevation_deg: float) -> np.ndarray:
        """Pixel means of the shader's ``F``, float32 ``shape``."""
        L = cv.light_direction(azimuth_deg, elevation_deg).astype(np.float32)
        self._pass.set(L=tuple(float(c) for c in L), hardness=self.k)
        return self._pass.run({"horizonMap": self._horizon, "factorCube": self._cube})


class PomGL(_GLTechnique):
    """The ``pom`` march in GLSL on OpenGL.

    The shader is ``hzval/techniques/gl/shaders/pom_shadow.glsl``; settings as
    :class:`hzval.techniques.pom.RayMarchShadow`'s.
    """

    name = "pom-gl"
    label = "ray-marched shadows on OpenGL"
    summary = (
        "the pom ray march in GLSL (hzval/techniques/gl/shaders/pom_shadow.glsl) on a real OpenGL pipeline"
    )
    file_stem = "pom_gl"

    def __init__(
        self,
        scene: Scene,
        height: np.ndarray,
        *,
        steps: int = pom.DEFAULT_STEPS,
        variant=None,
        softness=None,
        bake=None,
        albedo=None,
        unshadowed=None,
        samples=None,
    ):
        h, samples = pom.set_up_march(
            self, scene, height, steps, variant, softness, bake, albedo, unshadowed, samples
        )
        self.gl = gl.info()
        self._pass = gl.SamplePass("pom_shadow.glsl", "POM", samples, self.shape)
        ctx = gl.context()
        self._height = ctx.texture(
            (self.cols, self.rows), 1, np.ascontiguousarray(h, np.float32).tobytes(), dtype="f4"
        )
        self._height.filter = (_GL_LINEAR, _GL_LINEAR)
        wrap = scene.material.boundary == "wrap"
        self._height.repeat_x = self._height.repeat_y = wrap

    settings_from_args = pom.RayMarchShadow.settings_from_args
    check_settings = pom.RayMarchShadow.check_settings

    @property
    @override
    def parameters(self) -> dict:
        out = {
            "technique": "the pom ray march in GLSL on OpenGL",
            "shader": "hzval/techniques/gl/shaders/pom_shadow.glsl",
            "steps": self.steps,
            "variant": self.variant,
            "gl": self.gl,
            "simulated": list(self.simulated),
        }
        if self.variant == "soft":
            out["softness"] = self.softness
        return out

    @override
    def storage_bytes(self) -> int:
        return self.rows * self.cols * 2

    def factor(self, azimuth_deg: float, elevation_deg: float) -> np.ndarray:
        """Return the pixel means of the shader's ``F``.

        Lights at or above the zenith light everything, at or below the horizon nothing, as
        :mod:`hzval.techniques.pom`.
        """
        if elevation_deg >= 90.0:
            return np.ones(self.shape, np.float32)
        if elevation_deg <= 0.0:
            return np.zeros(self.shape, np.float32)
        phi, e = math.radians(azimuth_deg), math.radians(elevation_deg)
        self._pass.set(
            uvStep=(math.cos(phi) / self.cols, -math.sin(phi) / self.rows),
            tanE=math.tan(e),
            hMax=self.h_max,
            steps=self.steps,
            eps=pom.EPSILON_PER_HEIGHT * max(1.0, abs(self.h_max)),
            softness=self.softness if self.variant == "soft" else 0.0,
            openTile=self.scene.material.boundary == "open",
        )
        return self._pass.run({"heightMap": self._height})


def _validate(bake, k: float, storage: str) -> None:
    if bake is None or bake.horizon is None:
        raise InputError("bake", "horizon-gl needs the bake's horizon map")
    if bake.horizon.shape[-1] != cv.CHANNEL_COUNT:
        raise InputError(
            "bake",
            f"horizon-gl runs Listing 5.1's {cv.CHANNEL_COUNT}-channel map; this bake "
            f"stores {bake.horizon.shape[-1]} directions",
        )
    hz_storage.get(storage)
    if storage.endswith("-sqrt"):
        raise InputError("storage", f"horizon-gl samples sines; {storage} stores square roots")
    if not (math.isfinite(k) and k > 0):
        raise InputError("k", f"the shadow hardness must be a positive number, got {k}")


def _layers(level: np.ndarray, u8: bool) -> bytes:
    """Return a level ``(rows, cols, 8)`` as the array texture's two RGBA layers, layer-major."""
    n = cv.CHANNELS_PER_LAYER
    layers = np.stack([level[..., :n], level[..., n : 2 * n]])
    return np.ascontiguousarray(unit_to_u8(layers) if u8 else layers.astype(np.float32)).tobytes()


def _horizon_texture(ctx, horizon: np.ndarray, storage: str, scene: Scene):
    """Return the horizon map's 2-D array texture with its levels (module docstring)."""
    lk = scene.lookup
    chain, blocks = _stored_chain(horizon, storage, lk)
    u8 = storage != "float"
    rows, cols = chain[0].shape[:2]
    tex = ctx.texture_array((cols, rows, 2), 4, _layers(chain[0], u8), dtype="f1" if u8 else "f4")
    if blocks:  # BPTC: the encoder's blocks, as an engine ships them
        for level, (data, layer_blocks) in enumerate(zip(chain, blocks)):
            _compressed_image_3d(tex.glo, level, data.shape[1], data.shape[0], b"".join(layer_blocks))
    elif len(chain) > 1:
        tex.build_mipmaps(0, len(chain) - 1)  # allocates the levels; overwritten below
        for level, data in enumerate(chain[1:], start=1):
            _sub_image_3d(tex.glo, level, data.shape[1], data.shape[0], _layers(data, u8), u8)
    _gl_function("glTexParameteri", ctypes.c_uint, ctypes.c_uint, ctypes.c_int)(
        _GL_TEXTURE_2D_ARRAY, 0x813D, len(chain) - 1
    )  # GL_TEXTURE_MAX_LEVEL
    if lk.filter == "nearest":
        tex.filter = (_GL_NEAREST, _GL_NEAREST)
    elif lk.mipmapped:
        tex.filter = (_GL_LINEAR_MIPMAP_LINEAR, _GL_LINEAR)
    else:
        tex.filter = (_GL_LINEAR, _GL_LINEAR)
    if lk.filter == "anisotropic":
        tex.anisotropy = float(lk.max_anisotropy)
    tex.repeat_x = tex.repeat_y = scene.material.boundary == "wrap"
    return tex


def _stored_chain(horizon: np.ndarray, storage: str, lk) -> tuple[list[np.ndarray], list[list[bytes]]]:
    """Return what the GPU samples at each mip level and, for ``bc7``, the encoded blocks.

    The result is ``(levels, blocks)``: level 0 alone without a mip filter, each level made from the stored
    one below and stored again (:func:`hzval.scene.lookup.mip_chain`'s ``quantise``, as ``--path gpu`` makes
    them); for ``bc7`` each level's encoded blocks per layer.
    """
    st = hz_storage.get(storage)
    keep = storage == "bc7"
    blocks: list[list[bytes]] = []

    def stored_level(level: np.ndarray) -> np.ndarray:
        out: list = []
        q = st.roundtrip(level, out)
        if keep:
            blocks.append(out)
        return q

    quantise = None if storage == "float" else stored_level
    stored = horizon if quantise is None else quantise(horizon)
    if not lk.mipmapped:
        return [stored], blocks
    everything = slice(None)
    chain = lookup.mip_chain(
        stored, everything if lk.mips == "max" else None, stored=everything, quantise=quantise
    )
    return chain, blocks


def _cube_texture(ctx):
    """Return the 16 x 16 RGBA8 weight cube map, faces +x, -x, +y, -y, +z, -z; bilinear, level 0 only."""
    faces = weight_cube(CUBE_SIZE)
    tex = ctx.texture_cube(
        (CUBE_SIZE, CUBE_SIZE), 4, b"".join(np.ascontiguousarray(f).tobytes() for f in faces)
    )
    tex.filter = (_GL_LINEAR, _GL_LINEAR)
    return tex


_gl_functions: dict = {}


def _gl_function(name: str, *argtypes):
    """Return a GL entry point through EGL (moderngl has no per-level upload for array textures)."""
    if name not in _gl_functions:
        egl = ctypes.CDLL("libEGL.so.1")
        egl.eglGetProcAddress.restype = ctypes.c_void_p
        egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]
        address = egl.eglGetProcAddress(name.encode())
        if not address:
            raise gl.Unavailable(f"the GL driver has no {name}")
        _gl_functions[name] = ctypes.CFUNCTYPE(None, *argtypes)(address)
    return _gl_functions[name]


def _compressed_image_3d(glo: int, level: int, width: int, height: int, data: bytes) -> None:
    """``glCompressedTexImage3D`` of both layers of mip ``level`` as BPTC (BC7) blocks."""
    u, i = ctypes.c_uint, ctypes.c_int
    _gl_function("glBindTexture", u, u)(_GL_TEXTURE_2D_ARRAY, glo)
    buf = ctypes.create_string_buffer(data, len(data))
    _gl_function("glCompressedTexImage3D", u, i, u, i, i, i, i, i, ctypes.c_void_p)(
        _GL_TEXTURE_2D_ARRAY,
        level,
        _GL_COMPRESSED_RGBA_BPTC_UNORM,
        width,
        height,
        2,
        0,
        len(data),
        ctypes.cast(buf, ctypes.c_void_p),
    )


def _sub_image_3d(glo: int, level: int, width: int, height: int, data: bytes, u8: bool) -> None:
    """``glTexSubImage3D`` of both layers of mip ``level`` of the array texture ``glo``."""
    u = ctypes.c_uint
    i = ctypes.c_int
    _gl_function("glBindTexture", u, u)(_GL_TEXTURE_2D_ARRAY, glo)
    _gl_function("glPixelStorei", u, i)(0x0CF5, 1)  # GL_UNPACK_ALIGNMENT
    buf = ctypes.create_string_buffer(data, len(data))
    _gl_function("glTexSubImage3D", u, i, i, i, i, i, i, i, u, u, ctypes.c_void_p)(
        _GL_TEXTURE_2D_ARRAY,
        level,
        0,
        0,
        0,
        width,
        height,
        2,
        _GL_RGBA,
        _GL_UNSIGNED_BYTE if u8 else _GL_FLOAT,
        ctypes.cast(buf, ctypes.c_void_p),
    )
