"""The ground truth: Mitsuba 3 traces the displaced mesh, simulating only what the scene declares.

Every number hzval reports is measured against this module, so it favours
being right over being fast. It builds the displaced mesh of
:mod:`hzval.geometry.tile` once - the bilinear height field of the texel centres,
tessellated with no preferred diagonal to within ``material.truth_tolerance``
texels (``--truth-tolerance``; docs/truth-surface.md), so that a turned map
is the turned surface - and loads it into a ``mi.Scene`` with nothing else
in it: no sensor, no emitter and no Mitsuba BSDF. What the technique
approximates is the *geometry* - who sees the light, who sees the sky - and
that is what Mitsuba answers here, with ``Scene.ray_intersect`` and
``Scene.ray_test`` on the true surface. The shading formulas are the ones
the techniques evaluate (:mod:`hzval.core.shading`; a Mitsuba BSDF would only be
a second place to define them, and one more way for the two sides to drift
apart), applied per sample at the point that was hit. For every light of
the sweep :meth:`Truth.render` returns a :class:`hzval.scene.spec.Frame`.

Shading (``[material] shading``)
    ``smooth`` (the default): the shading normal ``n_s`` is interpolated from
    vertex normals, as a displaced mesh is shaded, and the vertex normals
    are the normal map's own (:func:`hzval.core.conventions.normal_map`: the same
    central differences, one-sided at an ``open`` border). It is their
    bilinear interpolation at the sample's ``(x, y)``, the interpolation the
    techniques' texture filtering applies, so that where the light is seen
    the truth's shading *is* the techniques' and every remaining difference
    is the shadows (``tests/truth/test_plane_fidelity.py``). Mitsuba's own renderer
    interpolates vertex normals over each triangle instead
    (:mod:`hzval.commands.export_scene` writes them to the PLY); the two differ by a few
    thousandths of white on rough maps. ``faceted``: each triangle's own
    normal, as before (on a photographed map it put 67% of the image error
    into the shading). The geometric normal ``n`` still decides what faces
    away from the light, where rays start and which directions enter the
    surface.

Sampling
    The camera (:mod:`hzval.scene.camera`) gives the rays. The ``top`` view's run
    straight down (-z) through the positions of
    :func:`hzval.scene.camera.sample_positions`, the very points at which the
    techniques shade, so no error comes from sampling alone. Another view's
    rays are traced into the mesh (:meth:`Truth._view_hits`: ``wrap`` the
    endless tiling, in hops; ``open`` the tile alone), and each sample is
    then the surface point its ray hits, found again from above as a top-view
    sample is; a sample whose ray hits nothing counts for nothing, and a pixel
    none of whose samples hit is left out (``Frame.mask``). Camera rays are
    traced once, when the truth is built; only rays toward the light (and,
    for ``interreflection``, the paths) depend on the frame. Pixel values
    are the means of their ``spp`` samples, and every layer comes with the
    variance of that mean (sample variance / spp; NaN for spp = 1). For
    stratified positions it is an upper bound: the strata remove part of it.

Light
    ``L`` points toward the light (:mod:`hzval.core.conventions`). A ``soft``
    light gives every sample its own direction from
    :func:`hzval.scene.spec.light_samples` (uniform over the disk's solid angle),
    used for its shadow ray and its shading alike; ``irradiance`` E is the
    irradiance on a surface facing the light. A direction at or below the
    horizontal plane (``L.z <= 0``) is occluded: the material lies on that
    plane, which is the horizon of every point (the horizon bake never
    reports a horizon below 0 either, ``open`` included).

Effects (docs/ARCHITECTURE.md, "Effects"), per sample, then averaged per pixel:

``shadow``
    ``V`` = 1 if the ray toward ``L`` escapes, else 0: 0 also where the
    triangle hit faces away from the light (``n.L <= 0``), whose own surface
    blocks the ray. Shadow rays only.
``diffuse``
    ``albedo / pi * E * max(0, n_s.L)`` with the shading normal ``n_s`` and
    the linear albedo of the texel that holds the sample (nearest: the
    approximation reads the same texel). It equals Mitsuba's own ``diffuse``
    plugin evaluated at the same surface interactions and shading frame to
    1e-4 (``tests/truth/test_plane.py``). A ``soft`` light's sampled directions
    each carry ``2 E / (1 + cos rho)`` (:func:`hzval.core.shading.disk_sample_irradiance`),
    so that a surface facing the disk receives ``E``.
``specular``
    Blinn-Phong as in FGED2 chapter 7: ``ks * E * max(0, n_s.h)^alpha * [n_s.L > 0]``
    with ``h = normalize(L + v)`` and ``v`` toward the camera (``+z`` for
    ``top``; a perspective camera, whose ``v`` differs per pixel, is refused
    with it), ``ks`` = :data:`hzval.core.shading.SPECULAR_KS`, ``alpha`` =
    :data:`hzval.core.shading.SPECULAR_EXPONENT`.
``ambient``
    ``A`` = 1 if a cosine-weighted direction about ``n_s`` escapes (one into the
    triangle hit, ``n.d <= 0``, does not), else 0
    (``layers["ambient"]``, the exact cosine-weighted unoccluded fraction);
    the sky is uniform over the upper hemisphere with radiance
    ``sky = E *`` :data:`hzval.core.shading.SKY_RADIANCE_PER_IRRADIANCE` and a Lambertian surface
    reflects ``albedo * A * sky`` of it. ``A`` does not depend on the light:
    it is traced once.
``interreflection``
    A path tracer to Mitsuba's ``max_depth`` convention
    (:meth:`Truth._path_trace`); only then are paths traced.
``reflection_occlusion``
    ``R``, the share of a glossy reflection of a uniform environment that
    the displaced surface does not block (``layers["reflection_occlusion"]``).
    The lobe is the ``specular`` one, FGED2's Blinn-Phong of exponent
    :data:`hzval.core.shading.SPECULAR_EXPONENT` about ``n_s``, seen from ``v``
    (the camera's direction, as for ``specular``), sampled by its half-vector distribution
    (Walter et al. 2007), each direction weighted as that sampling requires (:meth:`Truth._trace_reflection`);
    a direction below the triangle hit (``n.wo <= 0``) or below the
    horizontal reflects nothing and counts as blocked. It is what the approximation's Toolbag fade ``o``
    estimates. Like ``A`` it does not depend on the light (traced once) and,
    as in the approximation, the scene has no environment map, so it is a
    layer of its own and leaves the image unchanged.

The direct term is ``D`` = diffuse + specular, or ``D = E`` (grey) when the
scene declares neither; the image is ``D * V`` (``D`` without ``shadow``),
plus ``albedo * A * sky`` when ``ambient`` is declared, all per sample.

Self-intersection
    A shadow ray spawned with Mitsuba's ``SurfaceInteraction3f.spawn_ray``
    starts a small distance along the normal of the triangle hit. At a mesh
    vertex (a texel centre) or near an edge in a valley, that point can lie
    *under* the neighbouring triangle, and the ray hits it: on a 64x64
    uniform-noise map with 4 texels of relief and the light at the zenith,
    where nothing can be occluded, 29.8% of rays from the vertices reported a
    hit (41% on a 512x512 noise map of 25.6 texels relief, and 1.1% of its
    jittered samples, whose offset, proportional to the coordinates, is
    0.045 texels there). The mesh is a height field, so a point raised
    *vertically* above the surface is above every triangle around it, and a
    ray toward any direction that one of them faces stays above: shadow rays
    start at the sample's exact ``(x, y)``, at the surface height plus
    :attr:`Truth.lift` (1.2e-4 texels for heights up to 32 texels; 1e-6 is
    too little for float32 heights of tens of texels, 1e-5 is enough). No
    false shadow remains (``tests/truth/test_plane.py``). The lift has one side
    effect, which a rule removes: on a triangle facing away from a light
    that grazes it, the lifted ray can run above the triangle's plane to its
    far edge and escape, so ``n.L <= 0`` counts as shadowed without a ray (on
    the bricks at 30 degrees that concerns about 1000 of 4.2M samples;
    with the rule the answer moves by 73 samples between lifts of 1e-5 and
    1.2e-4 texels: it has converged). Samples exactly on a line of mesh
    edges are moved a few ulps off it (:func:`off_edge_lines`): a ray
    running inside an edge can slip between its two triangles. Mitsuba's
    own offset, 0.045 texels at 500 texels from the origin, also leaks light
    where shadows begin: on the bricks at 30 degrees it lit 6,000 to 15,000
    of the 4.2M samples that are in shadow (0.15-0.35%, azimuths -60 to 45),
    and shadowed 40 to 360 that are lit.

Boundaries
    ``open``: nothing outside the image. ``wrap``: the mesh carries a margin
    of neighbouring tiles (:func:`hzval.geometry.tile.wrap_margin`) sized for the
    light's lowest direction when shadow rays are the only rays, for 10 degrees
    when rays leave in every direction (ambient, reflection, paths), never
    below 10 degrees, and at most :data:`hzval.geometry.tile.MIN_MARGIN_CAP` (32) texels wide: a margin
    for a grazing light or a deep relief grows as ``relief / tan(e)`` and the
    mesh with its square. Rays that need more - lights below
    10 degrees, ambient and path rays near the horizon, soft lights that dip
    low, any ray over a relief deeper than the margin holds - are traced in hops: a hop ends
    before the ray can leave the margin (as far as the mesh reaches from where it starts, the
    tile's width from most points), its end point is wrapped back into the tile, and the next hop
    continues from there, until the ray is above the highest point of the
    surface. So the surface tiles without end for every ray, not only within
    the margin.

Memory
    Camera rays are traced once, and every sample's hit (the origin's height,
    the normals: :data:`STATE_BYTES_PER_SAMPLE` bytes) is kept for the frames, up
    to :data:`KEEP_SAMPLES` samples, in bands of :data:`KEPT_BAND_SAMPLES`:
    the rays' own buffers (Embree's inputs and outputs, the shading's terms)
    are then a band's, reused from band to band, not the image's
    (docs/truth-surface.md, "Cost", has what that saves). A larger image is rendered in bands of
    whole pixel rows, :data:`BAND_SAMPLES` samples each, whose camera rays are traced
    again in every frame; only ``A`` is kept per band. Sample positions,
    random streams and light samples are indexed by the sample's place in
    the whole image, so a band gives bit for bit the pixels of one piece
    (``tests/truth/test_plane.py``).
    A mesh too large to hold beside the rest of a sweep (the 4096 bricks: 187M
    triangles) is built a band of rows at a time (``mesh_band_rows``,
    :mod:`hzval.truth.bands`, chosen by :func:`hzval.truth.memory.truth_plan`): each
    band's mesh holds the cells its samples' rays can reach, every light's
    shadow rays are traced in it when the truth is built, and the frames
    shade from one visibility bit a sample a light, bit for bit the single
    mesh's answers (``tests/truth/test_bands.py``).

Kernels
    Everything that changes between frames (the light direction) and every
    scene-dependent number enters the kernels as an opaque Dr.Jit variable
    (``dr.opaque``), so a new azimuth - or a new ``Truth`` of the same kind -
    reuses the compiled kernels (docs/ARCHITECTURE.md, "Known pitfalls"). Frames are timed
    with :func:`hzval.core.backend.sync`. Only ``mi.Float``, ``mi.Point3f`` and
    friends are used: ``llvm_ad_rgb`` and ``cuda_ad_rgb`` run the same code.

References: Mitsuba 3 documentation ("Scene.ray_test", "Scene.ray_intersect",
"SurfaceInteraction3f.spawn_ray", the ``path`` integrator's ``max_depth``);
Dr.Jit documentation ("dr.opaque", "dr.block_sum", "dr.gather"); Lengyel,
FGED2 chapter 7 (Blinn-Phong); Walter et al. 2007 (half-vector sampling).
"""

