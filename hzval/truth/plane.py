"""The ground truth: Mitsuba 3 traces the displaced mesh, simulating only what the scene declares.

The design in full: docs/internals.md, "hzval.truth.plane".
"""

from __future__ import annotations

import math
import time

import numpy as np

from hzval.core import backend, resources, shading
from hzval.core import conventions as cv
from hzval.core.backend import dr, mi  # Dr.Jit loads at first use, once the LLVM is chosen
from hzval.core.conventions import normal_map
from hzval.core.errors import InputError
from hzval.geometry import tile as mesh
from hzval.scene.spec import EFFECTS, Frame, Scene, image_shape, light_samples
from hzval.truth import bands as truth_bands
from hzval.truth import common, rays
from hzval.truth import samples as truth_samples

__all__ = [
    "SIMULATES",
    "surface_margin",
    "mesh_grid",
    "mesh_triangles",
    "Truth",
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
    """Return the elevation, degrees, whose rays the wrap margin holds without a hop.

    It is the light's lowest direction (``lowest``) when shadow rays toward it are the only rays, else (rays
    in every direction: ambient, reflection, paths) :data:`hzval.geometry.tile.MIN_ELEVATION_DEG`; never lower
    than that. The bricks at 30 degrees on 2048 texels: a margin of 178 texels instead of 581, a mesh of
    2405^2 vertices instead of 3211^2 (the BVH's build time and memory with it).
    """
    everywhere = any(scene.declares(e) for e in ("ambient", "reflection_occlusion", "interreflection"))
    if everywhere:
        return mesh.MIN_ELEVATION_DEG
    return max(mesh.MIN_ELEVATION_DEG, lowest)


def surface_margin(scene: Scene, h_texels: np.ndarray) -> tuple[float, int]:
    """Return ``(min_elevation_deg, margin)`` of the truth's mesh of heights ``h_texels`` (texels).

    ``min_elevation_deg`` is the lowest elevation its rays are traced toward (the light's lowest direction, at
    most :data:`hzval.geometry.tile.MIN_ELEVATION_DEG`), ``margin`` its wrap margin in texels (0 for
    ``open``).
    """
    light = scene.light
    lowest = light.elevation_deg - (light.radius_deg if light.kind == "soft" else 0.0)
    min_elevation = min(mesh.MIN_ELEVATION_DEG, lowest) if lowest > 0 else mesh.MIN_ELEVATION_DEG
    if scene.material.boundary != "wrap":
        return min_elevation, 0
    # never wider than the margin for 10 degrees, nor than 32 texels: longer rays hop (see
    # "Boundaries"), while a margin for a grazing light or a deep relief would grow as
    # relief / tan(e), quadratically in memory
    return min_elevation, mesh.wrap_margin(h_texels, _margin_elevation_deg(scene, lowest), capped=True)


def mesh_grid(scene: Scene, height: np.ndarray):
    """Return the truth mesh's vertex grid and its cells' levels, without a triangle.

    The result is ``(grid, levels, h_texels)``: the vertex grid of the truth's mesh of the normalised
    ``height`` map for ``scene`` (margin and skirt included) and its cells' levels
    (:func:`hzval.geometry.tile.cell_levels` at ``material.truth_tolerance``), as :class:`Truth` makes them.
    """
    mat = scene.material
    h_tex = cv.heights_in_texels(np.asarray(height, np.float32), mat.depth)
    min_elevation, margin = surface_margin(scene, h_tex)
    g = mesh.grid(
        h_tex,
        mat.boundary,
        min_elevation_deg=min_elevation,
        margin=margin if mat.boundary == "wrap" else None,
    )
    tolerance = mesh.DEFAULT_TOLERANCE if mat.truth_tolerance is None else mat.truth_tolerance
    return g, mesh.cell_levels(g.z, tolerance), h_tex


def mesh_triangles(scene: Scene, height: np.ndarray) -> int:
    """Return the triangles of the truth's mesh, counted without building it.

    The mesh is of the normalised ``height`` map for ``scene``, margin and skirt included (:func:`mesh_grid`);
    the count is what :func:`hzval.truth.memory.estimate_peak_bytes` charges for the mesh.
    """
    return mesh.triangle_count(mesh_grid(scene, height)[1])


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
        self.keeps = truth_samples.keeps_samples(*self.shape, self.spp) if keep is None else bool(keep)
        self.bands = truth_samples.band_ranges(self.shape, self.spp, band_samples)
        self.mesh_bands, self._vis = None, {}
        if self.mesh_band_rows is not None:
            # the frames shade from each sample's visibility bit: nothing of the camera rays is kept
            self.keeps = False
            self.mesh_bands = truth_bands.group_bands(self.bands, self.shape[1], self.mesh_band_rows)
        self._trace_camera_rays()

    def _build_surface(self, h: np.ndarray) -> None:
        """Build the displaced mesh (with its wrap margin), the ray lift and the kernels' constants."""
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
            self.mesh = mesh.displaced_mesh(
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
            self._grid = mesh.grid(
                h_tex, mat.boundary, min_elevation_deg=self.min_elevation_deg, margin=margin
            )
            tolerance = mesh.DEFAULT_TOLERANCE if mat.truth_tolerance is None else float(mat.truth_tolerance)
            self._levels = mesh.cell_levels(self._grid.z, tolerance)
            info.update(levels=self._levels, tolerance=tolerance)
        # the finest sub-cell grid: every edge of the mesh is on one of its lines (samples.off_edge_lines)
        self.edge_level = mesh.edge_level(info["levels"])
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
        """Return the tests' own sample positions, flat float32, or ``None`` for the scene's."""
        if positions is None:
            return None
        xs, ys = (np.ascontiguousarray(p, dtype=np.float32).ravel() for p in positions)
        need = self.shape[0] * self.shape[1] * self.spp
        if xs.shape != (need,) or ys.shape != (need,):
            raise InputError(
                "positions", f"expected {need} samples (pixels x spp), got {xs.size} and {ys.size}"
            )
        return xs, ys

    def _trace_ambient(self, st: "truth_samples.Samples"):
        """Trace ``A`` per sample: a cosine-weighted direction escapes (independent of the light, once)."""
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

    def _trace_reflection(self, st: "truth_samples.Samples") -> tuple[np.ndarray, np.ndarray]:
        """Return ``R`` per pixel of the band ``st`` and its variance (flat).

        ``R`` is the share of the glossy lobe that escapes (independent of the light, once).

        Directions and weights: :func:`common.lobe_sample`; ``V`` = 1 where the
        direction escapes; ``R`` and its variance: :func:`common.reflection_estimate`
        (a model's truth, :mod:`hzval.truth.model`, calls the same two).
        """
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

    def light_directions(self, azimuth_deg: float, st: "truth_samples.Samples | None" = None):
        """Return ``(L, lowest, highest)``: the samples' light directions and the light's elevation bounds.

        ``L`` is the light direction of every sample of ``st`` (default: every sample, one band); ``lowest``
        and ``highest`` are the lowest and highest elevations of the light, radians.

        A hard light is one opaque vector for all samples (a new azimuth
        changes its value, not the kernel); a soft one an array from
        :func:`hzval.scene.spec.light_samples`, the approximation's directions. A soft light's bounds
        are its disk's (elevation -+ radius), the same in every band: the hops they ask for
        suffice for each of its directions.
        """
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
        self, st: "truth_samples.Samples", azimuth_deg: float
    ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Return pixel means and variances of the mean over the samples of the band ``st``.

        See :func:`common.mean_and_variance`. They are of ``visibility`` and ``ambient`` (the 0/1 samples) and
        ``image`` (the radiance; only where an effect shades), each a pair of flat float32 arrays ``(pixels[,
        3])``.
        """
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
