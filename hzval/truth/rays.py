"""The plane truth's rays, of which :class:`hzval.truth.plane.Truth` is made.

They are the camera's rays and their hits (CameraRays), shadow, ambient and reflection queries against the
displaced tile with its hops across a wrapping tile (RayQueries), and the path tracer of ``interreflection``
(PathTracing).
"""

from __future__ import annotations

import math
import time

import numpy as np

from hzval.core import backend
from hzval.core.backend import dr, mi  # Dr.Jit loads at first use, once the LLVM is chosen
from hzval.core.shading import SKY_RADIANCE_PER_IRRADIANCE
from hzval.scene.camera import sample_positions
from hzval.truth import bands as truth_bands
from hzval.truth import common
from hzval.truth import samples as truth_samples

__all__ = [
    "MIN_TRACED_ELEVATION_DEG",
    "CameraRays",
    "RayQueries",
    "PathTracing",
]

#: How far inside an ``open`` tile's border its height is probed, texels.
_EDGE = 2.0**-10
#: Rays lower than this above the horizontal (ambient and path rays, soft
#: lights reaching the horizon; ``wrap`` only) are not traced in more hops
#: than it takes to clear the surface at this elevation; the few still below
#: the surface's top after that count as occluded. The cosine-weighted share
#: of such directions is about sin^2 of it (2e-5).
MIN_TRACED_ELEVATION_DEG = 0.25


