"""One way to build a scene from flags, for every command.

:func:`scene_from_args` starts from ``--scene``'s file, else HEIGHT's sidecar (``m.toml``
beside ``m.png``), else the built-in scene; then applies the command's own defaults where
neither a flag nor the file sets the value, and then the flags. The material named on the
command line (HEIGHT or ``--material``, :func:`material_of`) is checked here, once.
"""

from __future__ import annotations

import dataclasses
import difflib
import sys
from pathlib import Path

from hzval import materials
from hzval.cli import flags
from hzval.core import errors
from hzval.io import documents, heightmap


def builtin(name: str) -> bool:
    """Return whether ``name`` is a built-in material rather than a height map's file."""
    return materials.is_builtin(name)


def material_of(args) -> str | None:
    """Return the material the command line names: HEIGHT's path, ``--material``'s name, or ``None``.

    An unknown material (with the nearest names) and ``--size`` with HEIGHT (a file has its own size) are
    refused in one line.
    """
    if args.height is not None and args.material is not None:
        raise errors.InputError("--material", f"give HEIGHT ({args.height}) or --material, not both")
    if args.material is not None:
        check_material_name(args.material)
    if args.height is not None and getattr(args, "size", None) is not None:
        refuse_size(args.size, str(args.height))
    return str(args.height) if args.height is not None else args.material


def check_material_name(name: str) -> None:
    """Refuse an unknown built-in material's name in one line, with the nearest names."""
    if materials.is_builtin(name):
        return
    near = difflib.get_close_matches(name, materials.names(), n=1, cutoff=0.6)
    hint = f"did you mean {' or '.join(near)}? " if near else ""
    raise errors.InputError(
        "--material",
        f"unknown material {name!r}; {hint}(known: {', '.join(materials.names())}; "
        "`hzval materials` describes them)",
    )


def refuse_size(size: int, height: str) -> None:
    """``--size`` names a built-in material's size; a height map file has its own (nothing resamples it)."""
    try:
        rows, cols = heightmap.probe_shape(height)
        own = f" ({cols}x{rows})"
    except errors.HzvalError:
        own = ""
    raise errors.InputError(
        "--size",
        f"{size} applies to built-in materials only; {height} has its own size{own}: "
        "resize the file, or leave --size out",
    )


def scene_name(args, scene) -> str:
    """Return a sweep's name: HEIGHT's stem, else the scene's.

    The scene's name is a built-in material's name unless a scene file names it.
    """
    if args.height is not None:
        return Path(args.height).stem
    if getattr(args, "material", None) is not None and not getattr(args, "scene", None):
        return args.material
    return scene.name


def model_view(base, overrides: dict) -> dict:
    """Return ``overrides`` with :data:`hzval.scene.spec.MODEL_CAMERA`'s view where it applies.

    It applies where the sweep is on a model and neither the scene nor the flags place a camera: a model seen
    from straight above shows one face.
    """
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.scene import spec as sc

    shape = overrides.get("mesh") or base.mesh.shape
    uv_scale = overrides.get("uv_scale") or base.mesh.uv_scale
    if sc.MeshSpec(shape, uv_scale).is_plane or base.camera != sc.Camera() or overrides.get("camera"):
        return overrides
    cam = sc.MODEL_CAMERA
    return {
        **overrides,
        "camera": cam.kind,
        "view_elevation": overrides.get("view_elevation") or cam.elevation_deg,
        "view_azimuth": overrides.get("view_azimuth") or cam.azimuth_deg,
    }


#: The :func:`hzval.scene.spec.override` keywords a command's flags may set, each the name of its
#: flag's ``dest``; ``truth_tolerance`` and ``resolution`` are checked and parsed first.
OVERRIDES = (
    "size", "depth", "boundary", "shading", "truth_tolerance", "elevation", "azimuths", "light",
    "light_radius", "effects", "spp", "seed", "supersampling", "camera", "view_elevation",
    "view_azimuth", "fov", "distance", "resolution", "plane", "filter", "mips", "parallax", "mesh",
    "uv_scale", "up", "tangent_bug", "tangents",
)  # fmt: skip

#: Where a scene file sets the keys a command may default (:func:`scene_from_args`'s ``defaults``).
FILE_KEYS = {
    "size": ("material", "size"),
    "depth": ("material", "depth"),
    "boundary": ("material", "boundary"),
    "elevation": ("light", "elevation_deg"),
    "azimuths": ("light", "azimuths"),
    "spp": ("samples", "spp"),
    "effects": ("effects", "list"),
    "camera": ("camera", "kind"),
    "resolution": ("camera", "resolution"),
}


def scene_overrides(args) -> dict:
    """Return the flags of ``args`` that change a scene (:data:`OVERRIDES`).

    Each is ``None`` where not given or where the command has no such flag; the material is
    :func:`material_of`'s.
    """
    out = {k: getattr(args, k, None) for k in OVERRIDES}
    out["truth_tolerance"] = flags.truth_tolerance(args)
    out["resolution"] = flags.resolution(getattr(args, "resolution", None))
    return out


