"""The base of the techniques whose shadow factor is a formula of the sample's own textures and light.

Engines ship these where hzval's other techniques march or sweep: AO micro-shadowing
(:mod:`hzval.techniques.microshadow_filament`, :mod:`hzval.techniques.microshadow_hdrp`), bent cones
(:mod:`hzval.techniques.bent_cone`), Valve's self-shadowed bump maps (:mod:`hzval.techniques.ssbump`)
and the bump-terminator term of offline renderers (:mod:`hzval.techniques.terminator`). Each is shaded
in the flat surface's kernel (:class:`hzval.techniques.surface.FlatShading`): its textures are packed
beside the shading's, filtered as the scene's lookup says, and its factor ``F`` multiplies the
direct term, as the horizon map's does. ``F`` reads ``L`` in the sample's own tangent frame, so each
renders on models too.

A subclass sets the :class:`hzval.techniques.registry.Technique` attributes, :attr:`textures` (the
texture planes it reads and how each is stored) and :meth:`PerPixelFactor.factor`. Every texture is
stored as baked (``float``, the default: a sweep's factor images are then each formula on the written
bake) or as engines store it (``u8``: 8 bits per channel, unit vectors as a normal map's), chosen
with a ``--<texture>-storage`` flag (:data:`STORAGES`); the tradeoff measures both side by side.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from hzval.core.backend import dr, mi
from hzval.core.errors import InputError
from hzval.io.files import unit_to_u8
from hzval.scene import lookup
from hzval.scene.spec import Frame, Scene
from hzval.techniques.registry import Context, Technique, Variant
from hzval.techniques.surface import NOT_MODELLED, FlatShading

__all__ = ["PerPixelFactor", "STORAGES", "Texture", "TEXTURES", "stored", "add_storage_flag"]

#: How a texture of these techniques may be stored: as baked, or 8 bits per channel.
STORAGES: tuple[str, ...] = ("float", "u8")


@dataclass(frozen=True)
class Texture:
    """A texture these techniques read: the :class:`hzval.bake.maps.Bake` field that holds it, the
    bake content that makes it (:data:`hzval.bake.maps.CONTENTS`), whether it is a unit vector (stored
    in 8 bits as ``0.5 + 0.5 v``, as a normal map) and what it is, for ``--help``."""

    field: str
    content: str
    signed: bool
    what: str
    default: str = "float"


#: The textures more than one technique reads, by the name of their ``--<name>-storage`` flag; a
#: technique's own texture is its class's (:attr:`PerPixelFactor.own_textures`).
TEXTURES: dict[str, Texture] = {
    "ao": Texture("mean_cos2", "ambient", False, "the ambient-occlusion map (ambient.exr's mean_cos2)"),
    "bent-normal": Texture("bent_normal", "bent_normal", True, "the bent-normal map (bent_normal.exr)"),
}

#: The slot of the normal map's normal when the shading itself reads no normal (``shadow`` alone).
NORMAL_SLOT = "factor_normal"


def stored(values: np.ndarray, storage: str, *, signed: bool = False) -> np.ndarray:
    """What the shader samples of a texture stored as ``storage``.

    Parameters
    ----------
    values : numpy.ndarray
        The baked texture: values in [0, 1], or unit vectors (``signed``).
    storage : str
        ``"float"`` (as baked) or ``"u8"`` (rounded to the nearest of 256 levels, as an upload does;
        unit vectors as ``0.5 + 0.5 v``, decoded and renormalised, as a normal map's are).
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
    q = unit_to_u8(0.5 + 0.5 * v if signed else v).astype(np.float32) / np.float32(255.0)
    if not signed:
        return q
    q = 2.0 * q - 1.0
    return (q / np.maximum(np.linalg.norm(q, axis=-1, keepdims=True), 1e-12)).astype(np.float32)


def add_storage_flag(parser, name: str, texture: Texture) -> None:
    """Add ``--<name>-storage`` to ``parser`` once (techniques that read one texture share its flag)."""
    try:
        parser.add_argument(
            f"--{name}-storage",
            choices=STORAGES,
            default=texture.default,
            help=f"how {texture.what} is stored: float as baked, or u8 as engines store it "
            f"(default {texture.default})",
        )
    except argparse.ArgumentError:
        pass  # another technique that reads it added it


class PerPixelFactor(FlatShading, Technique):
    """A technique whose factor is a formula of the sample's textures, normal and light (module
    docstring). ``storage``: ``{texture: "float" | "u8"}`` for the textures it reads."""

    needs = ("shadow",)
    not_modelled = NOT_MODELLED
    #: The textures it reads, in the order they are packed: names of :data:`TEXTURES` or of
    #: :attr:`own_textures`.
    textures: ClassVar[tuple[str, ...]] = ()
    #: Textures no other technique reads, by name.
    own_textures: ClassVar[dict[str, Texture]] = {}
    #: Whether :meth:`factor` reads the normal map's normal.
    reads_normal: ClassVar[bool] = True

    def __init__(
        self,
        scene: Scene,
        bake,
        albedo: np.ndarray | None = None,
        *,
        storage: dict | None = None,
        samples: lookup.Samples | None = None,
        **settings,
    ):
        self.storage = {t: self.texture(t).default for t in self.textures} | dict(storage or {})
        for t, s in self.storage.items():
            if s not in STORAGES:
                raise InputError(f"{t}-storage", f"must be one of {', '.join(STORAGES)}, got {s!r}")
        self.settings = self.validate(settings)
        super().__init__(scene, bake, albedo, samples=samples)

    @classmethod
    def texture(cls, name: str) -> Texture:
        """The texture of that name it reads."""
        return cls.own_textures.get(name) or TEXTURES[name]

    # -- what a subclass gives ------------------------------------------------------------------

    @classmethod
    def validate(cls, settings: dict) -> dict:
        """The technique's own settings, checked (raise :class:`hzval.core.errors.InputError` naming
        the setting); none by default."""
        if settings:
            raise TypeError(f"unexpected settings {', '.join(settings)}")
        return {}

    def constants(self) -> dict:
        """Per-object constants the factor reads, as opaque Dr.Jit values (uploaded once)."""
        return {}

    def factor(self, tex: dict, n, L, c: dict):
        """The shadow factor ``F`` of a sample: ``tex`` its filtered textures by name, ``n`` the normal
        map's unit normal (``None`` when :attr:`reads_normal` is false), ``L`` the unit light in its
        tangent frame, ``c`` :meth:`constants`."""
        raise NotImplementedError

    # -- the hooks of the flat shading ----------------------------------------------------------

    def _extra_planes(self) -> list[tuple[str, np.ndarray]]:
        if not self._shadow:
            return []
        planes = []
        for t in self.textures:
            tx = self.texture(t)
            planes.append((t, stored(getattr(self.bake, tx.field), self.storage[t], signed=tx.signed)))
        if self.reads_normal and not (self._diffuse or self._specular or self._reflection):
            planes.append((NORMAL_SLOT, self.bake.normal))
        return planes

    def _upload_constants(self) -> None:
        super()._upload_constants()
        self._constants = self.constants()
        dr.eval(self._constants)

    def _shadowed(self, direct, tex: dict, uni: dict, out: dict, shadows: bool, probe: bool):
        if not (self._shadow and shadows):
            return direct
        n = None
        if self.reads_normal:
            raw = tex["normal"] if "normal" in tex else tex[NORMAL_SLOT]
            n = dr.normalize(mi.Vector3f(*raw))
        F = dr.clip(self.factor(tex, n, uni["L"], self._constants), 0.0, 1.0)
        # within float32 rounding of 1 is 1: a ratio of two sums that are equal for an open texel
        # (ssbump) must not shade a flat surface
        F = dr.select(F >= 1.0 - 2.0**-20, 1.0, F)
        out["factor"] = F
        return direct * F

    def _extra_layout(self, shadows: bool) -> tuple[list, list]:
        return ([("factor", 1)] if self._shadow and shadows else []), []

    # -- the Technique interface ----------------------------------------------------------------

    @classmethod
    def bake_needs(cls, scene: Scene) -> frozenset[str]:
        own = {cls.texture(t).content for t in cls.textures}
        return frozenset({"normal"} | own | ({"ambient"} if scene.declares("ambient") else set()))

    @classmethod
    def build(cls, ctx: Context, **settings) -> "PerPixelFactor":
        return cls(ctx.scene, ctx.bake, ctx.albedo, samples=ctx.samples(), **settings)

    @classmethod
    def add_arguments(cls, parser) -> None:
        for t in cls.textures:
            add_storage_flag(parser, t, cls.texture(t))

    @classmethod
    def settings_from_args(cls, args) -> dict:
        if not cls.textures:
            return {}
        return {"storage": {t: getattr(args, f"{t.replace('-', '_')}_storage") for t in cls.textures}}

    @classmethod
    def tradeoff_variants(cls) -> list[Variant]:
        out = [Variant(f"{cls.label} (float textures)", {"storage": dict.fromkeys(cls.textures, "float")})]
        if cls.textures:
            out.append(
                Variant(f"{cls.label} (8-bit textures)", {"storage": dict.fromkeys(cls.textures, "u8")})
            )
        return out

    def storage_bytes(self) -> int:
        """The textures it reads as stored (4 bytes a channel as float, 1 as u8)."""
        total = 0
        for t in self.textures:
            a = getattr(self.bake, self.texture(t).field)
            total += a.size * (4 if self.storage[t] == "float" else 1)
        return int(total)

    @property
    def parameters(self) -> dict:
        out = {"simulated": list(self.simulated), **self.settings}
        if self.textures:
            out["storage"] = dict(self.storage)
            out["storage_bytes"] = self.storage_bytes()
        return out

    def render(
        self, azimuth_deg: float, *, shadows: bool = True, elevation_deg: float | None = None
    ) -> Frame:
        """The frame of the light at ``azimuth_deg`` (:meth:`hzval.techniques.surface.FlatShading.render`);
        layers: ``factor`` (pixel mean of F) and the declared effects'."""
        return super().render(azimuth_deg, shadows=shadows, elevation_deg=elevation_deg)
