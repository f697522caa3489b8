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
    (:mod:`hzval.commands.export` writes them to the PLY); the two differ by a few
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
    edges are moved a few ulps off it (:func:`_off_edge_lines`): a ray
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
    mesh with its square (the bricks at 1 degree: 2.4 GB; a 512 x 512 photo at
    depth 5: 30,000 x 30,000 vertices). Rays that need more - lights below
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
    are then a band's, reused from band to band, not the image's (at 2048 x
    2048 and 16 spp: a peak 1.7 GB lower, and 4-5 s less in a sweep of five
    lights, most of it the kernel's zeroing of pages new to the process). A larger image (4096 x
    4096 at 16 spp: 268M samples, 14 GB of such state) is rendered in bands of whole pixel
    rows, :data:`BAND_SAMPLES` samples each, whose camera rays are traced
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

import dataclasses
import math
import time

import numpy as np

from hzval.core import backend, resources, shading
from hzval.core import conventions as cv
from hzval.core.conventions import normal_map
from hzval.core.errors import InputError
from hzval.core.shading import SKY_RADIANCE_PER_IRRADIANCE, SPECULAR_EXPONENT, SPECULAR_KS
from hzval.geometry import tile as meshes
from hzval.scene.camera import sample_positions
from hzval.scene.spec import EFFECTS, Frame, Scene, image_shape, light_samples, load_albedo
from hzval.truth import bands as truth_bands

__all__ = [
    "LIFT_TEXELS",
    "LIFT_PER_HEIGHT",
    "MIN_TRACED_ELEVATION_DEG",
    "SIMULATES",
    "surface_margin",
    "mesh_grid",
    "mesh_triangles",
    "lift_for",
    "Truth",
    "KEEP_SAMPLES",
    "BAND_SAMPLES",
    "KEPT_BAND_SAMPLES",
    "STATE_BYTES_PER_SAMPLE",
    "bands",
    "keeps_samples",
    "stream_rng",
    "lobe_sample",
    "reflection_estimate",
]

#: Smallest lift of ray origins above the surface, in texels.
LIFT_TEXELS = 2.0**-13
#: Lift per texel of height magnitude: 32 float32 ulps of the heights.
LIFT_PER_HEIGHT = 2.0**-18
#: How far inside an ``open`` tile's border its height is probed, texels.
_EDGE = 2.0**-10
#: Rays lower than this above the horizontal (ambient and path rays, soft
#: lights reaching the horizon; ``wrap`` only) are not traced in more hops
#: than it takes to clear the surface at this elevation; the few still below
#: the surface's top after that count as occluded. The cosine-weighted share
#: of such directions is about sin^2 of it (2e-5).
MIN_TRACED_ELEVATION_DEG = 0.25

#: Effects that this truth simulates, in the order of ``hzval.scene.spec.EFFECTS``.
SIMULATES: tuple[str, ...] = (
    "shadow",
    "diffuse",
    "specular",
    "ambient",
    "reflection_occlusion",
    "interreflection",
)
#: Random stream of the ambient directions; the path tracer's first bounce
#: reuses it, so that its cosine-weighted directions are the ambient layer's.
_AMBIENT_STREAM = 0xA3B1
REFLECTION_STREAM = 0x5EF1
#: Declared effects that need the material's albedo.
_NEEDS_ALBEDO = ("diffuse", "ambient", "interreflection")


