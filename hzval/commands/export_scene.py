"""The truth as a Mitsuba 3 scene file: open hzval's ground truth in Mitsuba itself.

:func:`write_scene` writes, for one light of a scene, what
:class:`hzval.truth.plane.Truth` traces, in Mitsuba's own terms::

The design in full: docs/internals.md, "hzval.commands.export_scene".
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np
from PIL import Image

from hzval import materials
from hzval.bake.maps import BakeParams
from hzval.core import backend, errors, resources, srgb
from hzval.core.backend import mi  # Dr.Jit loads at first use, once the LLVM is chosen
from hzval.core.errors import InputError
from hzval.geometry import gltf, model
from hzval.geometry import tile as mesh
from hzval.io import atomic, codecs, staging
from hzval.scene.spec import DEFAULT_ALBEDO, Scene, image_shape, load_albedo
from hzval.truth import memory
from hzval.truth.model import ModelTruth

__all__ = ["write_scene", "mitsuba_render", "FILES"]

#: What :func:`write_scene` writes (``albedo.png`` only for an albedo image or a built-in material's own;
#: ``base.glb`` only on a model).
FILES: tuple[str, ...] = ("scene.xml", "mesh.ply", "albedo.png", "base.glb")


def check_fits(scene: Scene) -> int:
    """Refuse, before the map is generated or decoded, an export that would not fit in memory.

    The estimate is the sweep's (:func:`hzval.truth.memory.estimate_peak_bytes`, its mesh at four triangles a
    texel until the map is read; :func:`hzval.geometry.tile.tessellate` refuses a larger one) at one sample a
    pixel, since nothing is rendered (on a model: :func:`hzval.truth.memory.check_fits`'s model estimate); it
    is returned in bytes.
    """
    one = dataclasses.replace(scene, spp=1)
    rows, cols = memory.material_shape(one)
    what = "--size" if materials.is_builtin(scene.material.height) else scene.material.height
    if not scene.mesh.is_plane:
        return memory.check_fits(one, BakeParams(depth=scene.material.depth))
    need = memory.estimate_peak_bytes(one, rows, cols)
    return resources.refuse_over(what, need, f"the mesh of {cols}x{rows} texels", "a smaller map")


def write_scene(
    scene: Scene, height: np.ndarray, out: str | Path, *, azimuth_deg: float = 0.0, force: bool = False
) -> list[Path]:
    """Write the Mitsuba 3 scene of ``scene``'s truth for the light at ``azimuth_deg`` into ``out``.

    ``height``: the normalised height map ``(rows, cols)``. Returns the paths
    written; every file is written under a temporary name and renamed, in a folder held as
    :func:`hzval.io.staging.output_folder` holds it (``force`` as there).
    """
    with staging.output_folder(out, force=force):
        if not scene.mesh.is_plane:
            return _write_model(scene, height, Path(out), azimuth_deg)
        return _write_scene(scene, height, Path(out), azimuth_deg)


def _direct_only(scene: Scene) -> Scene:
    """Return ``scene`` validated.

    It is refused in one line where it declares what Mitsuba's direct integrator does not render.
    """
    scene = scene.validate()
    if any(scene.declares(e) for e in ("interreflection", "specular", "ambient", "reflection_occlusion")):
        raise InputError(
            scene.source or "--effects",
            "export-scene writes the diffuse, shadowed scene of "
            "Mitsuba's direct integrator: declare shadow and/or diffuse only",
        )
    return scene


def _write_scene(scene: Scene, height: np.ndarray, out: Path, azimuth_deg: float) -> list[Path]:
    backend.variant()
    scene = _direct_only(scene)
    h = np.asarray(height, np.float32)
    rows, cols = h.shape
    mat, light = scene.material, scene.light
    margin = None
    if mat.boundary == "wrap":
        margin = mesh.wrap_margin(
            np.asarray(h, np.float64) * mat.depth * cols,
            min(mesh.MIN_ELEVATION_DEG, max(light.elevation_deg, 1.0)),
        )
    what = "--size" if materials.is_builtin(mat.height) else mat.height
    mesh.check_fits(what, h, mat.depth, mat.boundary, margin=margin)
    m = mesh.displaced_mesh(
        h, mat.depth, mat.boundary, margin=margin, normals=mat.shading == "smooth", name="surface"
    )
    written = []
    mesh.write_ply(m, out / "mesh.ply")
    written.append(out / "mesh.ply")
    reflectance = _reflectance(scene, out, written)
    sensor = _top_sensor(scene, rows, cols, float(h.max()) * mat.depth * cols)
    xml = _scene_xml(scene, sensor, azimuth_deg, reflectance)
    with atomic.atomic_path(out / "scene.xml") as tmp:
        Path(tmp).write_text(xml, encoding="utf-8")
    written.append(out / "scene.xml")
    return written


def _reflectance(scene: Scene, out: Path, written: list[Path]) -> str:
    """Return the diffuse BSDF's ``reflectance`` element; copies an albedo image beside the scene."""
    albedo = scene.material.albedo
    own = None
    if albedo is None and materials.is_builtin(scene.material.height):
        own = materials.generate(scene.material.height, scene.material.size).albedo
    if not isinstance(albedo, str) and own is None:
        a = DEFAULT_ALBEDO if albedo is None else float(albedo)
        return f'<rgb name="reflectance" value="{a:.9g}, {a:.9g}, {a:.9g}"/>'
    if own is not None:  # a built-in material's linear albedo, stored as sRGB as a bitmap expects
        rgb = codecs.unit_to_u8(srgb.encode(own))
    else:
        try:
            with Image.open(albedo) as img:
                rgb = np.asarray(img.convert("RGB"))
        except OSError as exc:
            raise InputError(albedo, f"not a readable albedo image ({errors.first_line(exc)})") from None
    codecs.write_png(out / "albedo.png", rgb)
    written.append(out / "albedo.png")
    return (
        '<texture type="bitmap" name="reflectance"><string name="filename" value="albedo.png"/>'
        '<string name="filter_type" value="nearest"/></texture>'
    )


def _v(*xs) -> str:
    return quoteattr(", ".join(f"{x:.9g}" for x in xs))


def _film(scene: Scene, width: int, height: int) -> str:
    return f"""<sampler type="independent">
            <integer name="sample_count" value="{int(scene.spp)}"/>
            <integer name="seed" value="{int(scene.seed)}"/>
        </sampler>
        <film type="hdrfilm">
            <integer name="width" value="{width}"/>
            <integer name="height" value="{height}"/>
            <string name="pixel_format" value="rgb"/>
            <rfilter type="box"/>
        </film>"""


def _top_sensor(scene: Scene, rows: int, cols: int, top: float) -> str:
    """Return the orthographic sensor straight down over the tile (module docstring)."""
    height, width = image_shape(rows, cols, scene.camera)
    cx, cy = cols / 2.0, rows / 2.0
    eye = top + 1.0 + 0.05 * max(rows, cols)
    return f"""<sensor type="orthographic">
        <transform name="to_world">
            <scale x="{cx:.9g}" y="{cy:.9g}"/>
            <lookat origin={_v(cx, cy, eye)} target={_v(cx, cy, 0.0)} up="0, 1, 0"/>
        </transform>
        <float name="near_clip" value="0.01"/>
        <float name="far_clip" value="{eye + 10.0 * max(rows, cols):.9g}"/>
        {_film(scene, width, height)}
    </sensor>"""


def _view_sensor(scene: Scene, view) -> str:
    """Return a perspective sensor at a model truth's view (:func:`hzval.truth.model.model_view`)."""
    eye, target = np.asarray(view.eye, float), np.asarray(view.target, float)
    far = 10.0 * float(np.linalg.norm(eye - target)) + 1.0
    return f"""<sensor type="perspective">
        <string name="fov_axis" value="x"/>
        <float name="fov" value="{view.fov_deg:.9g}"/>
        <transform name="to_world">
            <lookat origin={_v(*eye)} target={_v(*target)} up={_v(*view.up)}/>
        </transform>
        <float name="near_clip" value="{far * 1e-5:.9g}"/>
        <float name="far_clip" value="{far:.9g}"/>
        {_film(scene, int(view.resolution[0]), int(view.resolution[1]))}
    </sensor>"""


def _scene_xml(scene: Scene, sensor: str, azimuth_deg: float, reflectance: str) -> str:
    light = scene.light
    L = light.direction(azimuth_deg)
    on = "the tile" if scene.mesh.is_plane else f"{scene.mesh.shape}, world units, z up"
    return f"""<?xml version="1.0" encoding="utf-8"?>
<!-- hzval's ground truth for one light, as Mitsuba 3 renders it (hzval.commands.export_scene):
     {scene.name} on {on}, depth {scene.material.depth:g}, {scene.material.boundary}, \
{scene.material.shading} shading,
     light azimuth {azimuth_deg:g}, elevation {light.elevation_deg:g} degrees; tangent space in texels,
     +x right, +y up the image. Render: mitsuba scene.xml -o out.exr -->
<scene version="3.0.0">
    <integrator type="direct">
        <integer name="emitter_samples" value="1"/>
        <integer name="bsdf_samples" value="0"/>
    </integrator>
    {sensor}
    <emitter type="directional">
        <vector name="direction" value={_v(-L[0], -L[1], -L[2])}/>
        <rgb name="irradiance" value={_v(light.irradiance, light.irradiance, light.irradiance)}/>
    </emitter>
    <shape type="ply">
        <string name="filename" value="mesh.ply"/>
        <bsdf type="diffuse">
            {reflectance}
        </bsdf>
    </shape>
</scene>
"""


def _write_model(scene: Scene, height: np.ndarray, out: Path, azimuth_deg: float) -> list[Path]:
    """Write a model's export: ``base.glb``, ``mesh.ply`` and ``scene.xml``; return the paths.

    ``base.glb`` is the base mesh as hzval used it (its frames included: ``--tangents``), ``mesh.ply`` the
    displaced model the truth traces, and ``scene.xml`` is seen from the truth's camera. The displaced mesh
    carries no texture coordinates, so the diffuse reflectance is the albedo's mean.
    """
    backend.variant()
    scene = _direct_only(dataclasses.replace(scene, spp=1))
    base = model.load(
        scene.mesh.shape, uv_scale=scene.mesh.uv_scale, up=scene.mesh.up, tangents=scene.mesh.tangents
    )
    written = [out / "base.glb", out / "mesh.ply", out / "scene.xml"]
    gltf.write_glb(written[0], base.positions, base.normals, base.uvs, base.tangents, base.faces)
    h = np.asarray(height, np.float32)
    truth = ModelTruth(scene, h, base)
    mesh.write_ply(truth.displaced_mesh, written[1])
    a = np.mean(load_albedo(scene.material, *h.shape), axis=(0, 1))
    reflectance = f'<rgb name="reflectance" value={_v(*a)}/>'
    xml = _scene_xml(scene, _view_sensor(scene, truth.view), azimuth_deg, reflectance)
    with atomic.atomic_path(written[2]) as tmp:
        Path(tmp).write_text(xml, encoding="utf-8")
    return written


def mitsuba_render(path: str | Path, spp: int | None = None) -> np.ndarray:
    """Render an exported ``scene.xml`` with Mitsuba: ``(rows, cols, 3)`` float32 linear radiance."""
    backend.variant()

    scene = mi.load_file(str(path))
    return np.asarray(mi.render(scene, spp=spp or 0), dtype=np.float32)
