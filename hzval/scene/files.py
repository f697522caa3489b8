"""A scene file: TOML read into a :class:`hzval.scene.spec.Scene`, and a height map's sidecar scene.

TOML layout (every key optional; see ``scenes/bricks.toml``)::

    name = "bricks"
    [material]  height = "bricks" (a built-in material: ``hzval materials``) | "path/relative/to/scene.png",
                size, depth, boundary (default: the material's), albedo (default: the material's),
                shading = "smooth" | "faceted", truth_tolerance (texels; hzval.geometry.tile.cell_levels)
    [camera]    kind = "top" | "orthographic" | "perspective", supersampling = 1 (top), elevation_deg,
                azimuth_deg, fov_deg, distance (tile widths), resolution = [W, H], film_size = [w, h]
                (hzval.scene.camera)
    [lookup]    plane = "bottom" | "mean" | "top", filter = "nearest" | "bilinear" | "trilinear" |
                "anisotropic", mips = "average" | "max", max_anisotropy, parallax = "none" | "offset" |
                "occlusion", parallax_steps: how the techniques find and read their textures
                (hzval.scene.lookup)
    [mesh]      shape = "plane" (the tile, the default) | "cube" | "sphere" | "cylinder" | "torus" |
                "path/relative/to/scene.obj" (.obj, .ply, .gltf, .glb with texture coordinates), uv_scale
                (the texture repeats), up = "y" | "z" (the file's up axis): the surface the material is on
                (hzval.geometry.model; docs/meshes.md)
    [light]     kind = "hard" | "soft", radius_deg, elevation_deg, azimuths = "-60:60:15", irradiance
    [effects]   list = ["shadow", "diffuse"], interreflection_depth = 3
    [samples]   spp = 16, seed = 0
    [check]     size, azimuths, spp, depth, resolution: how the regression check renders it
    (hzval.commands.check)
    [tolerances.truth], [tolerances.technique], [tolerances.NAME]  fail, fail_percent, hard_fail, warn
    (hzval.commands.check)
"""

from __future__ import annotations

from pathlib import Path

from hzval import materials
from hzval.core import strict
from hzval.core.errors import InputError
from hzval.io import documents, heightmap, paths
from hzval.scene.camera import Camera
from hzval.scene.lookup import Lookup
from hzval.scene.spec import (
    DEFAULT_EFFECTS,
    DEFAULT_INTERREFLECTION_DEPTH,
    MESH_SUFFIXES,
    Light,
    MaterialSpec,
    MeshSpec,
    Scene,
    elevation_fields,
    material_defaults,
    parse_azimuths,
)

__all__ = ["sidecar_of", "load_sidecar", "check_file", "load_scene"]


def _pairs(section: dict, keys) -> dict:
    """Return a TOML section with the lists under ``keys`` as tuples (frozen, hashable settings)."""
    return {k: (tuple(v) if k in keys and isinstance(v, list) else v) for k, v in section.items()}


def sidecar_of(height: str | Path) -> Path | None:
    """Return the sidecar scene of a height map file, if there is one.

    It is ``gravel.toml`` beside ``gravel.png``.
    """
    p = Path(height).with_suffix(".toml")
    return p if p.is_file() else None


def load_sidecar(path: str | Path, height: str | Path) -> Scene:
    """Return the sidecar scene ``path`` of the height map ``height``.

    The map is its material, whatever the file says; a sidecar that names another height map is an error (it
    would sweep another material under this map's name).
    """
    path, height = Path(path), paths.resolved(height)
    scene = load_scene(path, height=height)
    if scene.material.height != str(height):
        raise InputError(
            path,
            f"names the material {scene.material.height!r}, but it is the sidecar scene of "
            f"{height.name}: remove its material.height",
        )
    return scene


def _height_beside(path: Path) -> str | None:
    """Return the height map that a sidecar scene ``path`` naming no height sits beside.

    It is the one file of its stem with a height map suffix, if there is exactly one.
    """
    found = [path.with_suffix(s) for s in heightmap.SUFFIXES if path.with_suffix(s).is_file()]
    return str(found[0]) if len(found) == 1 else None