class _CameraRays:
    """The truth's camera rays (a part of :class:`Truth`): where each sample of the view meets the
    displaced mesh, kept between frames or traced again band by band (module docstring, "Memory"),
    with the albedo and shading normal there."""

    def _trace_camera_rays(self) -> None:
        """Where every sample's camera ray meets the surface, once, and what does not depend on the
        light (``A``, ``R``). One band keeps its samples (:class:`_Samples`) for every frame; with
        more (module docstring, "Memory") only ``A`` is kept, per band, and the reflection layer."""
        t0 = time.perf_counter()
        self.moved_off_edges, self._kept, self._ambient_bands = 0, None, []
        self.seen, self.hits = None, None
        if self.scene.camera.kind != "top":
            self._trace_view()
        ambient, reflects = self.scene.declares("ambient"), self.scene.declares("reflection_occlusion")
        self.timings["primary_s"] = 0.0
        if ambient:
            self.timings["ambient_s"] = 0.0
        if reflects:
            self.timings["reflection_s"] = 0.0
        reflection = []
        kept = []
        for first, stop in self.bands:
            if not self.keeps and not (ambient or reflects):
                # nothing to keep from a band's rays: each frame traces them again; count the
                # samples moved off edge lines only (positions, no rays: 40 s less at 4096)
                self.moved_off_edges += _off_edge_lines(
                    *self._band_positions(first, stop)[:2], self.rows, self.cols, self.edge_level
                )[2]
                continue
            st = self._camera_samples(first, stop)
            self.moved_off_edges += st.moved
            if ambient:
                st.ambient = self._trace_ambient(st)
                self._ambient_bands.append(st.ambient)
            if reflects:
                reflection.append(self._trace_reflection(st))
            if self.keeps:
                kept.append(st)
        self._kept = kept if self.keeps else None
        self._reflection = None
        if reflection:
            self._reflection = tuple(np.concatenate(parts).reshape(self.shape) for parts in zip(*reflection))
        self.timings["primary_s"] = (
            time.perf_counter()
            - t0
            - self.timings.get("ambient_s", 0.0)
            - self.timings.get("reflection_s", 0.0)
        )
        if self.mesh_bands is not None and self.scene.declares("shadow"):
            # the mesh a band at a time: every light's shadow rays now, before the techniques are built
            t0 = time.perf_counter()
            self._vis = truth_bands.band_pass(self, self.scene.light.azimuths_deg)
            self.timings["bands_s"] = time.perf_counter() - t0

    def _camera_samples(self, first: int, stop: int) -> "_Samples":
        """The samples of the pixels ``first <= p < stop``: where their camera rays meet the surface
        (lifted origin, geometric and shading normal) and the albedo of the texel that holds each
        (an expression over the positions: the kernels that read it gather it)."""
        import drjit as dr
        import mitsuba as mi

        rows, cols, spp = self.rows, self.cols, self.spp
        xs, ys, seen = self._band_positions(first, stop)
        xs, ys, moved = _off_edge_lines(xs, ys, rows, cols, self.edge_level)
        x, y = mi.Float(xs), mi.Float(ys)
        del xs, ys
        o, n, ns, valid = self._surface_at(x, y, coherent=True)
        # the albedo stays an expression, a gather from the texels that each frame's kernel makes
        # again: 12 bytes a sample less to keep (0.8 GB at 2048 x 2048 x 16), the same values
        albedo = self._albedo_at(x, y) if self._albedo_texels is not None else None
        dr.eval(o, n, ns, valid)
        if not bool(dr.all(valid)):
            raise RuntimeError("truth: a camera ray missed the displaced mesh (a sample outside the tile?)")
        backend.sync()
        return _Samples(
            first,
            stop,
            first * spp,
            (stop - first) * spp,
            o,
            n,
            ns,
            albedo,
            moved,
            seen=None if seen is None else mi.Bool(seen),
        )

    def _albedo_at(self, x, y, active=True):
        """The linear albedo of the texel that holds ``(x, y)`` (nearest, as the techniques read it)."""
        import drjit as dr
        import mitsuba as mi

        # column floor(x), row floor(rows - y) = rows - ceil(y), exact in float32 (rows - y itself
        # would round); opaque sizes: one kernel for every map
        c = self._c
        n_cols, n_rows = mi.Int32(c["cols"]), mi.Int32(c["rows"])
        col = dr.clip(mi.Int32(dr.floor(x)), 0, n_cols - 1)
        row = dr.clip(mi.Int32(c["rows"] - dr.ceil(y)), 0, n_rows - 1)
        return dr.gather(mi.Color3f, self._albedo_texels, mi.UInt32(row * n_cols + col), active)

    def _band_positions(self, first: int, stop: int):
        """``(x, y, seen)`` of the samples of the pixels ``first <= p < stop``: the scene's top-view
        positions or the tests' (``seen`` None: all), or where the camera's rays meet the surface
        (``seen``: which do; the others are put on the tile, and count for nothing)."""
        scene, spp = self.scene, self.spp
        if self.hits is not None:
            a, b = first * spp, stop * spp
            return self.hits[0][a:b], self.hits[1][a:b], self.seen_samples[a:b]
        if scene.camera.kind != "top":
            return self._view_hits(first, stop)
        if self._positions is None and not self.keeps:
            return (
                *sample_positions(self.rows, self.cols, scene.camera, spp, scene.seed, pixels=(first, stop)),
                None,
            )
        if self._positions is None:
            # the whole image's positions, made once and shared with the techniques (hzval.scene.spec)
            whole = sample_positions(self.rows, self.cols, scene.camera, spp, scene.seed)
            return (*(p[first * spp : stop * spp] for p in whole), None)
        return (*(p[first * spp : stop * spp] for p in self._positions), None)

    def _trace_view(self) -> None:
        """Trace every camera ray once (a view other than ``top``): :attr:`seen`, the pixels whose
        rays meet the surface, and, when the truth keeps its samples (:attr:`keeps`), :attr:`hits`
        (float32 ``(x, y)`` of each sample's surface point, in the tile), which the frames reuse."""
        H, W = self.shape
        seen_px, hx, hy, hs = [], [], [], []
        for first, stop in self.bands:
            xs, ys, seen = self._view_hits(first, stop)
            seen_px.append(seen.reshape(-1, self.spp).any(axis=1))
            if self.keeps:
                hx.append(xs), hy.append(ys), hs.append(seen)
        self.seen = np.concatenate(seen_px).reshape(H, W)
        if self.keeps:
            one = len(hx) == 1  # one band: its arrays as they are, no copy
            self.hits = (hx[0], hy[0]) if one else (np.concatenate(hx), np.concatenate(hy))
            self.seen_samples = hs[0] if one else np.concatenate(hs)

    def _view_hits(self, first: int, stop: int):
        """Where the camera rays of the pixels ``first <= p < stop`` meet the surface: float32 ``x, y``
        in the tile (``wrap``: the endless tiling, in hops; ``open``: the tile alone) and which rays
        do. A ray first runs in float64, on the host, to just above the highest point (wrapped into
        the tile), so that the float32 rays start near the surface whatever the eye's distance."""
        import drjit as dr
        import mitsuba as mi

        o, d = self.view.rays(self.spp, self.scene.seed, first, stop)
        down = d[:, 2] < 0.0
        top = self.z_max + 4.0 * self.lift + 1e-3
        t0 = np.where(down & (o[:, 2] > top), (top - o[:, 2]) / np.where(down, d[:, 2], -1.0), 0.0)
        o = o + t0[:, None] * d
        wrap = self.scene.material.boundary == "wrap"
        if wrap:
            o[:, 0] %= self.cols
            o[:, 1] %= self.rows
        lowest = float(np.min(-d[down, 2])) if down.any() else 1.0
        hops = self._hops_for(math.asin(min(1.0, lowest))) + 1 if wrap else 1
        O = mi.Point3f(*(mi.Float(o[:, k].astype(np.float32)) for k in range(3)))
        D = mi.Vector3f(*(mi.Float(d[:, k].astype(np.float32)) for k in range(3)))
        del o, d
        x, y, hit, _ = self._next_surface(O, D, mi.Bool(down), hops)
        dr.eval(x, y, hit)
        seen = np.asarray(hit, bool)
        xs, ys = np.asarray(x, np.float32).copy(), np.asarray(y, np.float32).copy()
        # the rays that see nothing are put at a point of the tile: traced, and counted for nothing
        xs[~seen], ys[~seen] = np.float32(self.cols * 0.5 + 0.25), np.float32(self.rows * 0.5 + 0.25)
        if not wrap:
            xs, ys = np.clip(xs, 0.0, self.cols), np.clip(ys, 0.0, self.rows)
        return xs, ys, seen

    def _shading_samples(self, first: int, stop: int) -> "_Samples":
        """The samples of the pixels ``first <= p < stop`` of a truth whose mesh is in bands: their
        shading normals and albedo, which need no mesh (``o`` and ``n`` unset: their visibility is
        :meth:`_band_visibility`'s)."""
        import mitsuba as mi

        xs, ys, _ = self._band_positions(first, stop)
        xs, ys, moved = _off_edge_lines(xs, ys, self.rows, self.cols, self.edge_level)
        x, y = mi.Float(xs), mi.Float(ys)
        albedo = self._albedo_at(x, y) if self._albedo_texels is not None else None
        return _Samples(
            first,
            stop,
            first * self.spp,
            (stop - first) * self.spp,
            None,
            None,
            self._shading_normal(x, y),
            albedo,
            moved,
        )

    def _band_visibility(self, azimuth_deg: float, st: "_Samples"):
        """``V`` per sample of ``st`` from the bits of :func:`hzval.truth.bands.band_pass` (a light not
        of the scene's sweep gets its own pass)."""
        import mitsuba as mi

        az = float(azimuth_deg)
        if az not in self._vis:
            self._vis.update(truth_bands.band_pass(self, [az]))
        band = next(i for i, (first, _) in enumerate(self.bands) if first == st.first)
        bits = np.unpackbits(self._vis[az][band], count=st.count)
        return mi.Float(bits.astype(np.float32))

    def _frame_samples(self):
        """The samples of every band for a frame: the kept ones, or each band's traced again."""
        if self._kept is not None:
            yield from self._kept
            return
        for i, (first, stop) in enumerate(self.bands):
            if self.mesh_bands is not None:
                yield self._shading_samples(first, stop)
                continue
            st = self._camera_samples(first, stop)
            st.ambient = self._ambient_bands[i] if self._ambient_bands else None
            yield st