from __future__ import annotations

import math
import time

import numpy as np

from hzval.core import backend, resources, shading
from hzval.core import conventions as cv
from hzval.core.conventions import normal_map
from hzval.core.errors import InputError
from hzval.geometry import tile as meshes
from hzval.scene.spec import EFFECTS, Frame, Scene, image_shape, light_samples
from hzval.truth import bands as truth_bands
from hzval.truth import common, rays, samples

__all__ = [
    "SIMULATES",
    "surface_margin",
    "mesh_grid",
    "mesh_triangles",
    "Truth",
    "STATE_BYTES_PER_SAMPLE",
]
#: Effects that this truth simulates, in the order of ``hzval.scene.spec.EFFECTS``.
SIMULATES: tuple[str, ...] = (
    "shadow",
    "diffuse",
    "specular",
    "ambient",
    "reflection_occlusion",
    "interreflection",
)


def _margin_elevation_deg(scene: Scene, lowest: float) -> float:
    """The elevation, degrees, whose rays the wrap margin holds without a hop: the light's
    lowest direction (``lowest``) when shadow rays toward it are the only rays, else (rays
    in every direction: ambient, reflection, paths) :data:`hzval.geometry.tile.MIN_ELEVATION_DEG`;
    never lower than that. The bricks at 30 degrees on 2048 texels: a margin of 178 texels
    instead of 581, a mesh of 2405^2 vertices instead of 3211^2 (the BVH's build time and
    memory with it)."""
    everywhere = any(scene.declares(e) for e in ("ambient", "reflection_occlusion", "interreflection"))
    if everywhere:
        return meshes.MIN_ELEVATION_DEG
    return max(meshes.MIN_ELEVATION_DEG, lowest)