class CameraRays:
    """The truth's camera rays (a part of :class:`hzval.truth.plane.Truth`).

    They are where each sample of the view meets the displaced mesh, kept between frames or traced again band
    by band (docs/internals.md, the truth's "Memory"), with the albedo and shading normal there.
    """

    def _trace_camera_rays(self) -> None:
        """Trace every sample's camera ray to the surface once, with what does not depend on the light.

        What does not depend on the light is ``A`` and ``R``. One band keeps its samples
        (:class:`samples.Samples`) for every frame; with more (docs/internals.md, the truth's "Memory") only
        ``A`` is kept, per band, and the reflection layer.
        """
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
                self.moved_off_edges += truth_samples.off_edge_lines(
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

    def _camera_samples(self, first: int, stop: int) -> "truth_samples.Samples":
        """Return the samples of the pixels ``first <= p < stop``.

        They are where their camera rays meet the surface (lifted origin, geometric and shading normal) and
        the albedo of the texel that holds each (an expression over the positions: the kernels that read it
        gather it).
        """
        rows, cols, spp = self.rows, self.cols, self.spp
        xs, ys, seen = self._band_positions(first, stop)
        xs, ys, moved = truth_samples.off_edge_lines(xs, ys, rows, cols, self.edge_level)
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
        return truth_samples.Samples(
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
        """Return the albedo at ``(x, y)`` (:func:`hzval.truth.common.albedo_at`, the map's size opaque)."""
        return common.albedo_at(self._albedo_texels, self._c["rows"], self._c["cols"], x, y, active)

    def _band_positions(self, first: int, stop: int):
        """Return ``(x, y, seen)`` of the samples of the pixels ``first <= p < stop``.

        They are the scene's top-view positions or the tests' (``seen`` None: all), or where the camera's rays
        meet the surface (``seen``: which do; the others are put on the tile, and count for nothing).
        """
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
        """Trace every camera ray once, for a view other than ``top``.

        It finds :attr:`seen`, the pixels whose rays meet the surface, and, when the truth keeps its samples
        (:attr:`keeps`), :attr:`hits` (float32 ``(x, y)`` of each sample's surface point, in the tile), which
        the frames reuse.
        """
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
        """Return where the camera rays of the pixels ``first <= p < stop`` meet the surface.

        The hits are float32 ``x, y`` in the tile (``wrap``: the endless tiling, in hops; ``open``: the tile
        alone), with which rays do. A ray first runs in float64, on the host, to just above the highest point
        (wrapped into the tile), so that the float32 rays start near the surface whatever the eye's distance.
        """
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

    def _shading_samples(self, first: int, stop: int) -> "truth_samples.Samples":
        """Return the samples of the pixels ``first <= p < stop`` of a truth whose mesh is in bands.

        They hold their shading normals and albedo, which need no mesh (``o`` and ``n`` unset: their
        visibility is :meth:`_band_visibility`'s).
        """
        xs, ys, _ = self._band_positions(first, stop)
        xs, ys, moved = truth_samples.off_edge_lines(xs, ys, self.rows, self.cols, self.edge_level)
        x, y = mi.Float(xs), mi.Float(ys)
        albedo = self._albedo_at(x, y) if self._albedo_texels is not None else None
        return truth_samples.Samples(
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

    def _band_visibility(self, azimuth_deg: float, st: "truth_samples.Samples"):
        """Return ``V`` per sample of ``st`` from the bits of :func:`hzval.truth.bands.band_pass`.

        A light not of the scene's sweep gets its own pass.
        """
        az = float(azimuth_deg)
        if az not in self._vis:
            self._vis.update(truth_bands.band_pass(self, [az]))
        band = next(i for i, (first, _) in enumerate(self.bands) if first == st.first)
        bits = np.unpackbits(self._vis[az][band], count=st.count)
        return mi.Float(bits.astype(np.float32))

    def _frame_samples(self):
        """Yield the samples of every band for a frame: the kept ones, or each band's traced again."""
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


class RayQueries:
    """The truth's ray queries against the displaced mesh (a part of :class:`hzval.truth.plane.Truth`).

    They answer where a ray from above meets the surface and whether a shadow ray is blocked, across a
    ``wrap`` tile's hops, and hold the per-sample random streams. They read the Truth's Mitsuba scene and its
    tile geometry.
    """

    def _rng(self, stream: int, st: "truth_samples.Samples"):
        """Return a PCG32 per sample of ``st``.

        Each is seeded by the scene's seed, a stream tag and the sample's index in the whole image:
        deterministic, and the same in a band as in one piece.
        """
        return common.stream_rng(self.scene.seed, stream, st.start, st.count)

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
        """Return the ``smooth`` shading normal at ``(x, y)``: the vertex normals' bilinear interpolation.

        See the module docstring, "Shading".
        """
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
        """Return the point ``o + maxt d``, wrapped back into the tile (``wrap`` only)."""
        c = self._c
        p = o + d * maxt
        return mi.Point3f(
            p.x - c["cols"] * dr.floor(p.x / c["cols"]), p.y - c["rows"] * dr.floor(p.y / c["rows"]), p.z
        )

    def _hop_length(self, o, d):
        """Return, per ray, how far ``o + t d`` runs over the mesh before its end could be off it.

        ``o`` is in the tile and the end is wrapped back into the tile: ``t`` to the nearer of the box ``[-e,
        cols + e] x [-e, rows + e]`` (``e`` = margin - 0.75: the mesh ends at margin - 0.5, a quarter texel
        kept for float32's rounding) in the ray's horizontal direction. At least :attr:`_hop` texels
        horizontally; a ray from inside the tile runs the tile's width or more, so a narrow margin costs hops
        only to the rays that leave near the tile's edge.
        """
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
        """Run ``hops`` hops of the rays ``o + t d`` and return ``(blocked, active, o)``.

        This is for ``wrap``, with ``o`` in the tile. ``blocked``: the rays that met the surface; ``active``:
        those still under its top after the last hop; ``o``: where they are, wrapped into the tile. With
        ``dynamic`` the hops stop once every ray is resolved.
        """
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


class PathTracing:
    """The truth's interreflection (a part of :class:`hzval.truth.plane.Truth`).

    It traces paths up to the scene's declared depth, as Mitsuba's ``path`` integrator would trace them on the
    displaced mesh.
    """

    def _path_trace(self, st: "truth_samples.Samples", L1, vis1, azimuth_deg: float):
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
        sc = self.scene
        light = sc.light
        E_sky = self._c["E_sky"]
        max_depth = int(sc.interreflection_depth)
        rng = self._rng(0x9A7 + 0x1000 * (int(round(azimuth_deg * 1000)) & 0xFFFF), st)
        first = self._rng(common.AMBIENT_STREAM, st)  # the ambient layer's directions at the first vertex
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
        p_spec = common.specular_sampling_share(sc)
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
            wo, weight = common.sample_bsdf(sc, ns, v, albedo, p_spec, u_lobe, u)
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
        """Return a direction toward the light for a later path vertex.

        It is the centre of a hard light, or a direction drawn uniformly from a soft light's cone
        (``cos_max``: cosine of its radius).
        """
        if self.scene.light.kind != "soft":
            return centre
        return mi.Frame3f(centre).to_world(
            mi.warp.square_to_uniform_cone(mi.Point2f(rng.next_float32(), rng.next_float32()), cos_max)
        )