class _RayQueries:
    """The truth's ray queries against the displaced mesh (a part of :class:`Truth`): where a ray from
    above meets the surface, whether a shadow ray is blocked, across a ``wrap`` tile's hops, and
    the per-sample random streams. They read the Truth's Mitsuba scene and its tile geometry."""

    def _rng(self, stream: int, st: "_Samples"):
        """A PCG32 per sample of ``st``, seeded by the scene's seed, a stream tag and the sample's index
        in the whole image: deterministic, and the same in a band as in one piece."""
        return stream_rng(self.scene.seed, stream, st.start, st.count)

    def _surface_at(self, x, y, active=True, coherent: bool = False):
        """Lifted ray origin, geometric normal and shading normal of the surface above ``(x, y)``.

        The shading normal is the vertex normals' bilinear interpolation at
        ``(x, y)`` for ``smooth`` shading, the triangle's own for ``faceted``
        (module docstring, "Shading").

        A ray straight down from above the highest point finds the surface;
        the origin keeps the exact ``(x, y)`` and takes the height of the hit
        plus :attr:`lift`: vertically above the height field, it is above
        every triangle around it (module docstring, "Self-intersection").
        """
        import drjit as dr
        import mitsuba as mi

        c = self._c
        px, py = x, y
        if self.scene.material.boundary == "open":
            # a sample on the image border is on the mesh's outer edge, which
            # a ray may miss; the border half-texel is flat (hzval.geometry.tile), so
            # probing just inside it finds the same height
            px = dr.clip(x, _EDGE, c["cols"] - _EDGE)
            py = dr.clip(y, _EDGE, c["rows"] - _EDGE)
        # only the hit's position and geometric normal are read (RayFlags.Minimal); ``coherent``:
        # neighbouring rays run side by side (the camera's): together 2.0x faster, same hits
        si = self.mi_scene.ray_intersect(
            mi.Ray3f(mi.Point3f(px, py, c["probe"]), mi.Vector3f(0.0, 0.0, -1.0)),
            mi.RayFlags.Minimal,
            coherent,
            active,
        )
        n = mi.Vector3f(si.n)
        ns = n if self._normals is None else self._shading_normal(x, y)
        return mi.Point3f(x, y, si.p.z + c["lift"]), n, ns, si.is_valid()

    def _shading_normal(self, x, y):
        """The ``smooth`` shading normal at ``(x, y)``: the vertex normals' bilinear interpolation
        (module docstring, "Shading")."""
        import drjit as dr
        import mitsuba as mi

        c = self._c
        # u, v of hzval.core.conventions.tangent_to_uv, in the kernel
        uv = mi.Point2f(x / c["cols"], (c["rows"] - y) / c["rows"])
        return dr.normalize(mi.Vector3f(*self._normals.eval(uv)))

    def _hops_for(self, elevation: float) -> int:
        """Hops that a ray rising at ``elevation`` (radians) needs to clear the surface.

        From the lowest point it must rise ``relief`` (plus the lift) to be
        above the highest, i.e. run ``relief / tan(elevation)`` texels; one
        hop runs :attr:`_hop` texels. ``open`` needs one (unbounded) ray.
        """
        if self.scene.material.boundary == "open" or self.relief <= 0:
            return 1
        elevation = max(elevation, math.radians(MIN_TRACED_ELEVATION_DEG))
        run = (self.relief + 2 * self.lift) / math.tan(elevation)
        return max(1, math.ceil(run / self._hop))

    def _advance(self, o, d, maxt):
        """The point ``o + maxt d``, wrapped back into the tile (``wrap`` only)."""
        import drjit as dr
        import mitsuba as mi

        c = self._c
        p = o + d * maxt
        return mi.Point3f(
            p.x - c["cols"] * dr.floor(p.x / c["cols"]), p.y - c["rows"] * dr.floor(p.y / c["rows"]), p.z
        )

    def _hop_length(self, o, d):
        """Per ray, how far ``o + t d`` (``o`` in the tile) runs over the mesh before its end, wrapped
        back into the tile, could be off it: ``t`` to the nearer of the box ``[-e, cols + e] x [-e, rows
        + e]`` (``e`` = margin - 0.75: the mesh ends at margin - 0.5, a quarter texel kept for float32's
        rounding) in the ray's horizontal direction. At least :attr:`_hop` texels horizontally; a ray
        from inside the tile runs the tile's width or more, so a narrow margin costs hops only to the
        rays that leave near the tile's edge."""
        import drjit as dr

        c = self._c
        run_x = dr.select(d.x >= 0.0, c["cols"] + c["edge"] - o.x, o.x + c["edge"])
        run_y = dr.select(d.y >= 0.0, c["rows"] + c["edge"] - o.y, o.y + c["edge"])
        return dr.minimum(run_x / dr.maximum(dr.abs(d.x), 1e-12), run_y / dr.maximum(dr.abs(d.y), 1e-12))

    def _occluded(self, o, d, hops: int, dynamic: bool = False, coherent: bool = False, skip=None):
        """Whether the rays ``o + t d`` (``t > 0``) hit the surface; ``d`` unit.

        Directions at or below the horizontal are occluded (module docstring).
        Rays where ``skip`` is set are not traced (their answer is the caller's).
        A ray is traced only until it rises above the highest point of the
        surface (``t = (top - o.z) / d.z``), past which nothing can block it:
        the same answers, and Embree leaves the rest of the BVH alone.
        ``wrap`` traces ``hops`` hops (see "Boundaries"); with ``dynamic`` it
        stops early once every ray is resolved (a host round trip per hop),
        and rays still unresolved after ``hops`` count as occluded.
        ``coherent`` tells Embree that neighbouring rays travel together
        (parallel shadow rays from neighbouring samples: about 30% faster).
        """
        import drjit as dr
        import mitsuba as mi

        active = d.z > 0.0
        if skip is not None:
            active &= ~skip
        coherent = mi.Bool(coherent)
        top = self._c["top"]
        if self.scene.material.boundary == "open":
            ray = mi.Ray3f(o, d)
            ray.maxt = dr.maximum((top - o.z) / d.z, 0.0)
            return (d.z <= 0.0) | self.mi_scene.ray_test(ray, coherent, active)
        blocked = d.z <= 0.0
        hit, active, o = self._hop_loop(o, d, active, 1, coherent, False)  # every ray's first hop
        blocked |= hit
        if hops == 1:
            return blocked | active
        # the rays that leave the mesh before they clear the surface, those that start near the
        # tile's edge: traced on by themselves, so that their hops cost no more than they are
        dr.eval(blocked, active, o)
        idx = dr.compress(active)
        if dr.width(idx) == 0:
            return blocked
        o_left = dr.gather(mi.Point3f, o, idx)
        d_left = d if dr.width(d) == 1 else dr.gather(mi.Vector3f, d, idx)
        hit, left, _ = self._hop_loop(
            o_left, d_left, dr.full(mi.Bool, True, dr.width(idx)), hops - 1, coherent, dynamic
        )
        dr.scatter(blocked, True, idx, hit | left)
        return blocked

    def _hop_loop(self, o, d, active, hops: int, coherent, dynamic: bool):
        """``hops`` hops of the rays ``o + t d`` (``wrap``; ``o`` in the tile): ``(blocked, active, o)``,
        the rays that met the surface, those still under its top after the last hop, and where they
        are, wrapped into the tile. With ``dynamic`` the hops stop once every ray is resolved."""
        import drjit as dr
        import mitsuba as mi

        top = self._c["top"]
        blocked = mi.Bool(False)
        for i in range(hops):
            maxt = self._hop_length(o, d)
            ray = mi.Ray3f(o, d)
            ray.maxt = dr.minimum(maxt, dr.maximum((top - o.z) / d.z, 0.0))
            hit = self.mi_scene.ray_test(ray, coherent, active)
            blocked |= hit & active
            o = self._advance(o, d, maxt)
            active &= ~hit & (o.z < top)
            if dynamic and i + 1 < hops:
                dr.eval(o, active, blocked)
                if not bool(dr.any(active)):
                    break
        return blocked, active, o

    def _next_surface(self, o, d, active, hops: int):
        """Where the rays ``o + t d`` first meet the surface, wrapped into the tile.

        Returns ``(x, y, hit, escaped)``: ``hit`` rays met the surface at
        ``(x, y)``; ``escaped`` rays rose above it (``d.z > 0``) without
        meeting it. Rays that are neither went below the horizontal off an
        ``open`` tile, or were unresolved after ``hops`` hops. Only the
        position is kept: the path continues from :meth:`_surface_at` there,
        with an exact, lifted origin.
        """
        import drjit as dr
        import mitsuba as mi

        if self.scene.material.boundary == "open":
            si = self.mi_scene.ray_intersect(mi.Ray3f(o, d), active)
            hit = active & si.is_valid()
            return si.p.x, si.p.y, hit, active & ~hit & (d.z > 0.0)
        start = active
        active = mi.Bool(active)  # a copy: &= below must not touch the caller's mask
        hit = mi.Bool(False)
        x, y = mi.Float(0.0), mi.Float(0.0)
        for _ in range(hops):
            maxt = self._hop_length(o, d)
            ray = mi.Ray3f(o, d)
            ray.maxt = maxt
            si = self.mi_scene.ray_intersect(ray, active)
            now = active & si.is_valid()
            p = self._advance(si.p, d, 0.0)
            x, y = dr.select(now, p.x, x), dr.select(now, p.y, y)
            hit |= now
            o = self._advance(o, d, maxt)
            # rays going down never clear the top: they meet the surface or stop at the cap
            active &= ~now & ((o.z < self._c["top"]) | (d.z <= 0.0))
            dr.eval(o, active, hit, x, y)
            if not bool(dr.any(active)):
                break
        return x, y, hit, start & ~hit & ~active & (d.z > 0.0)