def surface_margin(scene: Scene, h_texels: np.ndarray) -> tuple[float, int]:
    """``(min_elevation_deg, margin)`` of the truth's mesh of heights ``h_texels`` (texels): the lowest
    elevation its rays are traced toward (the light's lowest direction, at most
    :data:`hzval.geometry.tile.MIN_ELEVATION_DEG`) and its wrap margin in texels (0 for ``open``)."""
    light = scene.light
    lowest = light.elevation_deg - (light.radius_deg if light.kind == "soft" else 0.0)
    min_elevation = min(meshes.MIN_ELEVATION_DEG, lowest) if lowest > 0 else meshes.MIN_ELEVATION_DEG
    if scene.material.boundary != "wrap":
        return min_elevation, 0
    # never wider than the margin for 10 degrees, nor than 32 texels: longer rays hop (see
    # "Boundaries"), while a margin for a grazing light or a deep relief would grow as
    # relief / tan(e), quadratically in memory
    return min_elevation, meshes.wrap_margin(h_texels, _margin_elevation_deg(scene, lowest), capped=True)


def mesh_grid(scene: Scene, height: np.ndarray):
    """``(grid, levels, h_texels)``: the vertex grid of the truth's mesh of the normalised ``height`` map
    for ``scene`` (margin and skirt included) and its cells' levels (:func:`hzval.geometry.tile.cell_levels`
    at
    ``material.truth_tolerance``), as :class:`Truth` makes them, without a triangle."""
    mat = scene.material
    h_tex = cv.heights_in_texels(np.asarray(height, np.float32), mat.depth)
    min_elevation, margin = surface_margin(scene, h_tex)
    g = meshes.grid(
        h_tex,
        mat.boundary,
        min_elevation_deg=min_elevation,
        margin=margin if mat.boundary == "wrap" else None,
    )
    tolerance = meshes.DEFAULT_TOLERANCE if mat.truth_tolerance is None else mat.truth_tolerance
    return g, meshes.cell_levels(g.z, tolerance), h_tex


