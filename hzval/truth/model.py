"""The ground truth on a model: Mitsuba 3 traces the displaced model, and the techniques' samples.

On the plane (:mod:`hzval.truth.plane`) the tangent frame is the world's. On a
model (:mod:`hzval.geometry.model`: a built-in shape or the user's UV-mapped mesh)
every point has its own: the interpolated vertex normal ``n`` and tangent
``t`` of the base mesh, re-orthonormalised, and ``b = w (n x t)``
(:mod:`hzval.geometry.tangents`). This module builds what both sides of a model's
sweep read:

The design in full: docs/internals.md, "hzval.truth.model".
"""

from __future__ import annotations

import functools
import math
import time

import numpy as np

from hzval.core import backend, budget, resources, shading
from hzval.core import conventions as cv
from hzval.core.backend import dr, mi
from hzval.core.conventions import normal_map
from hzval.core.errors import InputError
from hzval.geometry import displace, tangent_bugs
from hzval.geometry import tangents as tg
from hzval.scene import lookup
from hzval.scene.camera import Camera, View, view_axes
from hzval.scene.spec import EFFECTS, Frame, Scene, image_shape, light_samples
from hzval.truth import common
from hzval.truth.common import (
    LIFT_PER_HEIGHT,
    LIFT_TEXELS,
    REFLECTION_STREAM,
    lobe_sample,
    mean_and_variance,
    reflection_estimate,
    stream_rng,
)

__all__ = ["ModelTruth", "model_view", "SIMULATES"]

#: Effects the truth on a model simulates (interreflection: not yet).
SIMULATES: tuple[str, ...] = ("shadow", "diffuse", "specular", "ambient", "reflection_occlusion")
_AMBIENT_STREAM = 0xA3B1


def model_view(camera: Camera, points: np.ndarray, shape: tuple[int, int]) -> View:
    """Return the camera over a model whose displaced surface lies within ``points``.

    ``points`` is ``(N, 3)`` (world units). The camera looks from elevation/azimuth about the world's up axis
    (+z) as :meth:`hzval.scene.camera.Camera.view` looks at a tile (``top``: straight down).

    A perspective eye frames the points' bounding sphere: ``distance`` sphere diameters from its
    centre, or farther where the field of view needs it to hold the sphere. An orthographic film
    spans the points' projection, at the image's aspect, centred on it: on a unit quad whose UVs
    are its ``(x, y)`` these are the plane's own rays (its film is the tile), so the two agree
    pixel for pixel (``tests/truth/test_model.py``).
    """
    H, W = shape
    e = 90.0 if camera.kind == "top" else camera.elevation_deg
    a = -90.0 if camera.kind == "top" else camera.azimuth_deg
    w, up = view_axes(e, a)
    pts = np.asarray(points, float)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre = 0.5 * (lo + hi)
    R = max(float(np.linalg.norm(pts - centre, axis=1).max()), 1e-12)
    if camera.kind == "perspective":
        half = math.atan(math.tan(math.radians(camera.fov_deg) / 2.0) * min(1.0, H / W))
        dist = max(camera.distance * 2.0 * R, 1.02 * R / math.sin(half))
        return View(
            "perspective",
            tuple(centre + dist * w),
            tuple(centre),
            up,
            float(camera.fov_deg),
            None,
            (W, H),
            0,
            0,
            0.0,
            0.0,
            1,
        )
    f = -w
    r = np.cross(f, up)
    r /= np.linalg.norm(r)
    t = np.cross(r, f)
    pr, pt = pts @ r, pts @ t
    fw, fh = float(pr.max() - pr.min()), float(pt.max() - pt.min())
    film = (max(fw, fh * W / H, 1e-12), max(fh, fw * H / W, 1e-12))
    target = r * (0.5 * (pr.max() + pr.min())) + t * (0.5 * (pt.max() + pt.min())) + f * float(centre @ f)
    return View(
        "orthographic",
        tuple(target + (2.0 * R + 1.0) * w),
        tuple(target),
        up,
        None,
        film,
        (W, H),
        0,
        0,
        0.0,
        0.0,
        1,
    )