def _schema() -> dict:
    """Return what a scene file may hold (module docstring, "TOML layout").

    It is ``{table: {key: type}}`` from the dataclasses each table fills
    (:func:`hzval.core.strict.schema_of`), and the top-level ``name``.
    """
    azimuths = str | tuple[float, ...]
    tiers = {k: float for k in ("fail", "fail_percent", "hard_fail", "warn")}
    return {
        "material": strict.schema_of(MaterialSpec),
        "camera": strict.schema_of(Camera),
        "lookup": strict.schema_of(Lookup),
        "mesh": strict.schema_of(MeshSpec),
        "light": {
            **strict.schema_of(Light, drop=("azimuths_deg", "elevations_deg")),
            "azimuths": azimuths,
            "elevations": azimuths,
        },
        "effects": {"list": tuple[str, ...], "interreflection_depth": int},
        "samples": {"spp": int, "seed": int},
        "check": {
            "size": int,
            "azimuths": azimuths,
            "spp": int,
            "depth": float,
            "resolution": tuple[int, int],
        },
        # [tolerances.truth], [tolerances.technique] and one per technique or check variant, whose
        # names the registry knows: hzval.commands.check checks them (scene imports no technique)
        "tolerances": {"*": tiers},
    }


def check_file(data: dict, path: str | Path) -> None:
    """Refuse a scene file with an unknown table or key, or a value of the wrong type.

    An unknown name is reported with the nearest known name in the one line; types are checked, not coerced
    (:mod:`hzval.core.strict`).
    """
    schema = _schema()
    strict.check_keys(data, {"name": None, **schema}, path)
    if "name" in data:
        strict.check_value(data["name"], str | int, path, "name")
    for table, keys in schema.items():
        if table not in data:
            continue
        if table == "tolerances":
            strict.check_table(data[table], {k: dict for k in data[table]}, path, table)
            for kind, tiers in data[table].items():
                strict.check_table(tiers, keys["*"], path, f"{table}.{kind}")
        else:
            strict.check_table(data[table], keys, path, table)


def load_scene(path: str | Path, *, height: str | Path | None = None) -> Scene:
    """Read a scene from TOML; a relative ``material.height`` is relative to the scene file.

    When the file names no height map, the material is ``height`` if given, else the height map of the same
    stem beside the file (the file is its sidecar: ``gravel.toml`` for ``gravel.png``), else the built-in
    default. Depth and boundary default to the material's (:func:`hzval.scene.spec.material_defaults`).
    """
    path = Path(path)

    data = documents.read_toml(path)
    check_file(data, path)
    try:
        mat = dict(data.get("material", {}))
        if "height" not in mat:
            mat["height"] = str(height) if height is not None else (_height_beside(path) or materials.DEFAULT)
        if "size" in mat and not materials.is_builtin(mat["height"]):
            raise InputError(
                path,
                f"material.size applies to built-in materials only; the height map "
                f"{mat['height']} has its own size (resize the file, or leave size out)",
            )
        mat = {**material_defaults(mat["height"]), **mat}
        if not materials.is_builtin(mat["height"]):
            mat["height"] = str(paths.resolved(path.parent / mat["height"], path, "material.height"))
        if isinstance(mat.get("albedo"), str):
            mat["albedo"] = str(paths.resolved(path.parent / mat["albedo"], path, "material.albedo"))
        light = dict(data.get("light", {}))
        if "azimuths" in light:
            light["azimuths_deg"] = parse_azimuths(light.pop("azimuths"), f"{path}: light.azimuths")
        if "elevations" in light:
            light.update(
                elevation_fields(parse_azimuths(light.pop("elevations"), f"{path}: light.elevations"))
            )
        effects = data.get("effects", {})
        samples = data.get("samples", {})
        mesh = dict(data.get("mesh", {}))
        if Path(str(mesh.get("shape", ""))).suffix.lower() in MESH_SUFFIXES:
            mesh["shape"] = str(paths.resolved(path.parent / mesh["shape"], path, "mesh.shape"))
        scene = Scene(
            name=data.get("name", path.stem),
            material=MaterialSpec(**mat),
            camera=Camera(**_pairs(data.get("camera", {}), ("resolution", "film_size"))),
            mesh=MeshSpec(**mesh),
            lookup=Lookup(**data.get("lookup", {})),
            light=Light(**light),
            effects=tuple(effects.get("list", DEFAULT_EFFECTS)),
            interreflection_depth=effects.get("interreflection_depth", DEFAULT_INTERREFLECTION_DEPTH),
            spp=samples.get("spp", 16),
            seed=samples.get("seed", 0),
            tolerances=dict(data.get("tolerances", {})),
            check=dict(data.get("check", {})),
            source=str(path),
        )
    except TypeError as exc:  # check_file has refused unknown keys: what is left is a value's
        raise InputError(path, f"bad setting ({str(exc).splitlines()[0]})") from None
    except ValueError as exc:  # a value of the wrong kind, e.g. spp = "x"
        raise InputError(path, f"bad setting ({str(exc).splitlines()[0]})") from None
    return scene.validate()
