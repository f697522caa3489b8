"""The base of the techniques whose shadow factor is a formula of the sample's own textures and light.

Engines ship these where hzval's other techniques march or sweep: AO micro-shadowing
(:mod:`hzval.techniques.microshadow_filament`, :mod:`hzval.techniques.microshadow_hdrp`), bent cones
(:mod:`hzval.techniques.bent_cone`), Valve's self-shadowed bump maps (:mod:`hzval.techniques.ssbump`)
and the bump-terminator term of offline renderers (:mod:`hzval.techniques.terminator`). The factors
of all of a context's per-pixel techniques are computed in one pass of the flat surface's kernel
(:class:`FactorKernel`, a :class:`hzval.techniques.surface.FlatShading`): their textures packed once
and filtered as the scene's lookup says, each ``F`` per sample and its pixel mean a layer. Each
technique's image is the unshadowed shading's direct term times that mean plus its ambient term
(:meth:`hzval.techniques.surface.Unshadowed.shade`), as terrain's and pom's are. ``F`` reads ``L`` in
the sample's own tangent frame, so each renders on models too.

A subclass sets the :class:`hzval.techniques.registry.Technique` attributes, :attr:`textures` (the
texture planes it reads and how each is stored) and :meth:`PerPixelFactor.factor`. Every texture is
stored as baked (``float``, the default: a sweep's factor images are then each formula on the written
bake) or as engines store it, chosen with a ``--<texture>-storage`` flag (:attr:`Texture.storages`):
``u8`` (8 bits a channel, unit vectors as a normal map's) or a block format of
:mod:`hzval.io.storage` (BC4 for AO, BC5 for a bent normal's x and y with z rebuilt, BC1 or BC7 for
SSBump's three channels). The tradeoff measures each side by side.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from typing_extensions import override

from hzval.core.backend import dr, mi
from hzval.core.errors import InputError
from hzval.io import storage as hz_storage
from hzval.io.codecs import unit_to_u8
from hzval.scene import lookup
from hzval.scene.spec import EFFECTS, Frame, Scene
from hzval.techniques.registry import Context, Technique, Variant, replace_effects
from hzval.techniques.surface import NOT_MODELLED, FlatShading, Unshadowed, unshadowed

__all__ = [
    "PerPixelFactor",
    "FactorKernel",
    "BaseShadow",
    "STORAGES",
    "Texture",
    "TEXTURES",
    "stored",
    "texture_bytes",
    "add_storage_flag",
    "through",
]

#: How every texture of these techniques may be stored: as baked, or 8 bits per channel; each
#: texture adds the block formats engines use for it (:attr:`Texture.storages`).
STORAGES: tuple[str, ...] = ("float", "u8")


@dataclass(frozen=True)
class Texture:
    """A texture these techniques read.

    It records the :class:`hzval.bake.maps.Bake` field that holds it, the bake content that makes it
    (:data:`hzval.bake.maps.CONTENTS`), whether it is a unit vector (stored as ``0.5 + 0.5 v``, as a normal
    map), what it is, for ``--help``, and how it may be stored.
    """

    field: str
    content: str
    signed: bool
    what: str
    default: str = "float"
    #: Its storage formats: :data:`STORAGES` and the block formats of :mod:`hzval.io.storage` engines use.
    storages: tuple[str, ...] = STORAGES


#: The textures more than one technique reads, by the name of their ``--<name>-storage`` flag; a
#: technique's own texture is its class's (:attr:`PerPixelFactor.own_textures`).
TEXTURES: dict[str, Texture] = {
    "ao": Texture(
        "mean_cos2",
        "ambient",
        False,
        "the ambient-occlusion map (ambient.exr's mean_cos2)",
        storages=(*STORAGES, "bc4"),
    ),
    "bent-normal": Texture(
        "bent_normal",
        "bent_normal",
        True,
        "the bent-normal map (bent_normal.exr)",
        storages=(*STORAGES, "bc5"),
    ),
}

#: The slot of the normal map's normal when the shading itself reads no normal (``shadow`` alone).
NORMAL_SLOT = "factor_normal"


def stored(values: np.ndarray, storage: str, *, signed: bool = False) -> np.ndarray:
    """Return what the shader samples of a texture stored as ``storage``.

    Parameters
    ----------
    values : numpy.ndarray
        The baked texture ``(rows, cols[, C])``: values in [0, 1], or unit vectors (``signed``).
    storage : str
        ``"float"`` (as baked), ``"u8"`` (rounded to the nearest of 256 levels, as an upload does;
        unit vectors as ``0.5 + 0.5 v``, decoded and renormalised, as a normal map's are) or a block
        format of :mod:`hzval.io.storage` (encoded and decoded; unit vectors keep ``x`` and ``y`` alone,
        BC5's layout, and the shader rebuilds ``z = sqrt(1 - x^2 - y^2)``).
    signed : bool
        Whether ``values`` are unit vectors (the last axis).

    Returns
    -------
    numpy.ndarray
        float32, the shape of ``values``.

    Examples
    --------
    >>> import numpy as np
    >>> int(round(float(stored(np.array([0.5]), "u8")[0]) * 255))
    128
    """
    v = np.asarray(values, np.float32)
    if storage == "float":
        return v
    if storage != "u8":
        return _block_stored(v, hz_storage.get(storage), signed)
    q = unit_to_u8(0.5 + 0.5 * v if signed else v).astype(np.float32) / np.float32(255.0)
    if not signed:
        return q
    return _unit(2.0 * q - 1.0)


def _unit(v: np.ndarray) -> np.ndarray:
    return (v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)).astype(np.float32)


def _block_stored(v: np.ndarray, fmt, signed: bool) -> np.ndarray:
    """Return :func:`stored` of a block format.

    Channels are packed as :meth:`hzval.io.storage.Storage.roundtrip` packs them; a unit vector's ``x, y`` as
    ``0.5 + 0.5 v`` and ``z`` rebuilt (BC5 normal maps).
    """
    if not signed:
        flat = v[..., None] if v.ndim == 2 else v
        return fmt.roundtrip(np.clip(flat, 0.0, 1.0)).reshape(v.shape)
    xy = 2.0 * fmt.roundtrip(np.clip(0.5 + 0.5 * v[..., :2], 0.0, 1.0)) - 1.0
    z = np.sqrt(np.maximum(1.0 - np.sum(xy * xy, axis=-1), 0.0))
    return _unit(np.concatenate([xy, z[..., None]], axis=-1))


def texture_bytes(texture: Texture, storage: str, rows: int, cols: int, channels: int) -> int:
    """Return what the GPU holds of a texture's top level stored as ``storage``, bytes.

    Parameters
    ----------
    texture : Texture
        The texture (a unit vector's ``z`` is rebuilt by the shader in a block format).
    storage : str
        One of ``texture.storages``.
    rows, cols, channels : int
        Its size.

    Returns
    -------
    int
        4 bytes a channel as float, 1 as u8; a block format's blocks
        (:meth:`hzval.io.storage.Storage.bytes`).

    Examples
    --------
    >>> texture_bytes(TEXTURES["ao"], "bc4", 64, 64, 1) / (64 * 64)
    0.5
    >>> texture_bytes(TEXTURES["bent-normal"], "bc5", 64, 64, 3) / (64 * 64)
    1.0
    """
    if storage in STORAGES:
        return int(rows * cols * channels * (4 if storage == "float" else 1))
    return hz_storage.get(storage).bytes(rows, cols, 2 if texture.signed else channels)


def through(value, surrogate, on: bool = True):
    """Return ``value`` with ``surrogate``'s gradient when ``on``.

    This is a straight-through estimator (Bengio et al. 2013): a fit's way past a factor's clamps and steps,
    whose own gradient is 0 where a texel is wrong. Off (a render), it is ``value`` itself.
    """
    return surrogate + dr.detach(value - surrogate) if on else value


def add_storage_flag(parser, name: str, texture: Texture) -> None:
    """Add ``--<name>-storage`` to ``parser`` once (techniques that read one texture share its flag)."""
    try:
        parser.add_argument(
            f"--{name}-storage",
            choices=texture.storages,
            default=texture.default,
            help=f"how {texture.what} is stored: float as baked, or as engines store it "
            f"(default {texture.default})",
        )
    except argparse.ArgumentError:
        pass  # another technique that reads it added it


def _checked_storage(cls, storage: dict | None) -> dict:
    """``{texture: storage}`` as given, each one of its texture's storages, else one line naming its flag."""
    for t, value in (storage or {}).items():
        choices = cls.texture(t).storages
        if value not in choices:
            raise InputError(f"{t}-storage", f"must be one of {', '.join(choices)}, got {value!r}")
    return dict(storage or {})


class FactorKernel(FlatShading):
    """One kernel for the factors of every per-pixel technique of a context.

    Their textures are packed once, the normal fetched once, each technique's ``F`` a layer of the same pass
    (``factor0``, ``factor1``, ...). Techniques join it (:meth:`add`), its first frame builds it; a frame is
    kept until the light moves, so that the techniques of a sweep's frame share one render. The shading itself
    is not computed here: each technique composes its image from the shared unshadowed shading
    (:class:`hzval.techniques.surface.Unshadowed`), as terrain and pom do.
    """

    def __init__(self, scene: Scene, bake, samples: lookup.Samples | None = None):
        self._args = (replace_effects(scene, ("shadow",)), bake)
        self._samples = samples
        self.members: list = []
        self._built = False
        self._last: tuple | None = None

    def add(self, member) -> str:
        """Join ``member`` (a :class:`PerPixelFactor`); the name of its factor layer.

        One that joins after a frame makes the next frame build the kernel again, with every member.
        """
        self._built, self._last = False, None
        self.members.append(member)
        return f"factor{len(self.members) - 1}"

    def frame(self, azimuth_deg: float, elevation_deg: float | None) -> Frame:
        """Return the members' factors for one light (built at the first call; the last one kept)."""
        key = (float(azimuth_deg), elevation_deg)
        if self._last is None or self._last[0] != key:
            self.prepare()
            self._last = (key, self.render(azimuth_deg, elevation_deg=elevation_deg))
        return self._last[1]

    def sample_factors(self, x, y, azimuth_deg: float, elevation_deg: float | None) -> dict:
        """Per-point factors (:meth:`hzval.techniques.surface.FlatShading.sample`), by layer name."""
        self.prepare()
        return self.sample(x, y, azimuth_deg, elevation_deg)

    def prepare(self) -> None:
        """Build the kernel with its members now (the first frame does otherwise)."""
        if not self._built:
            self._built = True
            FlatShading.__init__(self, *self._args, samples=self._samples)

    # -- the hooks of the flat shading ----------------------------------------------------------

    def slot(self, member, texture: str) -> str:
        """Return the name of ``member``'s texture in the packed texture.

        The name is shared by the members that read the same plane stored the same way.
        """
        return f"{member.plane_name(texture)}:{member.storage[texture]}"

    def _extra_planes(self) -> list[tuple[str, np.ndarray]]:
        planes: dict[str, np.ndarray] = {}
        for m in self.members:
            for t in m.textures:
                if self.slot(m, t) not in planes:
                    planes[self.slot(m, t)] = m.stored_plane(t)
        if any(m.reads_normal for m in self.members):
            planes[NORMAL_SLOT] = self.bake.normal
        return list(planes.items())

    def _upload_constants(self) -> None:
        super()._upload_constants()
        self._constants = [m.constants() for m in self.members]
        dr.eval(self._constants)

    def _factor_layers(self) -> tuple[str, ...]:
        return tuple(f"factor{i}" for i in range(len(self.members)))

    def _shadowed(self, direct, tex: dict, uni: dict, out: dict, shadows: bool, probe: bool):
        n = dr.normalize(mi.Vector3f(*tex[NORMAL_SLOT])) if NORMAL_SLOT in tex else None
        for i, m in enumerate(self.members):
            own = {t: tex[self.slot(m, t)] for t in m.textures}
            F = dr.clip(m.factor(own, n if m.reads_normal else None, uni["L"], self._constants[i]), 0.0, 1.0)
            # within float32 rounding of 1 is 1: a ratio of two sums that are equal for an open
            # texel (ssbump) must not shade a flat surface
            out[f"factor{i}"] = dr.select(F >= 1.0 - 2.0**-20, 1.0, F)
        return direct

    def _extra_layout(self, shadows: bool) -> tuple[list, list]:
        return [(name, 1) for name in self._factor_layers()], []


class PerPixelFactor(Technique):
    """A technique whose factor is a formula of the sample's textures, normal and light (module docstring).

    ``storage``: ``{texture: "float" | "u8"}`` for the textures it reads; ``kernel``: the context's
    :class:`FactorKernel` it joins (default its own); ``plain``: the unshadowed shading its image is composed
    from (default its own).
    """

    needs = ("shadow",)
    not_modelled = NOT_MODELLED
    #: The textures it reads, in the order they are packed: names of :data:`TEXTURES` or of
    #: :attr:`own_textures`.
    textures: ClassVar[tuple[str, ...]] = ()
    #: Textures no other technique reads, by name.
    own_textures: ClassVar[dict[str, Texture]] = {}
    #: Whether :meth:`factor` reads the normal map's normal.
    reads_normal: ClassVar[bool] = True
    #: Whether :meth:`factor` gives its clamps and steps a gradient (:func:`through`): a fit's
    #: forward model sets it; the values are the same.
    straight_through: bool = False

    def __init__(
        self,
        scene: Scene,
        bake,
        albedo: np.ndarray | None = None,
        *,
        storage: dict | None = None,
        samples: lookup.Samples | None = None,
        kernel: FactorKernel | None = None,
        plain=None,
        **settings,
    ):
        self.scene, self.bake = scene, bake
        self.storage = {t: self.texture(t).default for t in self.textures} | _checked_storage(
            type(self), storage
        )
        self.settings = self.validate(settings)
        self.simulated = tuple(e for e in EFFECTS if scene.declares(e) and e not in self.not_modelled)
        self.kernel = kernel if kernel is not None else FactorKernel(scene, bake, samples)
        self._layer = self.kernel.add(self)
        self._plain = plain if plain is not None else Unshadowed(scene, bake, albedo, samples=samples)
        self.shape = self._plain.shape

    @classmethod
    def texture(cls, name: str) -> Texture:
        """Return the texture of that name it reads."""
        return cls.own_textures.get(name) or TEXTURES[name]

    def plane(self, name: str) -> np.ndarray:
        """Return the values of texture ``name`` before storage.

        They are the bake's field (a variant may derive its own, :meth:`plane_name` naming them).
        """
        return getattr(self.bake, self.texture(name).field)

    def plane_name(self, name: str) -> str:
        """Return what :meth:`plane` holds for texture ``name``.

        It is the same name, with the same values (techniques that read them share the kernel's one copy).
        """
        return self.texture(name).field

    def stored_plane(self, name: str) -> np.ndarray:
        """Return what the shader samples of texture ``name``.

        That is :meth:`plane` as its storage keeps it (:func:`stored`).
        """
        return stored(self.plane(name), self.storage[name], signed=self.texture(name).signed)

    # -- what a subclass gives ------------------------------------------------------------------

    @classmethod
    def validate(cls, settings: dict) -> dict:
        """Return the technique's own settings, checked.

        A bad setting raises :class:`hzval.core.errors.InputError` naming it. By default a technique has
        no settings of its own.
        """
        if settings:
            raise TypeError(f"unexpected settings {', '.join(settings)}")
        return {}

    @staticmethod
    def choice(settings: dict, key: str, choices: tuple[str, ...]) -> str:
        """Return ``settings[key]``, popped, one of ``choices`` (the first when unset).

        Anything else is refused in one line naming the setting.
        """
        value = settings.pop(key, None) or choices[0]
        if value not in choices:
            raise InputError(key, f"must be one of {', '.join(choices)}, got {value!r}")
        return value

    def constants(self) -> dict:
        """Per-object constants the factor reads, as opaque Dr.Jit values (uploaded once)."""
        return {}

    def factor(self, tex: dict, n, L, c: dict):
        """Return the shadow factor ``F`` of a sample.

        ``tex`` is its filtered textures by name, ``n`` the normal map's unit normal (``None`` when
        :attr:`reads_normal` is false), ``L`` the unit light in its tangent frame, ``c`` :meth:`constants`.
        """
        raise NotImplementedError

    # -- the Technique interface ----------------------------------------------------------------

    @classmethod
    @override
    def bake_needs(cls, scene: Scene) -> frozenset[str]:
        own = {cls.texture(t).content for t in cls.textures}
        return frozenset({"normal"} | own | ({"ambient"} if scene.declares("ambient") else set()))

    @classmethod
    def build(cls, ctx: Context, **settings) -> "PerPixelFactor":
        """Build the technique from a context.

        It uses the context's one factor kernel and unshadowed shading, shared with its other per-pixel
        techniques.
        """
        kernel = ctx.shared("perpixel factors", lambda: FactorKernel(ctx.scene, ctx.bake, ctx.samples()))
        return cls(ctx.scene, ctx.bake, ctx.albedo, kernel=kernel, plain=unshadowed(ctx), **settings)

    @classmethod
    def check_settings(cls, bake_params, settings: dict) -> None:
        """Refuse a setting before anything is written.

        The caller names its flag (:func:`hzval.techniques.registry.flag_errors`).
        """
        own = dict(settings)
        _checked_storage(cls, own.pop("storage", None))
        cls.validate(own)

    @classmethod
    @override
    def add_arguments(cls, parser) -> None:
        for t in cls.textures:
            add_storage_flag(parser, t, cls.texture(t))

    @classmethod
    @override
    def settings_from_args(cls, args) -> dict:
        if not cls.textures:
            return {}
        return {"storage": {t: getattr(args, f"{t.replace('-', '_')}_storage") for t in cls.textures}}

    @classmethod
    @override
    def tradeoff_variants(cls) -> list[Variant]:
        out = [Variant(f"{cls.label} (float textures)", {"storage": dict.fromkeys(cls.textures, "float")})]
        if cls.textures:
            out.append(
                Variant(f"{cls.label} (8-bit textures)", {"storage": dict.fromkeys(cls.textures, "u8")})
            )
            blocks = {t: [s for s in cls.texture(t).storages if s not in STORAGES] for t in cls.textures}
            for i in range(max(len(b) for b in blocks.values())):
                # the i-th block format of each texture (the last where it has fewer)
                chosen = {t: b[min(i, len(b) - 1)] for t, b in blocks.items() if b}
                label = ", ".join(f"{s.upper()} {t}" for t, s in chosen.items())
                out.append(
                    Variant(f"{cls.label} ({label})", {"storage": dict.fromkeys(cls.textures, "u8") | chosen})
                )
        return out

    def texture_bytes(self) -> dict[str, int]:
        """Each texture it reads as stored, bytes of the top level (:func:`texture_bytes`)."""
        out = {}
        for t in self.textures:
            a = self.plane(t)
            rows, cols = a.shape[:2]
            out[t] = texture_bytes(
                self.texture(t), self.storage[t], rows, cols, 1 if a.ndim == 2 else a.shape[-1]
            )
        return out

    def storage_bytes(self) -> int:
        """Return the textures it reads as stored (:meth:`texture_bytes`), in all."""
        return int(sum(self.texture_bytes().values()))

    @property
    @override
    def parameters(self) -> dict:
        out = {"simulated": list(self.simulated), **self.settings}
        if self.textures:
            texels = self.bake.normal.shape[0] * self.bake.normal.shape[1]
            out["storage"] = dict(self.storage)
            out["storage_bytes"] = self.storage_bytes()
            out["bytes_per_texel"] = {t: b / texels for t, b in self.texture_bytes().items()}
        return out

    def render(self, azimuth_deg: float, *, elevation_deg: float | None = None) -> Frame:
        """Return the frame of the light at ``azimuth_deg``.

        It is the unshadowed shading's direct term times the pixel mean of ``F`` from the shared kernel
        (:meth:`FactorKernel.frame`), plus its ambient term; the kernel's time is shared out among the
        techniques that joined it. Layers: ``factor`` and the declared effects'.
        """
        frame = self.kernel.frame(azimuth_deg, elevation_deg)
        F = frame.layers[self._layer]
        return self._plain.shade(azimuth_deg, elevation_deg, F, frame.seconds / len(self.kernel.members))

    def sample(self, x, y, azimuth_deg: float, elevation_deg: float | None = None) -> dict[str, np.ndarray]:
        """Return per-point ``F`` at tangent-space points ``(x, y)`` (texel units), no averaging.

        The result is ``{"factor": (n,)}``.
        """
        return {"factor": self.kernel.sample_factors(x, y, azimuth_deg, elevation_deg)[self._layer]}


class BaseShadow(PerPixelFactor):
    """The no-shadows baseline: no technique's shadows, ``F = 1``.

    On a model this is the base mesh's own shadow alone (the kernel multiplies every factor by it). It is the
    sweep's no-shadows baseline on a model, where a technique's factor includes that shadow too; it is not a
    registered technique.
    """

    name = "no shadows"
    label = "no shadows"
    file_stem = "no_shadows"
    reads_normal = False

    @override
    def factor(self, tex: dict, n, L, c: dict):
        return dr.full(mi.Float, 1.0, dr.width(L.z))