def _rays(o: np.ndarray, d: np.ndarray):
    """Return ``mi.Ray3f`` of host origins and directions ``(n, 3)``.

    The origins and directions are float64 (:meth:`hzval.scene.camera.View.rays`).
    """
    return mi.Ray3f(
        mi.Point3f(*(mi.Float(o[:, j].astype(np.float32)) for j in range(3))),
        mi.Vector3f(*(mi.Float(d[:, j].astype(np.float32)) for j in range(3))),
    )


def _welded_normals(model) -> np.ndarray:
    """Return ``(V, 3)``: each vertex's normal averaged over the vertices at its position.

    The vertices at a position are ``model.weld``'s. The average keeps a surface offset along the normals
    closed where the normals split (a cube's edges).
    """
    ids = model.weld
    sums = np.zeros((int(ids.max()) + 1, 3))
    np.add.at(sums, ids, model.normals)
    sums /= np.maximum(np.linalg.norm(sums, axis=1, keepdims=True), 1e-300)
    return sums[ids]


class _Traced:
    """A triangle mesh in its own ``mi.Scene`` and the base mesh's values at its vertices.

    The values are ``uvs``, ``normals``, ``tangents`` of ``frames``; ``p`` the base point, ``base_positions``
    where the mesh is the base mesh displaced. :meth:`at` interpolates them at a hit.
    """

    def __init__(self, name: str, positions: np.ndarray, faces: np.ndarray, frames):
        m = mi.Mesh(name, len(positions), len(faces), has_vertex_normals=False, has_vertex_texcoords=False)
        params = mi.traverse(m)
        params["vertex_positions"] = mi.Float(np.ascontiguousarray(positions, np.float32).ravel())
        params["faces"] = mi.UInt32(np.ascontiguousarray(faces, np.uint32).ravel())
        params.update()
        self.mesh = m
        self.scene = mi.load_dict({"type": "scene", "surface": m})
        self.triangles = int(len(faces))
        self._faces = mi.UInt32(np.ascontiguousarray(faces, np.uint32).ravel())

        def flat(a):
            return mi.Float(np.ascontiguousarray(a, np.float32).ravel())

        t = np.asarray(frames.tangents, np.float32)
        self._vertex = {
            "uv": flat(frames.uvs),
            "p": flat(frames.positions),
            "n": flat(frames.normals),
            "t": flat(t[:, :3]),
            "w": flat(t[:, 3]),
        }

    def at(self, prim, b1, b2):
        """Return ``f(key, size)``, which interpolates the vertex values ``key`` at a hit.

        ``size`` is the floats a vertex; ``f`` gives them at barycentrics ``(b1, b2)`` of the triangles
        ``prim`` (Mitsuba's: ``(1 - b1 - b2) p0 + b1 p1 + b2 p2``).
        """
        ids = [dr.gather(mi.UInt32, self._faces, prim * 3 + k) for k in range(3)]

        def value(key: str, size: int):
            kind = {1: mi.Float, 2: mi.Point2f, 3: mi.Vector3f}[size]
            a = [dr.gather(kind, self._vertex[key], i) for i in ids]
            return a[0] * (1.0 - b1 - b2) + a[1] * b1 + a[2] * b2

        return value