def base_scene(args, *, quiet: bool = False):
    """Return the scene the flags change, and the TOML it was read from (``{}`` for none).

    The scene is ``--scene``'s file where the command has one, else HEIGHT's sidecar (``gravel.toml`` beside
    ``gravel.png``, said on stderr unless ``quiet``), else the built-in default scene.
    """
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.scene import files as scene_files
    from hzval.scene import spec as sc

    if getattr(args, "scene", None):
        return scene_files.load_scene(args.scene), documents.read_toml(args.scene)
    height = getattr(args, "height", None)
    side = None if height is None else scene_files.sidecar_of(height)
    if side is None:
        return sc.Scene(), {}
    scene = scene_files.load_sidecar(side, height)
    if not quiet:
        print(f"hzval: using the sidecar scene {side}", file=sys.stderr)
    return scene, documents.read_toml(side)


def scene_from_args(args, defaults: dict | None = None, *, quiet: bool = False):
    """Return the scene a command's flags describe: the one way every command builds one.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed flags; a flag the command does not have counts as not given.
    defaults : dict, optional
        The command's own defaults (``views``: 128 texels, 4 samples), as
        :func:`hzval.scene.spec.override` keywords of :data:`FILE_KEYS`. Each applies where
        neither a flag nor the scene file (``--scene``, or HEIGHT's sidecar) sets the value;
        ``size`` only to a built-in material.
    quiet : bool
        Leave out the line that names a sidecar.

    Returns
    -------
    hzval.scene.spec.Scene
        Validated, named after HEIGHT's stem, else ``--material``, else the scene file's name.
    """
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.scene import spec as sc

    base, data = base_scene(args, quiet=quiet)
    given = {k: v for k, v in scene_overrides(args).items() if v is not None}
    if "elevation" in given:
        check_elevations(given["elevation"])
    height = material_of(args)
    material = height or base.material.height
    own = {}
    for key, value in (defaults or {}).items():
        table, name = FILE_KEYS[key]
        if key in given or name in (data.get(table) or {}):
            continue
        if key == "size" and not builtin(material):
            continue
        own[key] = value
    placed = model_view(base, {**own, **given})
    if placed.get("camera") != {**own, **given}.get("camera") and not quiet:
        cam = sc.MODEL_CAMERA  # said once the run is done (flags.print_notes): errors stay one line
        args.notes = [
            *getattr(args, "notes", []),
            f"on a model with no camera given, a perspective view from {cam.elevation_deg:g} degrees "
            f"up and azimuth {cam.azimuth_deg:g} (a top view shows one face; --camera and "
            "--view-elevation choose another)",
        ]
    try:
        scene = sc.override(base, **placed, height=height)
    except errors.InputError as exc:
        raise _as_flag(exc, given) from None
    if "size" in given and not builtin(scene.material.height):  # a scene file's own height map
        refuse_size(given["size"], scene.material.height)
    if "light_radius" in given and scene.light.kind != "soft":  # it would be ignored in silence
        raise errors.InputError(
            "--light-radius",
            f"applies to a soft light (--light soft); this run's light is {scene.light.kind}",
        )
    return dataclasses.replace(scene, name=scene_name(args, scene))


def check_elevations(value) -> tuple[float, ...]:
    """Return the light elevations of ``--elevation``, each in (0, 90] degrees.

    ``--elevation`` is one number, a list or START:STOP:STEP; anything else, or an elevation out of range,
    is refused in one line naming the flag.
    """
    # on use: importing the CLI loads no renderer (the LLVM is chosen first)
    from hzval.scene import spec as sc

    try:
        values = sc.parse_azimuths(value, "--elevation") if isinstance(value, str) else (float(value),)
    except errors.InputError:
        raise errors.InputError(
            "--elevation", f"expected degrees in (0, 90]: one value, a list or START:STOP:STEP, got {value!r}"
        ) from None
    for e in values:
        if not 0.0 < e <= 90.0:  # math.nan fails too
            raise errors.InputError(
                "--elevation", f"the light's elevation must be in (0, 90] degrees, got {e:g}"
            )
    return values


#: The scene keys a flag sets, as :meth:`hzval.scene.spec.Scene.validate` names them.
KEY_FLAGS = {
    "material.size": "size",
    "material.depth": "depth",
    "material.truth_tolerance": "truth_tolerance",
    "light.elevation_deg": "elevation",
    "light.elevations": "elevation",
    "light.radius_deg": "light_radius",
    "light.azimuths": "azimuths",
    "samples.spp": "spp",
    "samples.seed": "seed",
}


def _as_flag(exc: errors.InputError, given: dict) -> errors.InputError:
    """Return an error about a scene key the flags set, named by its flag.

    For example ``--size: must be at least 8``. Errors about a scene file's own values keep naming the file.
    """
    key = next((k for k in KEY_FLAGS if exc.problem.startswith(k + " ")), None)
    if exc.what != "scene" or key is None or KEY_FLAGS[key] not in given and key != "material.size":
        return exc
    rest = exc.problem[len(key) + 1 :]
    rest = "for " + rest[3:] if rest.startswith("of ") else rest  # "of the built-in bricks must be"
    return errors.InputError("--" + KEY_FLAGS[key].replace("_", "-"), rest)


def input_name(args, info: dict) -> str:
    """Return how a command's closing line names its input.

    It is the height map's file as given, then what was read of it (``h.png: 16-bit PNG, grey``), or the
    built-in material.
    """
    height = getattr(args, "height", None)
    return f"{height}: {info['source']}" if height else info["source"]