class _PathTracing:
    """The truth's interreflection (a part of :class:`Truth`): paths up to the scene's declared depth,
    as Mitsuba's ``path`` integrator would trace them on the displaced mesh."""

    def _path_trace(self, st: "_Samples", L1, vis1, azimuth_deg: float):
        """Radiance per sample of paths up to Mitsuba's ``max_depth`` = ``interreflection_depth``.

        As in Mitsuba's ``path`` integrator, ``max_depth`` counts path
        segments from the camera: 2 is direct light only, 3 adds one
        interreflection, and so on. At each surface vertex the light is
        sampled (next-event estimation: the first vertex uses the samples'
        own light directions ``L1`` and their visibility ``vis1``, later ones
        draw from the light's cone), its visibility tested only if
        ``shadow`` is declared; the BSDF then samples the next direction,
        which collects the sky if ``ambient`` is declared and it escapes, or
        continues from the surface it meets. The light is reached by
        next-event estimation only and the sky by BSDF sampling only, so
        neither is counted twice and no MIS is needed. The first bounce
        reuses the ambient layer's cosine-weighted directions, so with
        ``max_depth = 2`` and a diffuse surface the result is the direct
        render's, sample for sample (with ``specular``, the sky's glossy
        reflection, which the direct render leaves out, is added).

        This is written here rather than run through Mitsuba's own ``path``
        integrator because its rays start at ``spawn_ray`` offsets, which
        show false shadows at mesh vertices and near valley edges of the
        displaced mesh and leak light where shadows begin (module
        docstring), and its rays see only the wrap margin, not the endless
        tiling; every ray here takes the same robust origins and hops as the
        shadow rays.
        """
        import drjit as dr
        import mitsuba as mi

        sc = self.scene
        light = sc.light
        E_sky = self._c["E_sky"]
        max_depth = int(sc.interreflection_depth)
        rng = self._rng(0x9A7 + 0x1000 * (int(round(azimuth_deg * 1000)) & 0xFFFF), st)
        first = self._rng(_AMBIENT_STREAM, st)  # the ambient layer's directions at the first vertex
        centre = light.direction(azimuth_deg)
        centre_v = mi.Vector3f(*(dr.opaque(mi.Float, float(c)) for c in centre))
        cos_max = dr.opaque(
            mi.Float, math.cos(math.radians(light.radius_deg)) if light.kind == "soft" else 1.0
        )
        cap = self._hops_for(math.radians(MIN_TRACED_ELEVATION_DEG))
        rho = light.radius_deg if light.kind == "soft" else 0.0
        lowest, highest = math.radians(light.elevation_deg - rho), math.radians(light.elevation_deg + rho)

        o, n, ns, albedo = st.o, st.n, st.ns, st.albedo
        v = self._toward_eye  # toward the previous vertex (the camera)
        beta = mi.Color3f(1.0)  # path throughput
        result = mi.Color3f(0.0)
        active = mi.Bool(True)
        p_spec = _specular_sampling_share(sc)
        for depth in range(1, max_depth):
            # next-event estimation toward the light
            L = L1 if depth == 1 else self._light_sample(rng, centre_v, cos_max)
            contrib = self._direct(ns, L, v, albedo)
            if sc.declares("shadow"):
                contrib = contrib * (vis1 if depth == 1 else self._visible(o, n, L, lowest, highest))
            result += dr.select(active, beta * contrib, 0.0)
            if depth + 1 >= max_depth and not sc.declares("ambient"):
                break
            # sample the BSDF for the next segment: the sky if it escapes, else the next vertex
            u_lobe = rng.next_float32()
            u = mi.Point2f(rng.next_float32(), rng.next_float32())
            if depth == 1:
                u = mi.Point2f(first.next_float32(), first.next_float32())
            wo, weight = _sample_bsdf(sc, ns, v, albedo, p_spec, u_lobe, u)
            weight = dr.select(dr.dot(n, wo) > 0.0, weight, 0.0)  # not into the triangle hit
            active &= dr.any(weight > 0.0)
            beta *= weight
            x, y, hit, escaped = self._next_surface(o, wo, active, cap)
            if sc.declares("ambient"):
                result += dr.select(escaped, beta * (E_sky * SKY_RADIANCE_PER_IRRADIANCE), 0.0)
            if depth + 1 >= max_depth:
                break
            active &= hit
            o_next, n_next, ns_next, valid = self._surface_at(x, y, active)
            active &= valid
            o = dr.select(active, o_next, o)
            n = dr.select(active, n_next, n)
            ns = dr.select(active, ns_next, ns)
            v = -wo
            if albedo is not None:
                albedo = self._albedo_at(x, y, active)
            dr.eval(o, n, ns, v, beta, result, active, albedo)
        return result

    def _light_sample(self, rng, centre, cos_max):
        """A direction toward the light for a later path vertex: the centre of a hard light, or a
        direction drawn uniformly from a soft light's cone (``cos_max``: cosine of its radius)."""
        import mitsuba as mi

        if self.scene.light.kind != "soft":
            return centre
        return mi.Frame3f(centre).to_world(
            mi.warp.square_to_uniform_cone(mi.Point2f(rng.next_float32(), rng.next_float32()), cos_max)
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


def lift_for(z_min: float, z_max: float) -> float:
    """The ray origins' lift above the surface, texels, for heights from ``z_min`` to ``z_max``
    (module docstring, "Self-intersection")."""
    return max(LIFT_TEXELS, LIFT_PER_HEIGHT * max(abs(z_min), abs(z_max)))


class Truth(_CameraRays, _RayQueries, _PathTracing):
    """Ground-truth renderer of one scene and height map.

    ``height``: the normalised height map ``H[row, col]`` (float32); the
    scene's ``material`` gives depth and boundary. ``positions``: optional
    ``(x, y)`` sample positions in texel units replacing
    :func:`hzval.scene.camera.sample_positions` (same length and pixel-major order,
    ``pixels * spp``); tests use it to put samples exactly on mesh vertices.
    ``band_samples`` (samples per band) and ``keep`` (whether the camera hits
    are kept between frames) override :func:`_bands` and :func:`keeps_samples`
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
    off a line of mesh edges, :func:`_off_edge_lines`), ``timings``
    (seconds: ``mesh_s``, ``primary_s``, ``ambient_s``), ``view`` (the placed
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
        self._albedo_texels = self._load_albedo(albedo)
        self._positions = self._check_positions(positions)
        self.count = self.shape[0] * self.shape[1] * self.spp
        self.keeps = keeps_samples(*self.shape, self.spp) if keep is None else bool(keep)
        self.bands = _bands(self.shape, self.spp, band_samples)
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
        # the finest sub-cell grid: every edge of the mesh is on one of its lines (_off_edge_lines)
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
        self.mi_scene = None if self.mesh is None else mi.load_dict({"type": "scene", "surface": self.mesh})
        self.lift = lift_for(self.z_min, self.z_max)
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

    def _load_albedo(self, albedo):
        """The linear albedo texels as one flat ``mi.Float`` array, or ``None`` when no effect reads it."""
        import mitsuba as mi

        scene, rows, cols = self.scene, self.rows, self.cols
        if not any(scene.declares(e) for e in _NEEDS_ALBEDO):
            return None
        a = (
            load_albedo(scene.material, rows, cols)
            if albedo is None
            else np.asarray(albedo, dtype=np.float32)
        )
        if a.shape != (rows, cols, 3):
            raise InputError("albedo", f"expected shape {(rows, cols, 3)}, got {a.shape}")
        return mi.Float(np.ascontiguousarray(a, dtype=np.float32).ravel())

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

    def _trace_ambient(self, st: "_Samples"):
        """``A`` per sample: a cosine-weighted direction escapes (independent of the light, once)."""
        import drjit as dr
        import mitsuba as mi

        t0 = time.perf_counter()
        rng = self._rng(_AMBIENT_STREAM, st)
        # cosine-weighted about the shading normal; a direction into the triangle hit is blocked
        d = mi.Frame3f(st.ns).to_world(
            mi.warp.square_to_cosine_hemisphere(mi.Point2f(rng.next_float32(), rng.next_float32()))
        )
        blocked = (dr.dot(st.n, d) <= 0.0) | self._occluded(
            st.o, d, self._hops_for(math.radians(MIN_TRACED_ELEVATION_DEG)), dynamic=True
        )
        ambient = dr.select(blocked, 0.0, 1.0)
        dr.eval(ambient)
        backend.sync()
        self.timings["ambient_s"] += time.perf_counter() - t0
        return ambient

    def _trace_reflection(self, st: "_Samples") -> tuple[np.ndarray, np.ndarray]:
        """``R`` per pixel of the band ``st`` and its variance (flat): the share of the glossy lobe that
        escapes
        (independent of the light, once).

        Directions and weights: :func:`lobe_sample`; ``V`` = 1 where the
        direction escapes; ``R`` and its variance: :func:`reflection_estimate`
        (a model's truth, :mod:`hzval.truth.model`, calls the same two).
        """
        import drjit as dr
        import mitsuba as mi

        t0 = time.perf_counter()
        rng = self._rng(REFLECTION_STREAM, st)
        wo, w = lobe_sample(st.ns, self._toward_eye, mi.Point2f(rng.next_float32(), rng.next_float32()))
        blocked = (dr.dot(st.n, wo) <= 0.0) | self._occluded(
            st.o, wo, self._hops_for(math.radians(MIN_TRACED_ELEVATION_DEG)), dynamic=True
        )
        out = reflection_estimate(w, dr.select(blocked, 0.0, 1.0), self.spp)
        self.timings["reflection_s"] += time.perf_counter() - t0
        return out

    # ------------------------------------------------------------------
    # Frames
    # ------------------------------------------------------------------

    def light_directions(self, azimuth_deg: float, st: "_Samples | None" = None):
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

    def _render_band(self, st: "_Samples", azimuth_deg: float) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Pixel means and variances of the mean (:func:`mean_and_variance`) over the samples of the
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
                stats[k] = mean_and_variance(s1, s1 * (1.0 - s1 / nn), n)
        if "image" in reduced:
            stats["image"] = tuple(
                zip(
                    *(
                        mean_and_variance(mi.Float64(c), mi.Float64(q), n)
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


#: Up to this many samples (2048 x 2048 at 32 spp) the truth keeps every sample's camera hit
#: between frames (module docstring, "Memory"); a larger image traces them again in each frame.
KEEP_SAMPLES = 1 << 27
#: Samples per band of a larger image: about 1 GB of per-sample state at a time.
BAND_SAMPLES = 1 << 24
#: Samples per band of an image whose samples are kept: the rays' own buffers (Embree's inputs
#: and outputs, the shading's terms) stay this small, and are reused from band to band.
KEPT_BAND_SAMPLES = 1 << 22
#: Bytes per sample of that state: the lifted origin's height (its x and y are the sample positions
#: themselves), the geometric and shading normals and ``A`` (8 float32; the albedo is gathered
#: again by each frame's kernel; ``memory.estimate_peak_bytes`` counts the state).
STATE_BYTES_PER_SAMPLE = 32


def bands(rows: int, cols: int, spp: int) -> list[tuple[int, int]]:
    """The bands of pixels in which a truth of a ``rows x cols`` image at ``spp`` works (:func:`_bands`)."""
    return _bands((rows, cols), spp)


def keeps_samples(rows: int, cols: int, spp: int) -> bool:
    """Whether a truth of a ``rows x cols`` image at ``spp`` keeps every sample's camera hit between
    frames (up to :data:`KEEP_SAMPLES`; module docstring, "Memory")."""
    return rows * cols * spp <= KEEP_SAMPLES


def _bands(shape: tuple[int, int], spp: int, band_samples: int | None = None) -> list[tuple[int, int]]:
    """Whole rows of pixels, ``[(first, stop), ...]`` pixel indices, each of at most ``band_samples``
    samples (at least one row); default: bands of :data:`KEPT_BAND_SAMPLES` where the samples are
    kept (:func:`keeps_samples`), else of :data:`BAND_SAMPLES`."""
    H, W = shape
    if band_samples is None:
        band_samples = KEPT_BAND_SAMPLES if keeps_samples(H, W, spp) else BAND_SAMPLES
    rows = max(1, int(band_samples) // (W * spp))
    return [(r * W, min(H, r + rows) * W) for r in range(0, H, rows)]


@dataclasses.dataclass
class _Samples:
    """The camera samples of a band of pixels ``first <= p < stop`` (samples ``start`` to ``start +
    count``): lifted origin ``o``, geometric normal ``n``, shading normal ``ns``, ``albedo`` (or
    None), ``A`` (``ambient``, when declared), and how many were ``moved`` off a line of edges."""

    first: int
    stop: int
    start: int
    count: int
    o: object
    n: object
    ns: object
    albedo: object
    moved: int
    ambient: object = None
    seen: object = None


def _off_edge_lines(
    xs: np.ndarray, ys: np.ndarray, rows: int, cols: int, level: int = 1
) -> tuple[np.ndarray, np.ndarray, int]:
    """Move samples that lie exactly on a line of mesh edges a few ulps off it.

    The mesh's edges (:func:`hzval.geometry.tile.tessellate`) run along the lines of
    the sub-cell grid of its finest ``level`` ``n`` (a power of two):
    ``(x - 1/2) n`` or ``(y - 1/2) n`` an integer (the columns and rows of
    texel centres among them), and along that grid's diagonals, where the
    two fractions ``u``, ``v`` of those coordinates are equal or sum to 1
    (a coarser cell's diagonals and sub-cells lie on the same lines). A
    sample on such a line has no single triangle, and a ray toward an
    azimuth along the line (0, 90, 180, 270 or 45, 135, 225, 315 degrees,
    all in common sweeps) runs inside the edge and can slip between its two
    triangles: Embree's traversal is not watertight there (embree/embree#387).
    With float32 positions this is not rare: on a 512x512 map at 16 spp
    about 230 samples per frame sat on the lines of the old diagonal mesh.
    They move by 8 ulps of the map's largest coordinate (1/2048 texel at
    512) toward the tile's interior, to a point of one triangle; a few on
    lines of a finer grid than their cell's move for nothing.
    """
    step = 2.0 ** (math.ceil(math.log2(max(rows, cols, 2))) - 20)

    def on_lines(x, y):
        # (x - 1/2) n and its fraction are exact in float32 (n a power of two), and two fractions
        # sum to exactly 1 only if 1 - fu, which is then a float32, equals fv
        u, v = (x - np.float32(0.5)) * np.float32(level), (y - np.float32(0.5)) * np.float32(level)
        fu, fv = u - np.floor(u), v - np.floor(v)
        return (fu == 0) | (fv == 0) | (fu == fv) | (fv == 1 - fu)

    # only the few samples found on a line are moved and checked again; they are found in one
    # Dr.Jit kernel (the same float32 test: 0.1 s against 0.8 s in NumPy at 2048 x 2048 x 16)
    idx = _on_edge_lines_index(xs, ys, level)
    moved = int(idx.size)
    if not moved:
        return xs, ys, 0  # as they are (the shared positions are read-only: no copy)
    xs, ys = np.array(xs, dtype=np.float32), np.array(ys, dtype=np.float32)
    for _ in range(3):
        if not idx.size:
            break
        x, y = xs[idx].astype(np.float64), ys[idx].astype(np.float64)
        xs[idx] = x + np.where(x < cols / 2, step, -step)
        ys[idx] = y + np.where(y < rows / 2, step / 2, -step / 2)
        idx = idx[on_lines(xs[idx], ys[idx])]
    return xs, ys, moved


def _on_edge_lines_index(xs: np.ndarray, ys: np.ndarray, level: int = 1) -> np.ndarray:
    """Indices (int64) of the samples exactly on a line of mesh edges (:func:`_off_edge_lines`)."""
    import drjit as dr
    import mitsuba as mi

    i = dr.arange(mi.UInt32, xs.size)
    n = dr.opaque(mi.Float, float(level))
    x = dr.gather(mi.Float, mi.Float(np.ascontiguousarray(xs, np.float32)), i)
    y = dr.gather(mi.Float, mi.Float(np.ascontiguousarray(ys, np.float32)), i)
    u, v = (x - 0.5) * n, (y - 0.5) * n
    fu, fv = u - dr.floor(u), v - dr.floor(v)
    return np.asarray(dr.compress((fu == 0.0) | (fv == 0.0) | (fu == fv) | (fv == 1.0 - fu)), dtype=np.int64)


def _specular_sampling_share(scene: Scene) -> float:
    """Share of BSDF samples drawn from the specular lobe (the rest cosine-weighted)."""
    if not scene.declares("specular"):
        return 0.0
    return 1.0 if not scene.declares("diffuse") else 0.25


def _sample_bsdf(scene: Scene, n, v, albedo, p_spec: float, u_lobe, u):
    """Sample the truth's BSDF about normal ``n`` seen from ``v``: ``(wo, f cos / pdf)``.

    The BSDF is the one :meth:`Truth._direct` evaluates: Lambert
    ``albedo / pi`` and, with ``specular``, FGED2's Blinn-Phong written as a
    BSDF, ``f cos = ks (n.h)^alpha [n.wo > 0]``. Directions come from a
    mixture of the cosine-weighted hemisphere and the lobe's half-vector
    distribution ``pdf(h) = (alpha + 1) / (2 pi) (n.h)^alpha``, ``pdf(wo) =
    pdf(h) / (4 wo.h)`` (Walter et al. 2007), so the weight stays bounded.
    """
    import drjit as dr
    import mitsuba as mi

    wo_d = mi.Frame3f(n).to_world(mi.warp.square_to_cosine_hemisphere(u))
    if p_spec > 0.0:
        wo_s, _ = _lobe_direction(n, v, u)
        wo = dr.select(u_lobe < p_spec, wo_s, wo_d) if p_spec < 1.0 else wo_s
    else:
        wo = wo_d
    cos_o = dr.dot(n, wo)
    f_cos = mi.Color3f(0.0)
    pdf = mi.Float(0.0)
    if scene.declares("diffuse"):
        f_cos += albedo * (dr.maximum(cos_o, 0.0) * (1.0 / math.pi))
    if p_spec < 1.0:
        pdf += (1.0 - p_spec) * dr.maximum(cos_o, 0.0) * (1.0 / math.pi)
    if scene.declares("specular"):
        hv = dr.normalize(wo + v)
        nh = dr.maximum(dr.dot(n, hv), 0.0)
        lobe = dr.power(nh, SPECULAR_EXPONENT)
        f_cos += mi.Color3f(dr.select(cos_o > 0.0, SPECULAR_KS * lobe, 0.0))
        pdf_h = (SPECULAR_EXPONENT + 1.0) * (0.5 / math.pi) * lobe
        pdf += p_spec * pdf_h / dr.maximum(4.0 * dr.abs(dr.dot(wo, hv)), 1e-12)
    ok = (cos_o > 0.0) & (pdf > 0.0)
    return wo, dr.select(ok, f_cos / dr.maximum(pdf, 1e-30), 0.0)


def stream_rng(seed: int, stream: int, start: int, count: int):
    """A PCG32 per sample ``start <= k < start + count`` of the image, seeded by the scene's ``seed``
    and a ``stream`` tag: deterministic, and the same in a band as in one piece (the plane's truth
    in bands, a model's in one piece, :mod:`hzval.truth.model`)."""
    import drjit as dr
    import mitsuba as mi

    state = (int(seed) * 0x9E3779B97F4A7C15 + stream) & 0xFFFFFFFFFFFFFFFF
    # Dr.Jit's PCG32(size, initstate, initseq) adds each lane's index to both (drjit/random.h):
    # sample k of one piece starts from initstate + k with the sequence 2k, so lane j of a
    # band starting at sample s takes initstate + s and initseq j + 2 s
    return mi.PCG32(
        size=count,
        initstate=(state + start) & 0xFFFFFFFFFFFFFFFF,
        initseq=dr.arange(mi.UInt64, count) + 2 * start,
    )


def lobe_sample(ns, v, u):
    """``(wo, w)``: a direction of the glossy lobe about the shading normal ``ns`` seen from ``v``
    (toward the camera, unit), from ``u`` in [0, 1)^2 (:func:`_lobe_direction`), and its weight in
    the estimate of ``R`` (the ``reflection_occlusion`` layer, module docstring).

    Drawn from the lobe's half-vector distribution, each direction carries the
    estimator's weight ``f cos / pdf = ks 8 pi (wo.h) / (alpha + 1)``
    (Walter et al. 2007; ``f cos = ks (n.h)^alpha [n.wo > 0]``, ``pdf =
    (alpha + 1) / (2 pi) (n.h)^alpha / (4 wo.h)``); the constant cancels in
    the ratio, so ``w = wo.h`` where ``ns.wo > 0``, else 0.
    """
    import drjit as dr

    wo, h = _lobe_direction(ns, v, u)
    return wo, dr.select(dr.dot(ns, wo) > 0.0, dr.maximum(dr.dot(wo, h), 0.0), 0.0)


def reflection_estimate(w, V, spp: int) -> tuple[np.ndarray, np.ndarray]:
    """``(R, variance)`` per pixel (flat float32) from per-sample weights ``w`` (:func:`lobe_sample`)
    and escapes ``V`` (0/1) of ``spp`` consecutive samples a pixel: ``R = sum w V / sum w`` (0
    where ``sum w = 0``) and the ratio estimator's variance ``sum w^2 (V - R)^2 / (sum w)^2``
    (NaN for one sample a pixel, which has none)."""
    import drjit as dr

    sums = [dr.block_sum(x, spp) for x in (w * V, w, w * w * V, w * w)]
    dr.eval(sums)
    backend.sync()
    wv, ws, w2v, w2 = (np.asarray(x, np.float64) for x in sums)
    R = np.divide(wv, ws, out=np.zeros_like(ws), where=ws > 0)
    var = np.divide(w2v * (1.0 - 2.0 * R) + R * R * w2, ws * ws, out=np.zeros_like(ws), where=ws > 0)
    if spp < 2:
        var[:] = np.nan
    return R.astype(np.float32), np.maximum(var, 0.0).astype(np.float32)


def _lobe_direction(n, v, u):
    """A direction of the Blinn-Phong lobe about normal ``n`` seen from ``v``, from ``u`` in [0, 1)^2.

    The half vector ``h`` has ``pdf(h) = (alpha + 1) / (2 pi) (n.h)^alpha``
    (``alpha`` = :data:`hzval.core.shading.SPECULAR_EXPONENT`) and the direction is
    ``v`` reflected about it (Walter et al. 2007); with ``h = n`` it is the
    mirror direction. It may point below the surface. Returns ``(wo, h)``.
    """
    import drjit as dr
    import mitsuba as mi

    cos_h = dr.power(u.x, 1.0 / (SPECULAR_EXPONENT + 1.0))
    sin_h = dr.safe_sqrt(1.0 - cos_h * cos_h)
    phi = 2.0 * math.pi * u.y
    h = mi.Frame3f(n).to_world(mi.Vector3f(sin_h * dr.cos(phi), sin_h * dr.sin(phi), cos_h))
    return 2.0 * dr.dot(v, h) * h - v, h


def mean_and_variance(s1, ss, spp):
    """Pixel means and variances of the mean from per-pixel sums of x and of (x - mean)^2: float64
    Dr.Jit arrays in, float32 arrays out (rounded once, from float64).

    ``spp``: the samples of every pixel (an ``int``), or an array of each pixel's (those that see the
    surface; a pixel of none has mean 0). The variance of the mean is the sample variance (``n - 1``
    in the denominator) over ``n``: NaN for one sample, which has none.
    """
    import drjit as dr
    import mitsuba as mi

    if isinstance(spp, int):
        mean = s1 / spp
        var = (
            dr.full(mi.Float64, math.nan, dr.width(mean))
            if spp < 2
            else dr.maximum(ss, 0.0) / (spp - 1) / spp
        )
        return mi.Float(mean), mi.Float(var)
    n = mi.Float64(spp)
    mean = s1 / dr.maximum(n, 1.0)
    var = dr.select(n >= 2, dr.maximum(ss, 0.0) / dr.maximum(n - 1, 1.0) / dr.maximum(n, 1.0), math.nan)
    return mi.Float(mean), mi.Float(var)