class ModelTruth:
    """The truth of one scene, height map and model (module docstring).

    It has the plane's :class:`hzval.truth.plane.Truth` interface: :meth:`render`, ``shape``, ``seen``,
    ``view``, ``simulated``, ``timings``, ``hits`` (``None``: the techniques' samples are :meth:`samples`),
    plus ``model`` (the base mesh) and ``plane_offset`` (world units along the normals from the base mesh to
    the techniques' surface, the lookup's plane).
    """

    hits = None
    keeps = True  # every sample's hit is kept between frames (budget.MODEL_BYTES_PER_SAMPLE)

    def __init__(self, scene: Scene, height: np.ndarray, model, *, albedo: np.ndarray | None = None):

        backend.variant()
        self.scene, self.model = scene.validate(), model
        self.built_elevation_deg = float(self.scene.light.elevation_deg)  # the lowest of a sweep's
        h = np.asarray(height, dtype=np.float32)
        self.rows, self.cols = rows, cols = h.shape
        self.shape = image_shape(rows, cols, scene.camera)
        self.spp = scene.spp
        unsupported = [e for e in scene.effects if e not in SIMULATES]
        if unsupported:
            raise InputError(
                scene.source or "scene",
                f"{', '.join(unsupported)} on a model: not simulated yet "
                f"(a model's truth simulates {', '.join(SIMULATES)})",
            )
        self.simulated = tuple(e for e in EFFECTS if e in scene.effects)
        self.timings: dict[str, float] = {}
        t0 = time.perf_counter()
        mat = scene.material
        self._check_fits(model, h)
        refined = displace.refine(
            model, (rows, cols), mat.boundary, height=h, depth=mat.depth, tolerance=mat.truth_tolerance
        )
        positions, faces = displace.displace(refined, h, mat.depth, model.world_per_uv, mat.boundary)
        self._texel = model.world_per_uv / cols  # world units per texel
        h_tex = cv.heights_in_texels(h, mat.depth)
        self._h_tex = h_tex
        self.lift = max(LIFT_TEXELS, LIFT_PER_HEIGHT * float(np.abs(h_tex).max())) * self._texel
        self._displaced = _Traced("displaced", positions, faces, refined)
        del positions, faces, refined
        # the techniques' surface: the base mesh at the lookup's plane (bottom: H = 0, as the truth's
        # base; mean; top), offset along its vertex normals as the plane sits at that height
        z0 = lookup.plane_height(scene.lookup, float(h_tex.min()), float(h_tex.max()), float(h_tex.mean()))
        self.plane_offset = z0 * self._texel
        self._surface = _Traced(
            "base", model.positions + _welded_normals(model) * self.plane_offset, model.faces, model
        )
        wrap = dr.WrapMode.Repeat if mat.boundary == "wrap" else dr.WrapMode.Clamp
        self._normal_map = mi.Texture2f(
            mi.TensorXf(np.ascontiguousarray(normal_map(h_tex, mat.boundary))),
            use_accel=False,
            migrate=False,
            filter_mode=dr.FilterMode.Linear,
            wrap_mode=wrap,
        )
        self._albedo = common.albedo_texels(scene, self.rows, self.cols, albedo)
        # the map's size opaque, as the plane's: one kernel for every map
        self._size = (dr.opaque(mi.Float, float(self.rows)), dr.opaque(mi.Float, float(self.cols)))
        # the displaced surface lies within the base mesh moved along its normals by the relief
        n_w = _welded_normals(model)
        extent = [model.positions + n_w * (float(z) * self._texel) for z in (h_tex.min(), h_tex.max())]
        self.view = model_view(scene.camera, np.concatenate(extent), self.shape)
        self.timings["mesh_s"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        self._trace_camera()
        self.timings["primary_s"] = (
            time.perf_counter()
            - t0
            - self.timings.get("ambient_s", 0.0)
            - self.timings.get("reflection_s", 0.0)
        )
        self._macro_key, self._macro_value = None, None

    def _check_fits(self, model, h: np.ndarray) -> None:
        """Refuse a displaced mesh and camera hits that would not fit in the memory available.

        The check comes before the mesh is built and counts its twisted cells' rings; the refusal is one line
        naming the tolerance.
        """
        mat = self.scene.material
        triangles, mesh_bytes = displace.estimate(
            model,
            (self.rows, self.cols),
            mat.boundary,
            height=h,
            depth=mat.depth,
            tolerance=mat.truth_tolerance,
        )
        samples = self.shape[0] * self.shape[1] * self.spp
        need = budget.model_truth_bytes(
            mesh_bytes, triangles, samples, self.scene.declares("reflection_occlusion")
        )
        resources.refuse_over(
            "--truth-tolerance",
            need,
            f"the displaced {model.source} ({triangles:.3g} triangles, with its camera hits)",
            "a larger tolerance, a smaller map or fewer --spp",
        )

    # -- camera rays, once ----------------------------------------------------------------------

    def _trace_camera(self) -> None:
        """Trace every sample's camera ray once, against the displaced model and the techniques' surface.

        The hit on the displaced model is the truth's; the one on the techniques' surface is theirs (where an
        engine shades). What the frames read there is kept. :attr:`seen`: the pixels all of whose samples hit
        both.
        """
        H, W = self.shape
        spp = self.spp
        o, d = self.view.rays(spp, self.scene.seed, 0, H * W)
        ray = _rays(o, d)
        del o, d
        self._st = self._hits(self._displaced, ray, shade=True)
        self._own = self._hits(self._surface, ray, shade=False)
        both = self._st["hit"] & self._own["hit"]
        dr.eval(both)
        backend.sync()
        seen = np.asarray(both, bool).reshape(H * W, spp)
        self.seen = seen.all(axis=1).reshape(H, W)
        self.seen_samples = seen.ravel()
        self._ambient = self._trace_ambient() if self.scene.declares("ambient") else None
        self._reflection = self._trace_reflection() if self.scene.declares("reflection_occlusion") else None

    def _hits(self, mesh: "_Traced", ray, *, shade: bool) -> dict:
        """Return where ``ray`` meets ``mesh`` and the values there.

        These are the point, its triangle's normal ``ng`` (on the side of the base normal), the frame
        (:func:`hzval.geometry.tangents.orthonormal`), the texel position ``(x, y)`` of its ``uv``, the base
        point ``pb`` and ``v`` toward the camera; ``shade``: also the shading normal (the normal map at ``uv``
        carried into the world) and the albedo there. A sample that misses keeps the world's frame at the
        texture's centre: traced, and counted for nothing.
        """
        pi = mesh.scene.ray_intersect_preliminary(ray, coherent=True)
        hit = pi.is_valid()
        prim = dr.select(hit, pi.prim_index, 0)
        at = mesh.at(prim, pi.prim_uv.x, pi.prim_uv.y)
        si = pi.compute_surface_interaction(ray)
        t, b, n = tg.orthonormal(at("n", 3), at("t", 3), at("w", 1))
        t, b, n = (
            dr.select(hit, a, mi.Vector3f(*e)) for a, e in ((t, (1, 0, 0)), (b, (0, 1, 0)), (n, (0, 0, 1)))
        )
        uv = dr.select(hit, at("uv", 2), mi.Point2f(0.5, 0.5))
        x, y = uv.x * self.cols, uv.y * self.rows  # texels, y up the image (hzval.core.conventions)
        if self.scene.material.boundary == "wrap":
            x, y = x - dr.floor(x / self.cols) * self.cols, y - dr.floor(y / self.rows) * self.rows
        out = {
            "p": si.p,
            "ng": dr.select(dr.dot(si.n, n) < 0.0, -si.n, si.n),
            "n": n,
            "t": t,
            "b": b,
            "hit": hit,
            "x": x,
            "y": y,
            "pb": at("p", 3),
            "v": -ray.d,
            "prim": prim,
        }
        if shade:
            # the texture's coordinates of the point (hzval.core.conventions owns the turn of y)
            nt = dr.normalize(
                mi.Vector3f(*self._normal_map.eval(mi.Point2f(*cv.tangent_to_uv(x, y, self.rows, self.cols))))
            )
            out["ns"] = dr.normalize(t * nt.x + b * nt.y + n * nt.z)
            if self._albedo is not None:
                out["albedo"] = self._albedo_at(x, y)
        dr.eval(out)
        return out

    @property
    def displaced_mesh(self):
        """The displaced model the truth traces, as a Mitsuba mesh (``export-scene`` writes it)."""
        return self._displaced.mesh

    def _albedo_at(self, x, y):
        """Return the albedo at ``(x, y)``, nearest, as on the plane.

        See :func:`hzval.truth.common.albedo_at`.
        """
        return common.albedo_at(self._albedo, *self._size, x, y)

    def _origin(self, p, n):
        """Return a ray's start: ``p`` lifted along the base normal ``n`` (module docstring)."""
        return p + n * self.lift

    def _trace_ambient(self):
        """Trace ``A`` per sample: a cosine-weighted direction about the shading normal escapes (once)."""
        t0 = time.perf_counter()
        st = self._st
        count = dr.width(st["hit"])
        rng = mi.PCG32(
            size=count,
            initstate=dr.arange(mi.UInt64, count),
            initseq=mi.UInt64(self.scene.seed) ^ _AMBIENT_STREAM,
        )
        d = mi.Frame3f(st["ns"]).to_world(
            mi.warp.square_to_cosine_hemisphere(mi.Point2f(rng.next_float32(), rng.next_float32()))
        )
        into = (dr.dot(st["ng"], d) <= 0.0) | (dr.dot(st["n"], d) <= 0.0)
        ray = mi.Ray3f(self._origin(st["p"], st["n"]), d)
        blocked = into | self._displaced.scene.ray_test(ray, active=st["hit"] & ~into)
        A = dr.select(blocked, 0.0, 1.0)
        dr.eval(A)
        self.timings["ambient_s"] = time.perf_counter() - t0
        return A

    def _trace_reflection(self) -> tuple[np.ndarray, np.ndarray]:
        """Return ``R`` per pixel and its variance ``(H, W)``.

        ``R`` is the share of the glossy lobe about each hit's shading normal, seen from its own ``v``, that
        escapes the displaced model (module docstring; the plane's estimator and random streams, sample for
        sample where the rays are the plane's).
        """
        t0 = time.perf_counter()
        st = self._st
        count = dr.width(st["hit"])
        rng = stream_rng(self.scene.seed, REFLECTION_STREAM, 0, count)
        wo, w = lobe_sample(st["ns"], st["v"], mi.Point2f(rng.next_float32(), rng.next_float32()))
        into = (dr.dot(st["ng"], wo) <= 0.0) | (dr.dot(st["n"], wo) <= 0.0)
        ray = mi.Ray3f(self._origin(st["p"], st["n"]), wo)
        blocked = into | self._displaced.scene.ray_test(ray, active=st["hit"] & ~into)
        R, var = reflection_estimate(dr.select(st["hit"], w, 0.0), dr.select(blocked, 0.0, 1.0), self.spp)
        self.timings["reflection_s"] = time.perf_counter() - t0
        return R.reshape(self.shape), var.reshape(self.shape)

    # -- frames ---------------------------------------------------------------------------------

    def _light(self, azimuth_deg: float):
        """Every sample's direction toward the light (world), and whether any is above the horizon."""
        light = self.scene.light
        if light.kind == "hard":
            return dr.opaque(mi.Vector3f, [float(c) for c in light.direction(azimuth_deg)])
        count = dr.width(self._st["hit"])
        s = np.ascontiguousarray(light_samples(light, azimuth_deg, count, self.scene.seed), np.float32)
        return dr.gather(mi.Vector3f, mi.Float(s.ravel()), dr.arange(mi.UInt32, count))

    def light_at(self, elevation_deg: float) -> None:
        """Light the frames that follow from ``elevation_deg`` (:func:`hzval.truth.common.relight`)."""
        common.relight(self, elevation_deg)

    def render(self, azimuth_deg: float) -> Frame:
        """Return the frame of the light at ``azimuth_deg`` (degrees, about the world's up axis).

        The elevation is the scene's. The layers are :meth:`hzval.truth.plane.Truth.render`'s, ``mask`` the
        seen pixels.
        """
        t0 = time.perf_counter()
        sc, st = self.scene, self._st
        L = self._light(azimuth_deg)
        sums = {}
        vis = None
        if sc.declares("shadow"):
            away = (dr.dot(st["ng"], L) <= 0.0) | (dr.dot(st["n"], L) <= 0.0)
            ray = mi.Ray3f(self._origin(st["p"], st["n"]), L)
            vis = dr.select(away | self._displaced.scene.ray_test(ray, active=st["hit"] & ~away), 0.0, 1.0)
            sums["visibility"] = vis
        img = None
        if any(sc.declares(e) for e in ("diffuse", "specular", "ambient")):
            E = float(sc.light.irradiance)
            if sc.light.kind == "soft":
                E = shading.disk_sample_irradiance(E, sc.light.radius_deg)
            img = shading.direct(
                st["ns"],
                L,
                st["v"],
                st.get("albedo"),
                dr.opaque(mi.Float, E),
                diffuse=sc.declares("diffuse"),
                specular=sc.declares("specular"),
            )
            img = dr.select(dr.dot(st["n"], L) > 0.0, img, 0.0)  # the base surface's horizon
            if vis is not None:
                img = img * vis
            if self._ambient is not None:
                img = img + shading.sky(
                    st["albedo"], self._ambient, dr.opaque(mi.Float, float(sc.light.irradiance))
                )
        if self._ambient is not None:
            sums["ambient"] = self._ambient
        layers, variance = self._reduce(sums, img)
        H, W = self.shape
        image = layers.pop("image", None)
        if self._reflection is not None:
            layers["reflection_occlusion"], variance["reflection_occlusion"] = self._reflection
        if image is None:
            v = layers.get("visibility", np.ones((H, W), np.float32))
            image = np.repeat((float(sc.light.irradiance) * v)[..., None], 3, axis=-1).astype(np.float32)
            var = variance.get("visibility", np.zeros((H, W), np.float32))
            variance["image"] = np.repeat((float(sc.light.irradiance) ** 2 * var)[..., None], 3, axis=-1)
        return Frame(
            azimuth_deg=float(azimuth_deg),
            elevation_deg=float(sc.light.elevation_deg),
            image=image,
            layers=layers,
            variance=variance,
            seconds=time.perf_counter() - t0,
            mask=self.seen,
        )

    def _reduce(self, sums: dict, img) -> tuple[dict, dict]:
        """Reduce the 0/1 layers ``sums`` and radiance ``img`` to pixel means and variances of the mean.

        See :func:`hzval.truth.common.mean_and_variance`; each is ``(H, W[, 3])`` float32.
        """
        spp, (H, W) = self.spp, self.shape
        reduced = {k: dr.block_sum(v, spp) for k, v in sums.items()}
        if img is not None:
            img_sum = dr.block_sum(img, spp)
            pixel = dr.arange(mi.UInt32, dr.width(self._st["hit"])) // spp
            dev = img - dr.gather(mi.Color3f, img_sum, pixel) * (1.0 / spp)
            reduced["image"], reduced["image_ss"] = img_sum, dr.block_sum(dev * dev, spp)
        dr.eval(reduced)
        layers, variance = {}, {}
        for k in sums:
            s1 = mi.Float64(reduced[k])
            mean, var = mean_and_variance(s1, s1 * (1.0 - s1 / spp), spp)
            layers[k], variance[k] = (np.asarray(a, np.float32).reshape(H, W) for a in (mean, var))
        if img is not None:
            parts = [
                mean_and_variance(mi.Float64(c), mi.Float64(q), spp)
                for c, q in zip(reduced["image"], reduced["image_ss"])
            ]
            layers["image"] = np.stack([np.asarray(m, np.float32) for m, _ in parts], -1).reshape(H, W, 3)
            variance["image"] = np.stack([np.asarray(v, np.float32) for _, v in parts], -1).reshape(H, W, 3)
        backend.sync()
        return layers, variance

    # -- what the techniques read ---------------------------------------------------------------

    def macro(self, direction) -> object:
        """Return the base mesh's own visibility of the world direction ``direction`` per sample.

        It is a ``mi.Float``, 0 or 1: a shadow ray from the base point against the undisplaced model, which an
        engine's shadow map answers. The last direction's is kept: every technique of a frame reads it.
        """
        key = tuple(float(c) for c in direction)
        if self._macro_key != key:
            st = self._own
            L = dr.opaque(mi.Vector3f, list(key))
            away = dr.dot(st["n"], L) <= 0.0
            ray = mi.Ray3f(self._origin(st["p"], st["n"]), L)
            M = dr.select(away | self._surface.scene.ray_test(ray, active=st["hit"] & ~away), 0.0, 1.0)
            dr.eval(M)
            self._macro_key, self._macro_value = key, M
        return self._macro_value

    def macro_shadowed(self, azimuth_deg: float) -> float:
        """Return the share of the seen pixels' samples that face the light but that the base mesh shadows.

        Facing the light is ``n.L > 0``. This is what the engine's shadow map, not the technique, decides
        (``metrics.json``).
        """
        direction = self.scene.light.direction(azimuth_deg)
        M = self.macro(direction)
        L = mi.Vector3f(*(float(c) for c in direction))
        dark = dr.select((dr.dot(self._own["n"], L) > 0.0) & (M < 0.5), 1.0, 0.0)
        per_sample = np.asarray(dark, np.float32).reshape(-1, self.spp)
        seen = self.seen.ravel()
        return float(per_sample[seen].mean()) if seen.any() else 0.0

    @functools.cached_property
    def handedness(self) -> np.ndarray:
        """Return ``(H, W)`` int8: the sign ``w`` of the correct frames per pixel.

        ``w`` is :func:`hzval.geometry.tangents.handedness`'s: -1 where the UVs are mirrored. It is given
        where every sample of a seen pixel has it, 0 elsewhere (a pixel across a mirror seam, or unseen). A
        tangent bug does not change it.
        """
        t, b, n = (np.stack([np.asarray(c, np.float64) for c in self._own[k]], -1) for k in ("t", "b", "n"))
        w = tg.handedness(t, b, n).reshape(-1, self.spp)
        sign = np.where((w < 0).all(axis=1), -1, np.where((w > 0).all(axis=1), 1, 0)).reshape(self.shape)
        return np.where(self.seen, sign, 0).astype(np.int8)

    def samples(self, at: str = "camera") -> lookup.Samples:
        """Return the techniques' :class:`hzval.scene.lookup.Samples`, with their frames.

        They lie where the camera's rays meet their surface (``"camera"``, as an engine shades: moved by the
        lookup's parallax mapping along each ray in its sample's tangent frame, with each pixel's footprint
        for a mip filter), or at the truth's own hits (``"truth"``: perfect parallax, a view's second set of
        scores).
        """
        st = self._own if at == "camera" else self._st
        xy = np.stack([np.asarray(st["x"], np.float64), np.asarray(st["y"], np.float64)], -1)
        frames = np.stack([np.asarray(c, np.float32) for k in ("t", "b", "n", "v") for c in st[k]], axis=-1)
        frames = self._engine_frames(frames)
        lk, h = self.scene.lookup, self._h_tex
        z0 = lookup.plane_height(lk, float(h.min()), float(h.max()), float(h.mean()))
        if at == "camera" and lk.parallax != "none":
            d = -frames[:, 9:12].astype(np.float64)  # the camera's ray, world
            d_t = np.stack([np.sum(frames[:, 3 * k : 3 * k + 3] * d, axis=1) for k in range(3)], -1)
            tex = lookup.height_texture(h, self.scene.material.boundary)
            xy = lookup.parallax_lookup(lk, tex, xy, d_t, z0, float(h.min()), float(h.max()))
        if self.scene.material.boundary == "wrap":
            xy = np.mod(xy, [self.cols, self.rows])
        else:
            xy = np.clip(xy, 0.0, [self.cols, self.rows])
        footprint = self._footprints() if lk.mipmapped else None
        return lookup.Samples(
            xy[:, 0].astype(np.float32),
            xy[:, 1].astype(np.float32),
            self.rows,
            self.cols,
            int(self.spp),
            footprint,
            z0,
            source=at,
            frames=frames,
            macro=self.macro,
        )

    def base_points(self) -> np.ndarray:
        """Return the base mesh's point (world) under every sample's truth hit.

        The result is ``(pixels * spp, 3)`` float64: the point whose uv and frame the hit keeps (NaN where the
        sample misses).
        """
        p = np.stack([np.asarray(c, np.float64) for c in self._st["pb"]], -1)
        p[~np.asarray(self._st["hit"], bool)] = np.nan
        return p

    def _engine_frames(self, frames: np.ndarray) -> np.ndarray:
        """Return the techniques' frames with the scene's tangent bug (:mod:`hzval.geometry.tangent_bugs`).

        With ``none`` they are ``frames`` themselves. ``per-face`` takes the base triangle the camera's ray
        meets on the techniques' surface, for the truth's hits too (the same ray's, which differs from the
        displaced hit's base triangle only within the relief's height of an edge).
        """
        bug = self.scene.mesh.tangent_bug
        prim = self._own["prim"]
        return tangent_bugs.apply(
            bug, frames, lambda: tangent_bugs.face_frames_at(self.model, np.asarray(prim, np.int64))
        )

    def _footprints(self) -> np.ndarray:
        """Return, per pixel, how far the texel seen on the techniques' surface moves to the next pixel.

        See :meth:`hzval.scene.camera.View.footprints`, with the surface's hits for the plane's points;
        ``wrap`` across the tile the short way; NaN where a ray misses.
        """

        def points(o, d):
            ray = _rays(o, d)
            hit = self._hits(self._surface, ray, shade=False)
            xy = np.stack([np.asarray(hit["x"], np.float64), np.asarray(hit["y"], np.float64)], -1)
            return xy, np.asarray(hit["hit"], bool)

        wrap = self.scene.material.boundary == "wrap"
        return self.view.footprints(points=points, period=(self.cols, self.rows) if wrap else None)

    def record(self) -> dict:
        """``metrics.json``'s ``mesh``: the base mesh's record and the displaced mesh's size."""
        return {
            **self.model.record(),
            "displaced_triangles": self._displaced.triangles,
            "seen_fraction": float(self.seen.mean()),
        }