def mesh_triangles(scene: Scene, height: np.ndarray) -> int:
    """Triangles of the truth's mesh of the normalised ``height`` map for ``scene``, margin and skirt
    included (:func:`mesh_grid`), counted without building it: what
    :func:`hzval.truth.memory.estimate_peak_bytes` charges for the mesh."""
    return meshes.triangle_count(mesh_grid(scene, height)[1])


class Truth(rays.CameraRays, rays.RayQueries, rays.PathTracing):
    """Ground-truth renderer of one scene and height map.

    ``height``: the normalised height map ``H[row, col]`` (float32); the
    scene's ``material`` gives depth and boundary. ``positions``: optional
    ``(x, y)`` sample positions in texel units replacing
    :func:`hzval.scene.camera.sample_positions` (same length and pixel-major order,
    ``pixels * spp``); tests use it to put samples exactly on mesh vertices.
    ``band_samples`` (samples per band) and ``keep`` (whether the camera hits
    are kept between frames) override :func:`samples.band_ranges` and :func:`samples.keeps_samples`
    (module docstring, "Memory"); tests use them to check that every way gives
    the same pixels.
    ``albedo``: optional linear ``(rows, cols, 3)`` albedo replacing
    :func:`hzval.scene.spec.load_albedo`; read only if an effect needs it.
    ``mesh_band_rows``: build the mesh in bands of at most this many pixel rows
    (:mod:`hzval.truth.bands`; whole sample bands, at least one) instead of at once; refused
    (``ValueError``) where a ray could leave a band (:func:`hzval.truth.bands.why_not`).

    Attributes: ``simulated`` (the effects simulated, for ``metrics.json``),
    ``shape`` (image rows, columns), ``margin`` (wrap margin, texels),
    ``lift`` (ray origin lift, texels), ``tolerance`` (texels: how far the mesh may be from the
    bilinear surface), ``edge_level`` (the finest sub-cell grid, :func:`hzval.geometry.tile.edge_level`),
    ``moved_off_edges`` (samples moved
    off a line of mesh edges, :func:`samples.off_edge_lines`), ``timings``
    (seconds: ``mesh_s``, of it ``bvh_s`` for the ray-tracing scene, ``primary_s``,
    ``ambient_s``), ``view`` (the placed
    camera, :class:`hzval.scene.camera.View`). A view other than ``top`` also sets
    ``seen`` (``(H, W)`` bool: pixels whose rays hit the surface) and, when one
    band holds the image, ``hits`` (float32 ``(x, y)`` of each sample's hit,
    in the tile) and ``seen_samples`` (which samples' rays hit).
    """

    def __init__(
        self,
        scene: Scene,
        height: np.ndarray,
        *,
        positions: tuple | None = None,
        albedo: np.ndarray | None = None,
        band_samples: int | None = None,
        keep: bool | None = None,
        mesh_band_rows: int | None = None,
    ):
        backend.variant()
        self.scene = scene.validate()
        self.built_elevation_deg = float(self.scene.light.elevation_deg)  # the lowest of a sweep's
        h = np.asarray(height, dtype=np.float32)
        if h.ndim != 2 or h.size < 2 or not np.all(np.isfinite(h)):
            # any size the loader and the bake take (1xN and Nx1 included): the mesh handles them
            raise InputError(
                "height", f"expected a finite 2-D height map of at least 2 pixels, got shape {h.shape}"
            )
        self.rows, self.cols = rows, cols = h.shape
        self.shape = image_shape(rows, cols, scene.camera)
        self.spp = scene.spp
        if scene.declares("interreflection") and not (
            scene.declares("diffuse") or scene.declares("specular")
        ):
            raise InputError(
                scene.source or "scene",
                "interreflection needs a surface that reflects: declare diffuse and/or specular as well",
            )
        self.simulated = tuple(e for e in EFFECTS if e in scene.effects and e in SIMULATES)
        self.timings: dict[str, float] = {}
        self.mesh_band_rows = None if mesh_band_rows is None else max(1, int(mesh_band_rows))
        if self.mesh_band_rows is not None and truth_bands.why_not(scene) is not None:
            raise ValueError(f"the truth's mesh cannot be built in bands: {truth_bands.why_not(scene)}")

        self._build_surface(h)
        self.view = scene.camera.view(rows, cols, (self.z_min, self.z_max))
        self._albedo_texels = common.albedo_texels(scene, rows, cols, albedo)
        self._positions = self._check_positions(positions)
        self.count = self.shape[0] * self.shape[1] * self.spp
        self.keeps = samples.keeps_samples(*self.shape, self.spp) if keep is None else bool(keep)
        self.bands = samples.band_ranges(self.shape, self.spp, band_samples)
        self.mesh_bands, self._vis = None, {}
        if self.mesh_band_rows is not None:
            # the frames shade from each sample's visibility bit: nothing of the camera rays is kept
            self.keeps = False
            self.mesh_bands = truth_bands.group_bands(self.bands, self.shape[1], self.mesh_band_rows)
        self._trace_camera_rays()

    def _build_surface(self, h: np.ndarray) -> None:
        """The displaced mesh (with its wrap margin), the ray lift and the kernels' constants."""
        import drjit as dr
        import mitsuba as mi

        rows, cols = self.rows, self.cols
        mat, light = self.scene.material, self.scene.light
        t0 = time.perf_counter()
        h_tex = cv.heights_in_texels(h, mat.depth)
        self.z_min, self.z_max = float(h_tex.min()), float(h_tex.max())
        self.relief = self.z_max - self.z_min
        self.min_elevation_deg, self.margin = surface_margin(self.scene, h_tex)
        info: dict = {}
        margin = self.margin if mat.boundary == "wrap" else None
        if self.mesh_band_rows is None:
            self.mesh = meshes.displaced_mesh(
                h,
                mat.depth,
                mat.boundary,
                min_elevation_deg=self.min_elevation_deg,
                texcoords=False,
                tolerance=mat.truth_tolerance,
                info=info,
                budget_bytes=resources.available_bytes(),
                margin=margin,
            )
        else:
            # in bands (hzval.truth.bands): the whole grid and its levels, as displaced_mesh makes them
            self.mesh = None
            self._grid = meshes.grid(
                h_tex, mat.boundary, min_elevation_deg=self.min_elevation_deg, margin=margin
            )
            tolerance = (
                meshes.DEFAULT_TOLERANCE if mat.truth_tolerance is None else float(mat.truth_tolerance)
            )
            self._levels = meshes.cell_levels(self._grid.z, tolerance)
            info.update(levels=self._levels, tolerance=tolerance)
        # the finest sub-cell grid: every edge of the mesh is on one of its lines (samples.off_edge_lines)
        self.edge_level = meshes.edge_level(info["levels"])
        self.tolerance = info["tolerance"]
        del info
        self._normals = None
        if mat.shading == "smooth":
            # the vertex normals, bilinearly between texel centres (module docstring, "Shading")
            wrap = dr.WrapMode.Repeat if mat.boundary == "wrap" else dr.WrapMode.Clamp
            self._normals = mi.Texture2f(
                mi.TensorXf(np.ascontiguousarray(normal_map(h_tex, mat.boundary))),
                use_accel=False,
                migrate=False,
                filter_mode=dr.FilterMode.Linear,
                wrap_mode=wrap,
            )
        self.mi_scene = None
        if self.mesh is not None:  # in bands, each band builds its own (hzval.truth.bands)
            backend.sync()
            t1 = time.perf_counter()
            self.mi_scene = mi.load_dict({"type": "scene", "surface": self.mesh})
            backend.sync()
            self.timings["bvh_s"] = time.perf_counter() - t1  # the scene: Embree's BVH, or OptiX's
        self.lift = common.lift_for(self.z_min, self.z_max)
        # a hop runs at least this far horizontally from any point of the tile and stays over the
        # margin (texel centres start half a texel inside; a quarter texel kept, _hop_length)
        self._hop = max(self.margin - 0.75, 0.25)
        # toward the camera: the top view's +z, an orthographic camera's direction (a perspective
        # one's differs per pixel: the effects that read it are refused with it, hzval.scene.spec)
        self._toward_eye = mi.Vector3f(*(self.scene.camera.toward_eye() or (0.0, 0.0, 1.0)))
        self._c = {  # scene-dependent numbers, opaque so that kernels are shared
            "rows": dr.opaque(mi.Float, float(rows)),
            "cols": dr.opaque(mi.Float, float(cols)),
            "edge": dr.opaque(mi.Float, self._hop),
            "top": dr.opaque(mi.Float, self.z_max + 2 * self.lift),
            "lift": dr.opaque(mi.Float, self.lift),
            "probe": dr.opaque(mi.Float, self.z_max + 1.0),
            # irradiance of each sampled light direction (shading, "Soft light"), and the sky's
            "E": dr.opaque(
                mi.Float,
                shading.disk_sample_irradiance(light.irradiance, light.radius_deg)
                if light.kind == "soft"
                else float(light.irradiance),
            ),
            "E_sky": dr.opaque(mi.Float, float(light.irradiance)),
        }
        backend.sync()
        self.timings["mesh_s"] = time.perf_counter() - t0

    def _check_positions(self, positions):
        """The tests' own sample positions, flat float32, or ``None`` for the scene's."""
        if positions is None:
            return None
        xs, ys = (np.ascontiguousarray(p, dtype=np.float32).ravel() for p in positions)
        need = self.shape[0] * self.shape[1] * self.spp
        if xs.shape != (need,) or ys.shape != (need,):
            raise InputError(
                "positions", f"expected {need} samples (pixels x spp), got {xs.size} and {ys.size}"
            )
        return xs, ys

    def _trace_ambient(self, st: "samples.Samples"):
        """``A`` per sample: a cosine-weighted direction escapes (independent of the light, once)."""
        import drjit as dr
        import mitsuba as mi

        t0 = time.perf_counter()
        rng = self._rng(common.AMBIENT_STREAM, st)
        # cosine-weighted about the shading normal; a direction into the triangle hit is blocked
        d = mi.Frame3f(st.ns).to_world(
            mi.warp.square_to_cosine_hemisphere(mi.Point2f(rng.next_float32(), rng.next_float32()))
        )
        blocked = (dr.dot(st.n, d) <= 0.0) | self._occluded(
            st.o, d, self._hops_for(math.radians(rays.MIN_TRACED_ELEVATION_DEG)), dynamic=True
        )
        ambient = dr.select(blocked, 0.0, 1.0)
        dr.eval(ambient)
        backend.sync()
        self.timings["ambient_s"] += time.perf_counter() - t0
        return ambient

    def _trace_reflection(self, st: "samples.Samples") -> tuple[np.ndarray, np.ndarray]:
        """``R`` per pixel of the band ``st`` and its variance (flat): the share of the glossy lobe that
        escapes
        (independent of the light, once).

        Directions and weights: :func:`common.lobe_sample`; ``V`` = 1 where the
        direction escapes; ``R`` and its variance: :func:`common.reflection_estimate`
        (a model's truth, :mod:`hzval.truth.model`, calls the same two).
        """
        import drjit as dr
        import mitsuba as mi

        t0 = time.perf_counter()
        rng = self._rng(common.REFLECTION_STREAM, st)
        wo, w = common.lobe_sample(
            st.ns, self._toward_eye, mi.Point2f(rng.next_float32(), rng.next_float32())
        )
        blocked = (dr.dot(st.n, wo) <= 0.0) | self._occluded(
            st.o, wo, self._hops_for(math.radians(rays.MIN_TRACED_ELEVATION_DEG)), dynamic=True
        )
        out = common.reflection_estimate(w, dr.select(blocked, 0.0, 1.0), self.spp)
        self.timings["reflection_s"] += time.perf_counter() - t0
        return out

    # ------------------------------------------------------------------
    # Frames
    # ------------------------------------------------------------------

    def light_directions(self, azimuth_deg: float, st: "samples.Samples | None" = None):
        """``(L, lowest, highest)``: the light direction of every sample of ``st`` (default: every
        sample, one band), and the lowest and highest elevations of the light, radians.

        A hard light is one opaque vector for all samples (a new azimuth
        changes its value, not the kernel); a soft one an array from
        :func:`hzval.scene.spec.light_samples`, the approximation's directions. A soft light's bounds
        are its disk's (elevation -+ radius), the same in every band: the hops they ask for
        suffice for each of its directions.
        """
        import drjit as dr
        import mitsuba as mi

        light = self.scene.light
        if light.kind == "hard":
            v = light.direction(azimuth_deg)
            L = mi.Vector3f(*(dr.opaque(mi.Float, float(c)) for c in v))
            e = math.asin(max(-1.0, min(1.0, float(v[2]))))
            return L, e, e
        first, count = (0, self.count) if st is None else (st.start, st.count)
        s = np.ascontiguousarray(
            light_samples(light, azimuth_deg, self.count, self.scene.seed, samples=(first, first + count)),
            dtype=np.float32,
        )
        # a gather, not three column arrays: Dr.Jit maps NumPy memory as it
        # is, and a contiguous load would compile one kernel per alignment
        L = dr.gather(mi.Vector3f, mi.Float(s.ravel()), dr.arange(mi.UInt32, count))
        e, rho = math.radians(light.elevation_deg), math.radians(light.radius_deg)
        return L, e - rho, e + rho

    def _visible(self, o, n, L, lowest: float, highest: float):
        """1 where the light direction ``L`` escapes from ``o`` on a triangle of normal ``n``, else 0.

        A triangle that faces away from the light (``n.L <= 0``) shadows its
        own points: the ray enters the surface at once. That is decided
        here, not by the ray, whose lifted origin could otherwise slip over
        the triangle's far edge when the light grazes it (module docstring).
        Frames whose every direction is below the horizon trace nothing;
        lights that reach below the margin's elevation take the hops they
        need, stopping early once every ray is resolved.
        """
        import drjit as dr
        import mitsuba as mi

        if highest <= 0.0:
            return dr.zeros(mi.Float, dr.width(o))
        hops = self._hops_for(lowest)
        facing_away = dr.dot(n, L) <= 0.0
        blocked = self._occluded(o, L, hops, dynamic=hops > 2, coherent=True, skip=facing_away) | facing_away
        return dr.select(blocked, 0.0, 1.0)

    def _direct(self, n, L, v, albedo):
        """Direct radiance per unit visibility: ``D`` of :mod:`hzval.core.shading`."""
        sc = self.scene
        return shading.direct(
            n, L, v, albedo, self._c["E"], diffuse=sc.declares("diffuse"), specular=sc.declares("specular")
        )

    def light_at(self, elevation_deg: float) -> None:
        """Light the frames that follow from ``elevation_deg`` (:func:`hzval.truth.common.relight`)."""
        if (
            common.relight(self, elevation_deg)
            and self.mesh_bands is not None
            and self.scene.declares("shadow")
        ):
            # a mesh built in bands traced every light's shadow rays at once, for one elevation: trace
            # this one's (one elevation's bits at a time, as the memory plan counts them)
            self._vis = truth_bands.band_pass(self, self.scene.light.azimuths_deg)

    def render(self, azimuth_deg: float) -> Frame:
        """Render the light at ``azimuth_deg`` (degrees; elevation from the scene).

        Returns a :class:`hzval.scene.spec.Frame`: ``image`` (rows, cols, 3) linear
        radiance; ``layers["visibility"]`` (with ``shadow``) and
        ``layers["ambient"]`` (with ``ambient``) in [0, 1]; ``variance`` of the
        pixel mean for each (sample variance / spp; NaN when spp = 1; for
        stratified positions an upper bound); ``seconds`` the wall time of
        this call, kernels synchronised. Band by band where there are several, the same values.
        """
        t0 = time.perf_counter()
        sc = self.scene
        H, W = self.shape
        layers, variance = {}, {}

        def place(key, rows, mean, var):
            # each band's means and variances go straight into the float32 results: no image-sized
            # float64 sums (a GB at 4096 x 4096)
            for out, part in ((layers, mean), (variance, var)):
                if key not in out:
                    out[key] = np.empty((H, W) + part.shape[1:], np.float32)
                out[key][rows] = part.reshape((-1, W) + part.shape[1:])

        for st in self._frame_samples():
            rows = slice(st.first // W, st.stop // W)
            for k, (mean, var) in self._render_band(st, azimuth_deg).items():
                place(k, rows, mean, var)
        image = layers.pop("image", None)
        if image is not None:
            variance["image"] = variance.pop("image")
        if self._reflection is not None:
            layers["reflection_occlusion"], variance["reflection_occlusion"] = self._reflection
        if image is None:
            E = float(sc.light.irradiance)
            v = layers["visibility"] if "visibility" in layers else np.ones((H, W), np.float32)
            var = variance["visibility"] if "visibility" in layers else np.zeros((H, W), np.float32)
            image = np.repeat((E * v)[..., None], 3, axis=-1).astype(np.float32)
            variance["image"] = np.repeat((E * E * var)[..., None], 3, axis=-1).astype(np.float32)
        seconds = time.perf_counter() - t0
        return Frame(
            azimuth_deg=float(azimuth_deg),
            elevation_deg=float(sc.light.elevation_deg),
            image=image,
            layers=layers,
            variance=variance,
            seconds=seconds,
            mask=self.seen,
        )

    def _render_band(
        self, st: "samples.Samples", azimuth_deg: float
    ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Pixel means and variances of the mean (:func:`common.mean_and_variance`) over the samples of the
        band ``st``: ``visibility`` and ``ambient`` (the 0/1 samples) and ``image`` (the radiance;
        only where an effect shades), each a pair of flat float32 arrays ``(pixels[, 3])``."""
        import drjit as dr
        import mitsuba as mi

        sc = self.scene
        L, lowest, highest = self.light_directions(azimuth_deg, st)
        sums: dict[str, object] = {}
        vis = None
        if sc.declares("shadow"):
            vis = (
                self._visible(st.o, st.n, L, lowest, highest)
                if self.mesh_bands is None
                else self._band_visibility(azimuth_deg, st)
            )
            sums["visibility"] = vis
        grey = not any(sc.declares(e) for e in ("diffuse", "specular", "ambient", "interreflection"))
        if grey:
            img = None  # E * V or E: derived from the layers
        elif sc.declares("interreflection"):
            img = self._path_trace(st, L, vis, azimuth_deg)
        else:
            img = self._direct(st.ns, L, self._toward_eye, st.albedo)
            if vis is not None:
                img = img * vis
            if st.ambient is not None:
                img = img + shading.sky(st.albedo, st.ambient, self._c["E_sky"])
        if st.ambient is not None:
            sums["ambient"] = st.ambient

        spp = self.spp
        if st.seen is not None:
            # a sample whose ray sees no surface counts for nothing: pixel means are over the others
            sums = {k: dr.select(st.seen, v, 0.0) for k, v in sums.items()}
            sums["seen"] = dr.select(st.seen, 1.0, 0.0)
            if img is not None:
                img = dr.select(st.seen, img, 0.0)
        reduced = {k: dr.block_sum(v, spp) for k, v in sums.items()}
        if img is not None:
            # two passes: squared deviations from the pixel mean, not E[x^2] - E[x]^2,
            # which cancels catastrophically in float32 where the image hardly varies
            img_sum = dr.block_sum(img, spp)
            pixel = dr.arange(mi.UInt32, st.count) // spp
            if st.seen is None:
                dev = img - dr.gather(mi.Color3f, img_sum, pixel) * (1.0 / spp)
            else:
                n = dr.maximum(dr.gather(mi.Float, reduced["seen"], pixel), 1.0)
                dev = dr.select(st.seen, img - dr.gather(mi.Color3f, img_sum, pixel) / n, 0.0)
            reduced["image"], reduced["image_ss"] = img_sum, dr.block_sum(dev * dev, spp)
        dr.eval(reduced)
        n = reduced.pop("seen", spp)  # samples per pixel that see the surface
        stats = {}
        for k in ("visibility", "ambient"):
            if k in reduced:
                # 0/1 samples: the squared deviations sum to s (1 - s / n)
                s1 = mi.Float64(reduced[k])
                nn = n if isinstance(n, int) else dr.maximum(mi.Float64(n), 1.0)
                stats[k] = common.mean_and_variance(s1, s1 * (1.0 - s1 / nn), n)
        if "image" in reduced:
            stats["image"] = tuple(
                zip(
                    *(
                        common.mean_and_variance(mi.Float64(c), mi.Float64(q), n)
                        for c, q in zip(reduced["image"], reduced["image_ss"])
                    )
                )
            )
        dr.eval(stats)
        backend.sync()
        out = {}
        for k, (mean, var) in stats.items():
            if k == "image":
                out[k] = tuple(
                    np.stack([np.asarray(c, dtype=np.float32) for c in v], axis=-1) for v in (mean, var)
                )
            else:
                out[k] = (np.asarray(mean, dtype=np.float32), np.asarray(var, dtype=np.float32))
        return out


#: Bytes per sample of that state: the lifted origin's height (its x and y are the sample positions
#: themselves), the geometric and shading normals and ``A`` (8 float32; the albedo is gathered
#: again by each frame's kernel; ``memory.estimate_peak_bytes`` counts the state).
STATE_BYTES_PER_SAMPLE = 32
