"""The scene: one description that both the truth and the approximation render.

A scene names a material, a camera, a light with its sweep, the effects it
calls for, and sample counts. It is read from TOML (``scenes/*.toml``, :mod:`hzval.scene.files`) and
the command line overrides it. Only the surface differs between the two
renderers; everything here (camera, sample positions, light directions,
units) is shared, so that any error that is not the technique's shows up as
a bug rather than as error.

Units and conventions: positions in texel units of the tangent space of
:mod:`hzval.core.conventions`; the light's ``irradiance`` is the irradiance E on
a surface facing it (so a Lambertian surface of albedo a shows radiance
``a / pi * E * cos(theta)``); angles in degrees.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np
from PIL import Image

from hzval import materials
from hzval.core import conventions as cv
from hzval.core import srgb
from hzval.core.errors import InputError
from hzval.geometry import tangent_bugs
from hzval.geometry import tangents as tg
from hzval.geometry.tile import DEFAULT_TOLERANCE
from hzval.io import heightmap
from hzval.scene.camera import Camera, stream
from hzval.scene.lookup import Lookup

__all__ = [
    "material_record",
    "IRRADIANCE_RANGE",
    "EFFECTS",
    "SHADINGS",
    "DEFAULT_AZIMUTHS_TEXT",
    "DEFAULT_AZIMUTHS",
    "DEFAULT_TRUTH_TOLERANCE",
    "DEFAULT_ALBEDO",
    "MaterialSpec",
    "MeshSpec",
    "MODEL_CAMERA",
    "MESH_SUFFIXES",
    "Light",
    "DEFAULT_EFFECTS",
    "DEFAULT_INTERREFLECTION_DEPTH",
    "Scene",
    "MAX_LIGHTS",
    "check_light_count",
    "parse_azimuths",
    "elevation_fields",
    "material_defaults",
    "override",
    "image_shape",
    "light_samples",
    "load_material_height",
    "load_albedo",
    "Frame",
]

#: Effects a scene can call for (docs/ARCHITECTURE.md, "Effects"), in rendering order.
EFFECTS: tuple[str, ...] = (
    "shadow",
    "diffuse",
    "specular",
    "ambient",
    "reflection_occlusion",
    "interreflection",
)
#: How the truth shades the displaced mesh (docs/internals.md, the truth's "Shading"): with
#: the normal interpolated from vertex normals, as a displaced mesh is shaded
#: and as the techniques' normal map is, or with each triangle's flat normal.
SHADINGS: tuple[str, ...] = ("smooth", "faceted")
#: The default sweep (Lengyel's Figure 5.3), as ``--azimuths`` spells it and as degrees.
DEFAULT_AZIMUTHS_TEXT = "-60:60:15"
DEFAULT_AZIMUTHS = tuple(float(a) for a in range(-60, 61, 15))


#: The truth's default tolerance, texels (:data:`hzval.geometry.tile.DEFAULT_TOLERANCE`).
DEFAULT_TRUTH_TOLERANCE = DEFAULT_TOLERANCE

#: The albedo of a height map that comes without one.
DEFAULT_ALBEDO = 0.8


#: The irradiances a scene may declare: float32 renders hold a pixel's variance, about the square of
#: its radiance, between 1.2e-38 (the smallest normal) and 3.4e38; these keep it well inside, and
#: cover every unit a renderer uses (1 here; 1e5 lux for the sun).
IRRADIANCE_RANGE = (1e-6, 1e9)


@dataclass(frozen=True)
class MaterialSpec:
    """Which height map, at which depth and boundary.

    ``height`` names a built-in material (:data:`hzval.materials.REGISTRY`,
    generated at ``size``) or a height map file. ``albedo``: an sRGB image
    path, a constant linear albedo, or ``None`` for the material's own (a
    built-in material's albedo; :data:`DEFAULT_ALBEDO` for a file).
    """

    height: str = materials.DEFAULT
    size: int = materials.DEFAULT_SIZE
    depth: float = 0.05
    boundary: str = "wrap"
    albedo: str | float | None = None
    shading: str = "smooth"  # the truth's shading normal: "smooth" (vertex normals) or "faceted"
    #: how far, in texels of height, the truth's triangles may be from the bilinear surface
    #: (hzval.geometry.tile.cell_levels; the default from docs/truth-surface.md's convergence study)
    truth_tolerance: float = DEFAULT_TRUTH_TOLERANCE


@dataclass(frozen=True)
class MeshSpec:
    """The surface the material is on (:mod:`hzval.geometry.model`).

    ``shape`` is a built-in shape or a mesh file's path; ``uv_scale``: how often the texture repeats across
    the UVs; ``up``: the file's up axis (``None``: the format's default); ``tangent_bug``: the engine bug the
    techniques' frames are built with (:data:`hzval.geometry.tangent_bugs.BUGS`; the truth's never change);
    ``tangents``: which frames the mesh uses (:data:`hzval.geometry.tangents.METHODS`).
    """

    shape: str = "plane"
    uv_scale: float = 1.0
    up: str | None = None
    tangent_bug: str = "none"
    tangents: str = "auto"

    @property
    def is_plane(self) -> bool:
        """Today's tile: the plane the techniques' textures lie on, traced as a height field."""
        return self.shape == "plane" and self.uv_scale == 1.0


#: The camera of a sweep on a model that names none: in perspective from 35 degrees up, so that a
#: cube shows three faces (the plane's default, ``top``, would show one).
MODEL_CAMERA = Camera(kind="perspective", elevation_deg=35.0, azimuth_deg=-30.0)

#: Suffixes of the mesh files a scene may name (hzval.geometry.model reads them).
MESH_SUFFIXES: tuple[str, ...] = (".obj", ".ply", ".gltf", ".glb")


@dataclass(frozen=True)
class Light:
    """A directional light (``hard``) or a disk of angular radius ``radius_deg`` (``soft``).

    A sweep lights the surface from every ``(elevation, azimuth)`` pair of :meth:`elevations` and
    ``azimuths_deg``. ``elevations_deg`` (``[light] elevations``, ``--elevation 15:75:15``) makes
    light elevation a sweep axis; empty, the one ``elevation_deg``. With several, ``elevation_deg``
    is the lowest: what the truth is built for (its shadow rays are the longest there).
    """

    kind: str = "hard"
    radius_deg: float = 0.0
    elevation_deg: float = 30.0
    azimuths_deg: tuple[float, ...] = DEFAULT_AZIMUTHS
    irradiance: float = 1.0
    elevations_deg: tuple[float, ...] = ()

    def direction(self, azimuth_deg: float, elevation_deg: float | None = None) -> np.ndarray:
        """Return the unit vector toward the light's centre at ``azimuth_deg`` and ``elevation_deg``.

        ``elevation_deg`` defaults to :attr:`elevation_deg`.
        """
        e = self.elevation_deg if elevation_deg is None else elevation_deg
        return cv.light_direction(azimuth_deg, e)

    def elevations(self) -> tuple[float, ...]:
        """Return the sweep's light elevations in degrees.

        They are :attr:`elevations_deg`, else :attr:`elevation_deg`.
        """
        return tuple(self.elevations_deg) or (self.elevation_deg,)

    def at(self, elevation_deg: float) -> "Light":
        """Return this light at one elevation of the sweep (no elevation axis)."""
        return dataclasses.replace(self, elevation_deg=float(elevation_deg), elevations_deg=())


#: What a scene simulates when it does not say: Lengyel's Figure 5.3 - a
#: normal-mapped (Lambertian) surface with horizon-mapped shadows - so that
#: the report's plain normal mapping differs from the horizon-mapped image
#: by exactly the shadows.
DEFAULT_EFFECTS = ("shadow", "diffuse")

#: Mitsuba's ``max_depth`` convention: 2 is direct light only, 3 adds one bounce.
DEFAULT_INTERREFLECTION_DEPTH = 3


@dataclass(frozen=True)
class Scene:
    """A scene: the material, the surface it is on, the camera, the lights, the lookup, the effects."""

    name: str = "bricks"
    material: MaterialSpec = MaterialSpec()
    camera: Camera = Camera()
    mesh: MeshSpec = MeshSpec()
    lookup: Lookup = Lookup()
    light: Light = Light()
    effects: tuple[str, ...] = DEFAULT_EFFECTS
    interreflection_depth: int = DEFAULT_INTERREFLECTION_DEPTH
    spp: int = 16
    seed: int = 0
    tolerances: dict = field(default_factory=dict)
    check: dict = field(default_factory=dict)  # how `hzval check` renders it (hzval.commands.check)
    source: str | None = None  # the TOML file it came from

    def validate(self) -> "Scene":
        """Return this scene if every setting is in its range, else raise one line naming the file or flag."""
        what = self.source or "scene"
        m, lt = self.material, self.light
        cv.check_depth(m.depth, f"{what}: material.depth" if self.source else "--depth", m.boundary)
        # values from TOML may be of any type: every number must be one (and finite) before it is compared
        for name, value in (
            ("material.depth", m.depth),
            ("material.size", m.size),
            ("material.truth_tolerance", m.truth_tolerance),
            ("light.radius_deg", lt.radius_deg),
            ("light.elevation_deg", lt.elevation_deg),
            ("light.irradiance", lt.irradiance),
            ("samples.spp", self.spp),
            ("samples.seed", self.seed),
            ("effects.interreflection_depth", self.interreflection_depth),
            *((f"light.azimuths[{i}]", a) for i, a in enumerate(lt.azimuths_deg)),
            *((f"light.elevations[{i}]", e) for i, e in enumerate(lt.elevations_deg)),
        ):
            if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
                raise InputError(what, f"{name} must be a number, got {value!r}")
            if name == "light.radius_deg" and lt.kind != "soft":
                continue
            if not math.isfinite(value):
                raise InputError(what, f"{name} must be a finite number, got {value}")
        if m.truth_tolerance <= 0:
            raise InputError(
                what, f"material.truth_tolerance must be a positive number of texels, got {m.truth_tolerance}"
            )
        if m.shading not in SHADINGS:
            raise InputError(what, f"material.shading must be smooth or faceted, got {m.shading!r}")
        if m.boundary not in cv.BOUNDARIES:
            raise InputError(what, f"material.boundary must be wrap or open, got {m.boundary!r}")
        if m.size < 2:
            raise InputError(what, f"material.size must be at least 2, got {m.size}")
        if materials.is_builtin(m.height) and m.size < materials.get(m.height).min_size:
            raise InputError(
                what,
                f"material.size of the built-in {m.height} must be at least "
                f"{materials.get(m.height).min_size}, got {m.size}",
            )
        lo, hi = IRRADIANCE_RANGE
        if not lo <= lt.irradiance <= hi:
            raise InputError(
                what,
                f"light.irradiance must be in [{lo:g}, {hi:g}] (renders are float32: a pixel's variance, "
                f"the square of its radiance, must stay finite and normal), got {lt.irradiance:g}",
            )
        if int(self.seed) != self.seed or self.seed < 0:
            raise InputError(what, f"samples.seed must be a non-negative integer, got {self.seed}")
        if self.interreflection_depth < 2:
            raise InputError(
                what,
                "effects.interreflection_depth counts path segments as Mitsuba's max_depth: "
                f"at least 2 (direct light), got {self.interreflection_depth}",
            )
        if lt.kind not in ("hard", "soft"):
            raise InputError(what, f"light.kind must be hard or soft, got {lt.kind!r}")
        if lt.kind == "soft" and not 0 < lt.radius_deg < 90:
            raise InputError(what, f"a soft light needs 0 < light.radius_deg < 90, got {lt.radius_deg}")
        if not -90 <= lt.elevation_deg <= 90:
            raise InputError(what, f"light.elevation_deg must be in [-90, 90], got {lt.elevation_deg}")
        if not lt.azimuths_deg:
            raise InputError(what, "light.azimuths is empty")
        check_light_count(len(lt.azimuths_deg), what if self.source else "--azimuths")
        for e in lt.elevations_deg:
            if not 0 < e <= 90:
                raise InputError(what, f"light.elevations must each be in (0, 90], got {e:g}")
        check_light_count(len(lt.azimuths_deg) * len(lt.elevations()), what if self.source else "--elevation")
        unknown = [e for e in self.effects if e not in EFFECTS]
        if unknown or not self.effects:
            raise InputError(what, f"unknown or no effects {unknown}; choose from {', '.join(EFFECTS)}")
        if self.spp < 1:
            raise InputError(what, "samples.spp must be at least 1")
        self.camera.validate(what)
        self.lookup.validate(what)
        self._validate_mesh(what)
        if self.camera.kind == "perspective" and self.mesh.is_plane:
            # on a model every sample carries its own view (lookup.Samples.frames); the tile's do not
            needs_v = [e for e in ("specular", "reflection_occlusion") if self.declares(e)]
            if needs_v:
                raise InputError(
                    what,
                    f"{' and '.join(needs_v)} with a perspective camera need the view direction "
                    "per pixel, which the tile's techniques do not take yet: use an orthographic "
                    "camera (or --mesh, whose samples carry their own)",
                )
        return self

    def declares(self, effect: str) -> bool:
        """Return whether the scene declares ``effect`` (:data:`EFFECTS`)."""
        return effect in self.effects

    def _validate_mesh(self, what: str) -> None:
        ms = self.mesh
        if not isinstance(ms.shape, str) or not ms.shape:
            raise InputError(what, f"mesh.shape must be a shape name or a mesh file, got {ms.shape!r}")
        if (
            isinstance(ms.uv_scale, bool)
            or not isinstance(ms.uv_scale, (int, float))
            or not math.isfinite(ms.uv_scale)
            or ms.uv_scale <= 0
        ):
            raise InputError(
                what if self.source else "--uv-scale",
                f"the UV scale must be a positive number, got {ms.uv_scale!r}",
            )
        if ms.up not in (None, "y", "z"):
            raise InputError(what if self.source else "--up", f"the up axis must be y or z, got {ms.up!r}")

        tangent_bugs.check(ms.tangent_bug, what if self.source else "--tangent-bug")

        if ms.tangents not in tg.METHODS:
            raise InputError(
                what if self.source else "--tangents",
                f"mesh.tangents must be one of {', '.join(tg.METHODS)}, got {ms.tangents!r}",
            )


# --------------------------------------------------------------------------
# Reading and overriding
# --------------------------------------------------------------------------

#: The most lights a sweep renders: one-degree steps around the whole circle, both ends included.
#: Each light is a frame (the truth, every technique, their comparisons and about ten files: 1 s and
#: 5 MB at 512 x 512, 70 MB at 2048); beyond one degree apart, neighbouring frames differ by less
#: than their own noise. The count is computed from START:STOP:STEP before any list is made.
MAX_LIGHTS = 361


def check_light_count(n: int, what: str = "--azimuths") -> int:
    """``n`` if it is at most :data:`MAX_LIGHTS`, else one line naming ``what``."""
    if n > MAX_LIGHTS:
        count = f"{int(n)}" if n < 1e12 else f"{n:.3g}"
        raise InputError(what, f"{count} lights; at most {MAX_LIGHTS} (one-degree steps around the circle)")
    return n


def parse_azimuths(text: str | list, what: str = "--azimuths") -> tuple[float, ...]:
    """Parse azimuths in degrees from a range, a comma-separated list or a list.

    A range is ``"-60:60:15"`` (start:stop:step, stop included; a negative step counts down), a
    comma-separated list ``"0,45,90"``. The azimuths are finite, at most :data:`MAX_LIGHTS` of them (counted
    before the list is made).
    """
    bad = InputError(what, f"expected START:STOP:STEP or a comma-separated list of degrees, got {text!r}")
    if isinstance(text, (list, tuple)):
        check_light_count(len(text), what)
        if any(isinstance(a, bool) or not isinstance(a, (int, float)) for a in text):
            raise InputError(what, f"expected a list of numbers of degrees, got {list(text)!r}")
        values = tuple(float(a) for a in text)
    elif not isinstance(text, str):
        raise bad
    elif ":" in text:
        try:
            start, stop, step = (float(v) for v in text.split(":"))
        except ValueError:
            raise bad from None
        if not all(map(math.isfinite, (start, stop, step))):
            raise bad
        if step == 0 or (stop - start) * step < 0:  # a step that never reaches STOP: say which way
            raise InputError(
                what,
                f"{text!r} counts from {start:g} toward {stop:g} in steps of {step:g}, which never get "
                f"there; use {start:g}:{stop:g}:{math.copysign(abs(step) or 15.0, stop - start):g}",
            )
        count = math.floor((stop - start) / step + 1e-9) + 1
        check_light_count(count, what)
        values = tuple(start + i * step for i in range(int(count)))
    else:
        try:
            values = tuple(float(v) for v in text.split(",") if v.strip())
        except ValueError:
            raise bad from None
        check_light_count(len(values), what)
    if not all(map(math.isfinite, values)):
        raise bad
    return values


def elevation_fields(values) -> dict:
    """Return :class:`Light`'s ``elevation_deg`` and ``elevations_deg`` of the elevations ``values``.

    Repeats are dropped and the order kept: one elevation is the light's elevation, several a sweep axis built
    at the lowest.
    """
    values = tuple(dict.fromkeys(float(v) for v in values))
    if len(values) == 1:
        return {"elevation_deg": values[0], "elevations_deg": ()}
    return {"elevation_deg": min(values), "elevations_deg": values}


def material_defaults(height: str) -> dict:
    """Return ``depth`` and ``boundary`` for a scene of ``height`` that does not set them.

    They are a built-in material's own, else 0.05 and ``wrap``.
    """
    if materials.is_builtin(height):
        m = materials.get(height)
        return {"depth": m.depth, "boundary": m.boundary}
    return {"depth": MaterialSpec.depth, "boundary": MaterialSpec.boundary}


def override(scene: Scene, **changes) -> Scene:
    """Return a copy of ``scene`` with command-line values; ``None`` leaves a value alone.

    Keys: ``height, size, depth, boundary, shading, truth_tolerance, elevation, azimuths, light, light_radius,
    effects, spp, seed, supersampling``; the camera's ``camera`` (its kind), ``view_elevation``,
    ``view_azimuth``, ``fov``, ``distance``, ``resolution`` (``(W, H)``), ``film_size``; the
    lookup's ``plane``, ``filter``, ``mips``, ``parallax``, ``parallax_steps``; the mesh's ``mesh``
    (its shape), ``uv_scale``, ``up``, ``tangent_bug``, ``tangents``.
    """
    c = {k: v for k, v in changes.items() if v is not None}
    mat = scene.material
    if "height" in c and c["height"] != mat.height:
        # another material: a depth or boundary that was the old material's default becomes the new one's
        old, new = material_defaults(mat.height), material_defaults(c["height"])
        mat = dataclasses.replace(mat, **{k: new[k] for k in new if getattr(mat, k) == old[k]})
    mat = dataclasses.replace(
        mat,
        **{k: c[k] for k in ("height", "size", "depth", "boundary", "shading", "truth_tolerance") if k in c},
    )
    light = scene.light
    if "elevation" in c:
        e = c["elevation"]
        values = parse_azimuths(e, "--elevation") if isinstance(e, str) else (float(e),)
        light = dataclasses.replace(light, **elevation_fields(values))
    if "azimuths" in c:
        light = dataclasses.replace(light, azimuths_deg=parse_azimuths(c["azimuths"]))
    if "light" in c:
        light = dataclasses.replace(light, kind=c["light"])
    if "light_radius" in c:
        light = dataclasses.replace(light, radius_deg=float(c["light_radius"]))
    effects = scene.effects
    if "effects" in c:
        effects = (
            tuple(e.strip() for e in c["effects"].split(",") if e.strip())
            if isinstance(c["effects"], str)
            else tuple(c["effects"])
        )
    camera_keys = {
        "camera": "kind",
        "supersampling": "supersampling",
        "view_elevation": "elevation_deg",
        "view_azimuth": "azimuth_deg",
        "fov": "fov_deg",
        "distance": "distance",
        "resolution": "resolution",
        "film_size": "film_size",
    }
    camera = dataclasses.replace(
        scene.camera,
        **{
            camera_keys[k]: (tuple(v) if isinstance(v, list) else v) for k, v in c.items() if k in camera_keys
        },
    )
    placed = [
        k for k in ("view_elevation", "view_azimuth", "fov", "distance", "resolution", "film_size") if k in c
    ]
    if camera.kind == "top" and placed:
        raise InputError(
            "--" + placed[0].replace("_", "-"),
            "places a camera: choose one with --camera orthographic or perspective (top is straight down)",
        )
    lookup = dataclasses.replace(
        scene.lookup, **{k: c[k] for k in ("plane", "filter", "mips", "parallax", "parallax_steps") if k in c}
    )
    mesh = dataclasses.replace(
        scene.mesh,
        **{
            k: c[m]
            for m, k in (
                ("mesh", "shape"),
                ("uv_scale", "uv_scale"),
                ("up", "up"),
                ("tangent_bug", "tangent_bug"),
                ("tangents", "tangents"),
            )
            if m in c
        },
    )
    return dataclasses.replace(
        scene,
        material=mat,
        light=light,
        effects=effects,
        camera=camera,
        lookup=lookup,
        mesh=mesh,
        spp=c.get("spp", scene.spp),
        seed=c.get("seed", scene.seed),
    ).validate()


# --------------------------------------------------------------------------
# Where each pixel is sampled, and toward where its light is
# --------------------------------------------------------------------------


def image_shape(rows: int, cols: int, camera: Camera) -> tuple[int, int]:
    """Return the pixels ``(H, W)`` of a render of a ``rows x cols`` height map.

    They are :meth:`hzval.scene.camera.Camera.image_shape`'s.
    """
    return camera.image_shape(rows, cols)


def light_samples(
    light: Light, azimuth_deg: float, count: int, seed: int, samples: tuple[int, int] | None = None
) -> np.ndarray:
    """``(count, 3)`` unit directions toward the light, one per sample.

    A hard light gives its direction every time; a soft light samples the
    cone of half-angle ``radius_deg`` about its centre uniformly in solid
    angle (a disk light of that angular radius, uniformly bright).
    ``samples``: ``(first, stop)``, only those of the ``count`` (a band), bit for bit.
    """
    first, stop = (0, count) if samples is None else (int(samples[0]), int(samples[1]))
    centre = light.direction(azimuth_deg)
    if light.kind == "hard":
        return np.broadcast_to(centre, (stop - first, 3)).astype(np.float32)
    cos_max = math.cos(math.radians(light.radius_deg))
    # one PCG64 stream: all u1, then all u2 (as default_rng([seed, 0x11647]).random twice)
    u1 = stream([seed, 0x11647], first).random(stop - first)
    u2 = stream([seed, 0x11647], count + first).random(stop - first)
    cos_t = 1.0 - u1 * (1.0 - cos_max)
    sin_t = np.sqrt(np.clip(1.0 - cos_t * cos_t, 0, None))
    phi = 2 * math.pi * u2
    local = np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t], axis=-1)
    # an orthonormal frame around the centre (Duff et al. 2017)
    z = centre
    sign = math.copysign(1.0, z[2])
    a = -1.0 / (sign + z[2])
    b = z[0] * z[1] * a
    t = np.array([1 + sign * z[0] * z[0] * a, sign * b, -sign * z[0]])
    s = np.array([b, sign + z[1] * z[1] * a, -z[1]])
    return (local[:, :1] * t + local[:, 1:2] * s + local[:, 2:] * z).astype(np.float32)


def load_material_height(spec: MaterialSpec):
    """Return the scene's height map as a :class:`hzval.io.heightmap.HeightMap`, its relief checked.

    The relief is checked at the material's depth (:func:`hzval.core.conventions.check_relief`): a map of
    heights in metres is refused here, in one line, before anything is built from it.
    """
    if materials.is_builtin(spec.height):
        m = materials.get(spec.height)
        hm = heightmap.from_array(
            materials.generate(spec.height, spec.size).height,
            source=f"built-in {m.label}, {spec.size}x{spec.size}",
        )
    else:
        hm = heightmap.check_usable(heightmap.load_height(spec.height))
    cv.check_relief(hm.height, spec.depth, spec.boundary, hm.path or hm.source)
    return hm


def load_albedo(spec: MaterialSpec, rows: int, cols: int) -> np.ndarray:
    """Return the linear albedo ``(rows, cols, 3)`` float32.

    It is a constant, an sRGB image decoded to linear, or (``albedo = None``) a built-in material's own.
    """
    if spec.albedo is None and materials.is_builtin(spec.height):
        own = materials.generate(spec.height, spec.size).albedo
        if own is not None:
            return np.array(own)
    if not isinstance(spec.albedo, str):
        a = DEFAULT_ALBEDO if spec.albedo is None else float(spec.albedo)
        if not 0 <= a <= 1:
            raise InputError("material.albedo", f"must be in [0, 1], got {a}")
        return np.full((rows, cols, 3), a, np.float32)

    try:
        with Image.open(spec.albedo) as img:
            rgb = np.asarray(img.convert("RGB"), dtype=np.float64) / 255.0
    except (OSError, ValueError) as exc:
        raise InputError(spec.albedo, f"not a readable albedo image ({str(exc).splitlines()[0]})") from None
    if rgb.shape[:2] != (rows, cols):
        raise InputError(
            spec.albedo, f"albedo is {rgb.shape[1]}x{rgb.shape[0]}, the height map {cols}x{rows}"
        )
    return srgb.decode(rgb).astype(np.float32)


@dataclass
class Frame:
    """One render of one light of the sweep, by the truth or the approximation.

    ``image``: the shaded result, linear radiance, float32 ``(H, W, 3)``.
    ``layers``: named one-channel ``(H, W)`` images: the truth's
    ``visibility`` (V) and the approximation's ``factor`` (F), in [0, 1],
    and any other per-effect term (e.g. ``ambient``). ``variance``: for Monte
    Carlo images, the per-pixel variance of the pixel's mean (squared
    standard error), keyed like ``layers`` (``"image"`` for the image).
    ``seconds``: render time, kernels synchronised. ``mask``: ``(H, W)`` bool, the
    pixels whose camera rays see the surface (a view other than ``top``; ``None``: all);
    the others are left out of every metric.
    """

    azimuth_deg: float
    elevation_deg: float
    image: np.ndarray
    layers: dict[str, np.ndarray] = field(default_factory=dict)
    variance: dict[str, np.ndarray] = field(default_factory=dict)
    seconds: float = 0.0
    mask: np.ndarray | None = None


def material_record(scene: Scene) -> tuple[np.ndarray, dict]:
    """Return ``scene``'s material height map and the record ``bake.json`` and ``fit.json`` keep of it.

    The height map comes from :func:`load_material_height`, the one loader; the record holds its file (or the
    built-in's name and size), how it was read, its digest and shape.
    """
    hm = load_material_height(scene.material)
    m = scene.material
    info = (
        {"path": None, "builtin": m.height, "size": m.size}
        if materials.is_builtin(m.height)
        else {"path": hm.path}
    )
    rows, cols = hm.height.shape
    info.update(source=hm.source, digest=hm.digest, rows=rows, cols=cols)
    return hm.height, info
