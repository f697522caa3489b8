"""An independent check of hzval's ground-truth visibility for any camera (oblique, perspective, top).

hzval writes a sweep report folder ``SWEEP_DIR`` (``metrics.json``, ``frames.json`` and one
folder per light). This script rebuilds the camera rays from the camera record in
``metrics.json``, marches them into the height field with its own NumPy code, marches a shadow
ray from every hit toward the light, and compares its per-pixel visibility ``V`` with hzval's
``visibility.exr`` of every frame::

    python tests/oracles/march_check.py SWEEP_DIR [--spp 4] [--tolerance 0.035] [--frames all|first]
                                               [--height PATH_OR_BUILTIN] [--seed 0] [--lift 1e-3]

It prints, per frame, the mean ``|V_hzval - V_march|`` over the pixels both sides see and the
seen-pixel counts, then the overall mean (pooled over the compared pixels of all frames), and
exits 1 (one line) when that exceeds ``--tolerance``, or when the folder cannot be checked.

Model (hzval's conventions, tangent-space texel units)
------------------------------------------------------
* Heights ``z = H * depth * cols`` (float32, as hzval computes them, then float64 here).
  Texel ``(row, col)`` has its centre at ``x = col + 0.5``, ``y = rows - row - 0.5``; ``+z`` out
  of the surface.
* The surface is the **bilinear** height field through the texel-centre heights: on each quad of
  neighbouring centres ``(x0, y0) .. (x0 + 1, y0 + 1)``, ``z = z00 + a fx + b fy + c fx fy`` with
  ``fx, fy`` the offsets inside the quad (the surface the techniques' bilinear filter reads, and
  the one hzval's mesh approximates to its ``truth_tolerance``, docs/truth-surface.md). The two
  sides should agree to the sampling noise and that tolerance.
* ``wrap``: the tile repeats endlessly in x and y. ``open``: the tile alone covers
  ``[0, cols] x [0, rows]``; between the border and the outermost centres (half a texel) the
  surface is flat at the edge heights; outside there is nothing (a camera ray that leaves sees
  nothing, a shadow ray that leaves escapes).
* Camera (``metrics["camera"]``): ``resolution = [cols, rows]`` of the image, row 0 at the top;
  ``u = 2 (col + s) / cols - 1``, ``v = 1 - 2 (row + s) / rows`` with ``s = 0.5`` for one
  sample per pixel, else a jitter in ``[0, 1)`` (stratified on a ``k x k`` grid when ``spp = k^2``,
  uniform otherwise); ``f = normalize(target - eye)``, ``r = normalize(f x up)``, ``t = r x f``.
  ``perspective``: rays leave ``eye`` along ``normalize(f + u tan(fov/2) r + v tan(fov/2)
  (rows/cols) t)``, ``fov_deg`` horizontal. ``orthographic`` and ``top``: rays leave
  ``eye + u (w/2) r + v (h/2) t`` along ``f``, ``film_size = [w, h]`` texels.
* Light: ``L = (cos e cos phi, cos e sin phi, sin e)`` toward the light, from each frame's
  ``azimuth_deg`` and ``elevation_deg`` (cross-checked against ``frames.json``'s
  ``light_direction``). A hard (directional) light; for a ``soft`` light the centre direction
  is used and a note says so (the soft penumbrae then count as disagreement).
* Visibility of a hit: 0 if ``L.z <= 0``; 0 if the bilinear surface's own normal there faces
  away from the light (``n.L <= 0``, self-shadow); else the shadow ray from ``(x, y, surface + lift)``
  toward ``L`` is occluded (0) if it is anywhere below the surface before it rises above the
  highest point (``open``: or leaves the tile, then it escapes); else 1. A pixel's ``V`` is the
  mean over its samples.

The march
---------
Exact and step-free: along a ray the bilinear field is a quadratic in ``t`` between the ray's
crossings of the two families of cell edges (``x - 0.5 = k``, ``y - 0.5 = k``), so ``f(t) = ray_z(t)
- surface(t)`` is a quadratic there too. All rays advance together (NumPy, chunks of :data:`CHUNK`
rays, the finished ones compacted away) from crossing to crossing, a two-way merge of arithmetic
sequences; each piece takes its cell from its midpoint and its quadratic measured from the piece's
start; the first root in a piece (the stable quadratic formula) is the hit, and a shadow ray is
blocked where the piece's ends or its parabola's lowest point are below the surface. Camera rays
start where they descend to ``z_max`` (or at the eye, if it is below; a ray above ``z_max`` that
does not descend misses) and end where they reach ``z_min`` (``open``: or leave the tile). A camera
ray that enters *below* the surface (the side of an ``open`` tile, or an eye under it) hits where
it first comes back through it (the underside; such hits are counted in ``underside``). A ray
that neither descends nor rises above the relief is given up after :data:`MAX_TILES` tile
widths.

Compared with hzval
-------------------
Only the pixels that both sides see entirely are compared: hzval's NaN pixels (its camera saw no
surface), the pixels where this march sees no surface with any sample, and the pixels where it
sees the surface with only some of its samples (a silhouette) are left out and counted, and the
pixels where the two sides disagree on seen/unseen are counted.

What it does not share with hzval: it imports none of ``hzval.truth.plane``, ``hzval.scene.camera``,
``hzval.scene.spec``, ``hzval.scene.lookup``, ``hzval.geometry.tile`` or ``hzval.techniques.horizon``; the
camera model, the
sample positions (its own jitter and seed, so it differs from hzval's samples by sampling noise),
the surface evaluation, the ray traversal and intersection (hzval's is Mitsuba's BVH on a float32
mesh, with a wrap margin and hops), the shadow-ray offset and the light direction are computed
here from the report's numbers alone. It shares the normalised height map (read with
``hzval.io.heightmap``, a built-in regenerated with ``hzval.materials`` and its digest checked
against the report's) and ``hzval.io.codecs.read_exr``.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
import time
from pathlib import Path

import numpy as np

#: Rays marched at once (memory: a few hundred bytes a ray).
CHUNK = 1 << 20
#: Default offset of a shadow ray's start above the surface, in texels.
LIFT = 1e-3
#: Camera rays run on to this many texels below the lowest point (so rounding cannot miss a flat map).
BELOW = 1e-6
#: A ray that neither descends nor rises above the relief is given up after this many tile widths.
MAX_TILES = 4.0
#: Kinds of camera record that have orthographic rays.
ORTHOGRAPHIC = ("orthographic", "top")


class CheckError(Exception):
    """A sweep folder that cannot be checked; the CLI prints it as one line."""


# --------------------------------------------------------------------------
# Camera
# --------------------------------------------------------------------------


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / n


def camera_frame(record: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(f, r, t)``: forward, right and the film's up, unit vectors of a camera record."""
    eye = np.asarray(record["eye"], dtype=np.float64)
    target = np.asarray(record["target"], dtype=np.float64)
    up = np.asarray(record["up"], dtype=np.float64)
    f = target - eye
    if not np.linalg.norm(f) > 0:
        raise CheckError("camera: eye and target coincide")
    f = _unit(f)
    r = np.cross(f, up)
    if not np.linalg.norm(r) > 1e-12:
        raise CheckError("camera: up is parallel to the viewing direction")
    r = _unit(r)
    t = np.cross(r, f)
    return f, r, t


def _jitter(spp: int, n_pixels: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``(n_pixels, spp)`` offsets in ``[0, 1)`` along columns and rows: 0.5 for one sample, a
    jittered ``k x k`` grid for ``spp = k^2``, uniform otherwise."""
    if spp == 1:
        half = np.full((n_pixels, 1), 0.5)
        return half, half.copy()
    k = math.isqrt(spp)
    if k * k == spp:
        s = np.arange(spp)
        sx = (s % k + rng.random((n_pixels, spp))) / k
        sy = (s // k + rng.random((n_pixels, spp))) / k
        return sx, sy
    return rng.random((n_pixels, spp)), rng.random((n_pixels, spp))


def image_shape(record: dict) -> tuple[int, int]:
    """``(rows, cols)`` of the image of a camera record (whose ``resolution`` is ``[cols, rows]``)."""
    cols, rows = (int(n) for n in record["resolution"])
    return rows, cols


def camera_rays(record: dict, spp: int = 4, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Origins and unit directions ``(N, 3)`` of the camera rays of a ``metrics["camera"]`` record.

    ``N = rows * cols * spp``, pixel-major: ray ``(row * cols + col) * spp + s`` is sample ``s``
    of pixel ``(row, col)``. ``spp = 1`` shoots through the pixel centres.
    """
    if spp < 1:
        raise ValueError(f"spp must be at least 1, got {spp}")
    kind = record.get("kind")
    rows, cols = image_shape(record)
    f, r, t = camera_frame(record)
    eye = np.asarray(record["eye"], dtype=np.float64)
    rng = np.random.default_rng([int(seed), 0x3A7C])
    sx, sy = _jitter(spp, rows * cols, rng)
    pix = np.arange(rows * cols)
    col = (pix % cols)[:, None] + sx
    row = (pix // cols)[:, None] + sy
    u = (2.0 * col / cols - 1.0).ravel()[:, None]
    v = (1.0 - 2.0 * row / rows).ravel()[:, None]
    if kind == "perspective":
        fov = record.get("fov_deg")
        if fov is None or not 0 < float(fov) < 180:
            raise CheckError(f"camera: a perspective camera needs fov_deg in (0, 180), got {fov!r}")
        tan = math.tan(math.radians(float(fov)) / 2)
        dirs = _unit(f + u * tan * r + v * (tan * rows / cols) * t)
        origins = np.broadcast_to(eye, dirs.shape).copy()
    elif kind in ORTHOGRAPHIC:
        film = record.get("film_size")
        if film is None:
            raise CheckError(f"camera: a {kind} camera needs film_size")
        w, h = (float(x) for x in film)
        origins = eye + u * (w / 2) * r + v * (h / 2) * t
        dirs = np.broadcast_to(f, origins.shape).copy()
    else:
        raise CheckError(f"camera: unknown kind {kind!r} (expected perspective, orthographic or top)")
    return origins, dirs


# --------------------------------------------------------------------------
# The height field
# --------------------------------------------------------------------------
#
# Internally the surface lives on the lattice of texel centres: X = x - 0.5, Y = y - 0.5, so that
# the centre of texel (row, col) is the lattice point (X, Y) = (col, rows - 1 - row), and
# G[j, i] = h[rows - 1 - j, i] is the height at lattice point (i, j). The quad (cell) (i, j)
# covers [i, i+1] x [j, j+1]; its diagonal runs from (i, j) to (i+1, j+1).


class _Field:
    """Heights on the lattice of texel centres, with the boundary's index rule."""

    def __init__(self, height_texels: np.ndarray, boundary: str):
        h = np.asarray(height_texels, dtype=np.float64)
        if h.ndim != 2 or min(h.shape) < 2:
            raise ValueError(f"height must be a 2-D array of at least 2x2, got shape {h.shape}")
        if boundary not in ("wrap", "open"):
            raise ValueError(f"unknown boundary {boundary!r} (expected wrap or open)")
        self.G = np.ascontiguousarray(h[::-1])
        self.flat = self.G.ravel()
        self.ny, self.nx = self.G.shape
        self.wrap = boundary == "wrap"
        self.zmin = float(h.min())
        self.zmax = float(h.max())
        #: rounding scale of f = ray z - surface z, in texels
        self.eps = 1e-9 * max(1.0, abs(self.zmin), abs(self.zmax))
        # open: the tile in lattice coordinates
        self.box = (-0.5, self.nx - 0.5, -0.5, self.ny - 0.5)

    def corners(self, i: np.ndarray, j: np.ndarray):
        """Heights ``z00, z10, z01, z11`` of cells ``(i, j)`` (int64 arrays)."""
        nx, ny = self.nx, self.ny
        if self.wrap:
            i0, j0 = i % nx, j % ny
            i1, j1 = (i0 + 1) % nx, (j0 + 1) % ny
        else:  # the flat skirt: clamped indices repeat the edge heights
            i0, i1 = np.clip(i, 0, nx - 1), np.clip(i + 1, 0, nx - 1)
            j0, j1 = np.clip(j, 0, ny - 1), np.clip(j + 1, 0, ny - 1)
        r0, r1 = j0 * nx, j1 * nx
        g = self.flat
        return g[r0 + i0], g[r0 + i1], g[r1 + i0], g[r1 + i1]

    def patch(self, X: np.ndarray, Y: np.ndarray):
        """The bilinear patch holding lattice points ``(X, Y)``: ``(i, j, z00, a, b, c)`` with
        ``z = z00 + a fx + b fy + c fx fy``, ``fx = X - i``, ``fy = Y - j`` (``c`` the cell's twist)."""
        i = np.floor(X)
        j = np.floor(Y)
        z00, z10, z01, z11 = self.corners(i.astype(np.int64), j.astype(np.int64))
        return i, j, z00, z10 - z00, z01 - z00, z00 - z10 - z01 + z11

    def inside(self, X: np.ndarray, Y: np.ndarray) -> np.ndarray:
        if self.wrap:
            return np.ones(np.shape(X), bool)
        x0, x1, y0, y1 = self.box
        return (X >= x0) & (X <= x1) & (Y >= y0) & (Y <= y1)

    def box_span(self, O: np.ndarray, D: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(t_in, t_out)`` of rays through the open tile's box (``t_in > t_out``: they miss)."""
        x0, x1, y0, y1 = self.box
        lo = np.full(len(O), -np.inf)
        hi = np.full(len(O), np.inf)
        for axis, (b0, b1) in enumerate(((x0, x1), (y0, y1))):
            o, d = O[:, axis], D[:, axis]
            with np.errstate(divide="ignore", invalid="ignore"):
                ta, tb = (b0 - o) / d, (b1 - o) / d
            still = d == 0
            t_lo = np.where(still, np.where((o >= b0) & (o <= b1), -np.inf, np.inf), np.minimum(ta, tb))
            t_hi = np.where(still, np.where((o >= b0) & (o <= b1), np.inf, -np.inf), np.maximum(ta, tb))
            lo, hi = np.maximum(lo, t_lo), np.minimum(hi, t_hi)
        return lo, hi


def _crossings(o: np.ndarray, d: np.ndarray, t: np.ndarray):
    """Next crossing of integer lines by ``o + t d`` after ``t``: ``(k, step, t_next)``."""
    p = o + t * d
    s = np.sign(d)
    k = np.where(s > 0, np.floor(p) + 1, np.where(s < 0, np.ceil(p) - 1, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        tn = np.where(s != 0, (k - o) / d, np.inf)
    return k, s, tn


def _march(field: _Field, O: np.ndarray, D: np.ndarray, t0: np.ndarray, t1: np.ndarray, first: bool):
    """March lattice-coordinate rays ``O + t D`` over ``t0 <= t <= t1``.

    ``first``: return ``(t_hit, underside)``, the first ``t`` at which the ray passes through the
    surface (NaN if none; ``underside`` where it entered below it). Otherwise return a bool
    array: whether the ray is anywhere strictly below the surface (``f < 0``).
    """
    n = len(O)
    t_hit = np.full(n, np.nan)
    under = np.zeros(n, bool)
    blocked = np.zeros(n, bool)
    idx = np.flatnonzero(t0 <= t1)
    if len(idx) == 0:
        return (t_hit, under) if first else blocked
    ox, oy, oz = O[idx, 0].copy(), O[idx, 1].copy(), O[idx, 2].copy()
    dx, dy, dz = D[idx, 0].copy(), D[idx, 1].copy(), D[idx, 2].copy()
    tc, tend = t0[idx].astype(np.float64), t1[idx].astype(np.float64)
    kx, sx, tx = _crossings(ox, dx, tc)
    ky, sy, ty = _crossings(oy, dy, tc)
    sign0 = np.zeros(len(idx))  # the side of the surface the ray starts on (first mode)
    state = [idx, ox, oy, oz, dx, dy, dz, tc, tend, kx, sx, tx, ky, sy, ty, sign0]
    fresh = True
    while len(state[0]):
        idx, ox, oy, oz, dx, dy, dz, tc, tend, kx, sx, tx, ky, sy, ty, sign0 = state
        tn = np.minimum(np.minimum(tx, ty), tend)
        c0, c1, c2 = _piece(field, ox, oy, oz, dx, dy, dz, tc, tn)
        span = tn - tc
        fc = c0
        fn = c0 + span * (c1 + span * c2)
        if first:
            if fresh:
                # below only by more than rounding (a ray started on z_max over a flat map is above)
                sign0 = np.where(fc < -field.eps, -1.0, 1.0)
                at_start = fc == 0
            else:
                at_start = np.zeros(len(idx), bool)
            s_hit = _first_root(c0, c1, c2, span)
            crossed = at_start | np.isfinite(s_hit) | (sign0 * fn <= 0)
            if crossed.any():
                with np.errstate(divide="ignore", invalid="ignore"):
                    w = np.clip(np.where(fc != fn, fc / (fc - fn), 0.0), 0.0, 1.0)
                # no root in the piece by rounding, yet a change of sign: the chord's
                th = tc + np.where(np.isfinite(s_hit), s_hit, span * w)
                th = np.where(at_start, tc, th)
                t_hit[idx[crossed]] = th[crossed]
                under[idx[crossed]] = sign0[crossed] < 0
            done = crossed | (tn >= tend)
        else:
            with np.errstate(divide="ignore", invalid="ignore"):
                sv = np.where(c2 > 0, -c1 / (2.0 * c2), -1.0)  # the parabola's lowest point
            inner = (sv > 0) & (sv < span)
            fv = np.where(inner, c0 + sv * (c1 + sv * c2), np.inf)
            below = (fn < 0) | (fc < 0) | (fv < 0)
            blocked[idx[below]] = True
            done = below | (tn >= tend)
        fresh = False
        # advance past the crossing(s) at tn
        hit_x, hit_y = tx <= tn, ty <= tn
        kx = kx + np.where(hit_x, sx, 0.0)
        ky = ky + np.where(hit_y, sy, 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            tx = np.where(hit_x, (kx - ox) / dx, tx)
            ty = np.where(hit_y, (ky - oy) / dy, ty)
        tc = tn
        state = [idx, ox, oy, oz, dx, dy, dz, tc, tend, kx, sx, tx, ky, sy, ty, sign0]
        if done.any():
            keep = ~done
            state = [s[keep] for s in state]
    return (t_hit, under) if first else blocked


def _piece(field: _Field, ox, oy, oz, dx, dy, dz, tc, tn):
    """``f(s) = ray z - surface z = c0 + c1 s + c2 s^2`` for ``s = t - tc`` on the piece ``[tc, tn]``
    of each ray, inside one cell (found at the piece's midpoint): the bilinear patch along a line is
    a quadratic (``c2 = -c dx dy``), here measured from the piece's start for its rounding's sake."""
    tm = 0.5 * (tc + tn)
    i, j, z00, a, b, c = field.patch(ox + tm * dx, oy + tm * dy)
    px, py = ox + tc * dx - i, oy + tc * dy - j
    c0 = oz + tc * dz - (z00 + a * px + b * py + c * px * py)
    c1 = dz - a * dx - b * dy - c * (px * dy + py * dx)
    c2 = -c * dx * dy
    return c0, c1, c2


def _first_root(c0, c1, c2, span):
    """The smallest ``s`` in ``[0, span]`` with ``c0 + c1 s + c2 s^2 = 0`` (NaN if none): the stable
    form of the quadratic formula (Numerical Recipes 5.6), the linear root where ``c2`` is 0."""
    with np.errstate(divide="ignore", invalid="ignore"):
        disc = c1 * c1 - 4.0 * c2 * c0
        sq = np.sqrt(np.maximum(disc, 0.0))
        q = -0.5 * (c1 + np.where(c1 >= 0, sq, -sq))
        quad = c2 != 0
        r1 = np.where(quad, q / c2, np.where(c1 != 0, -c0 / c1, np.nan))
        r2 = np.where(quad, c0 / q, np.nan)
        # a root a rounding's width before the piece's start is at its start
        slack = 1e-12 * (1.0 + span)

        def ok(r):
            return (disc >= 0) & np.isfinite(r) & (r >= -slack) & (r <= span)

        r1, r2 = np.where(ok(r1), r1, np.inf), np.where(ok(r2), r2, np.inf)
    r = np.clip(np.minimum(r1, r2), 0.0, None)
    return np.where(np.isfinite(r), r, np.nan)


def _to_lattice(P: np.ndarray) -> np.ndarray:
    Q = np.array(P, dtype=np.float64, copy=True)
    Q[:, :2] -= 0.5
    return Q


def march_hits(
    height_texels: np.ndarray,
    boundary: str,
    origins: np.ndarray,
    dirs: np.ndarray,
    *,
    return_underside: bool = False,
):
    """First intersections of rays with the height field: ``(points (N, 3), hit (N,) bool)``.

    ``height_texels``: ``(rows, cols)`` heights in texels (row 0 at the top); ``origins`` and
    ``dirs`` in tangent space (``x = col + 0.5`` at texel centres). Points of misses are NaN.
    ``return_underside`` adds a third array: the hits of rays that entered below the surface.
    """
    field = _Field(height_texels, boundary)
    O_all = _to_lattice(np.asarray(origins, np.float64).reshape(-1, 3))
    D_all = np.asarray(dirs, np.float64).reshape(-1, 3)
    n = len(O_all)
    points = np.full((n, 3), np.nan)
    hit = np.zeros(n, bool)
    underside = np.zeros(n, bool)
    reach = MAX_TILES * max(field.nx, field.ny)
    for s in range(0, n, CHUNK):
        O, D = O_all[s : s + CHUNK], D_all[s : s + CHUNK]
        oz, dz = O[:, 2], D[:, 2]
        horiz = np.hypot(D[:, 0], D[:, 1])
        with np.errstate(divide="ignore", invalid="ignore"):
            t_top = (field.zmax - oz) / dz
            t_bottom = (field.zmin - BELOW - oz) / dz  # a little below: f < 0 there, for sure
            t_far = np.where(horiz > 0, reach / horiz, np.inf)
        down = dz < 0
        t0 = np.where(down & (oz > field.zmax), t_top, 0.0)
        # descending: to z_min (there it has hit); otherwise until it rises above z_max
        t1 = np.where(down, t_bottom, np.where(dz > 0, np.minimum(t_top, t_far), t_far))
        t1 = np.where((oz > field.zmax) & ~down, -1.0, t1)  # above the relief, not descending
        if not field.wrap:
            lo, hi = field.box_span(O, D)
            t0, t1 = np.maximum(t0, lo), np.minimum(t1, hi)
        t1 = np.where(np.isfinite(t1), t1, -1.0)
        t_hit, under = _march(field, O, D, t0, t1, first=True)
        ok = np.isfinite(t_hit)
        P = O[ok] + t_hit[ok, None] * D[ok]
        P[:, :2] += 0.5
        points[s : s + CHUNK][ok] = P
        hit[s : s + CHUNK] = ok
        underside[s : s + CHUNK] = under & ok
    if return_underside:
        return points, hit, underside
    return points, hit


def surface(height_texels: np.ndarray, boundary: str, x: np.ndarray, y: np.ndarray):
    """Height ``z`` and unit geometric normal ``n (N, 3)`` of the surface at tangent-space
    ``(x, y)`` (NaN outside an ``open`` tile)."""
    field = _Field(height_texels, boundary)
    return _surface(field, np.asarray(x, np.float64) - 0.5, np.asarray(y, np.float64) - 0.5)


def _surface(field: _Field, X: np.ndarray, Y: np.ndarray):
    i, j, z00, a, b, c = field.patch(X, Y)
    fx, fy = X - i, Y - j
    z = z00 + a * fx + b * fy + c * fx * fy
    n = _unit(np.stack([-(a + c * fy), -(b + c * fx), np.ones_like(a)], axis=-1))
    out = ~field.inside(X, Y)
    z = np.where(out, np.nan, z)
    n[out] = np.nan
    return z, n


def visible(
    height_texels: np.ndarray, boundary: str, points: np.ndarray, L, lift: float = LIFT
) -> np.ndarray:
    """``(N,)`` float: 1 where the light ``L`` (toward the light) reaches surface points, else 0.

    Only the points' ``x, y`` are used: each shadow ray starts at the surface height there plus
    ``lift``. 0 also where ``L.z <= 0`` and where the triangle under the point faces away from
    ``L`` (``n.L <= 0``). NaN for NaN points (misses).
    """
    field = _Field(height_texels, boundary)
    L = np.asarray(L, np.float64).reshape(3)
    L = L / np.linalg.norm(L)
    P_all = np.asarray(points, np.float64).reshape(-1, 3)
    n = len(P_all)
    out = np.full(n, np.nan)
    for s in range(0, n, CHUNK):
        P = P_all[s : s + CHUNK]
        seen = np.isfinite(P).all(axis=1)
        V = np.full(len(P), np.nan)
        X, Y = P[seen, 0] - 0.5, P[seen, 1] - 0.5
        z, nrm = _surface(field, X, Y)
        inside = np.isfinite(z)
        v = np.full(len(X), np.nan)
        v[inside] = 0.0
        if L[2] > 0:
            faces = inside.copy()
            faces[inside] = nrm[inside] @ L > 0
            k = np.flatnonzero(faces)
            O = np.stack([X[k], Y[k], z[k] + lift], axis=1)
            D = np.broadcast_to(L, O.shape)
            t0 = np.zeros(len(k))
            t1 = np.maximum((field.zmax - O[:, 2]) / L[2], 0.0)
            if not field.wrap:
                t1 = np.minimum(t1, np.maximum(field.box_span(O, D)[1], 0.0))
            blocked = _march(field, O, D, t0, t1, first=False)
            v[k] = np.where(blocked, 0.0, 1.0)
        V[seen] = v
        out[s : s + CHUNK] = V
    return out


def light_direction(azimuth_deg: float, elevation_deg: float) -> np.ndarray:
    """``L = (cos e cos phi, cos e sin phi, sin e)``, toward the light."""
    phi, e = math.radians(azimuth_deg), math.radians(elevation_deg)
    return np.array([math.cos(e) * math.cos(phi), math.cos(e) * math.sin(phi), math.sin(e)])


# --------------------------------------------------------------------------
# A sweep folder
# --------------------------------------------------------------------------


def _read_json(path: Path) -> dict:
    try:
        with open(path) as f:
            return json.load(f)
    except FileNotFoundError:
        raise CheckError(f"no {path.name} in {path.parent}") from None
    except (OSError, ValueError) as exc:
        raise CheckError(f"cannot read {path}: {exc}") from None


def _digest_of_array(height: np.ndarray) -> str:
    from hzval.io import heightmap

    return heightmap.from_array(height).digest


def load_material(
    metrics: dict, sweep_dir: Path, override: str | None = None
) -> tuple[np.ndarray, list[str]]:
    """The normalised height map ``(rows, cols)`` float32 of a sweep, and notes about it.

    ``override``: a height-map path or a built-in name. Otherwise the report's
    ``material.path`` (as recorded, else relative to the sweep folder), or for a built-in the
    one among ``material.builtin``, ``material.name`` and the built-ins whose label the
    ``source`` names whose regenerated digest matches the report's.
    """
    from hzval import materials
    from hzval.io import heightmap

    mat = metrics.get("material") or {}
    notes: list[str] = []
    rows, cols = mat.get("rows"), mat.get("cols")
    want = mat.get("digest")

    def builtin(name: str) -> np.ndarray:
        if rows is None or cols is None:
            raise CheckError(f"material: a built-in ({name}) needs the report's rows and cols")
        return np.asarray(materials.generate(name, (int(rows), int(cols))).height, np.float32)

    def from_file(path: Path) -> np.ndarray:
        hm = heightmap.load_height(path)
        if want and hm.digest != want:
            notes.append(f"height map {path}: digest differs from the report's")
        return np.asarray(hm.height, np.float32)

    if override is not None:
        if materials.is_builtin(override):
            h = builtin(override)
        else:
            h = from_file(Path(override))
    elif mat.get("path"):
        p = Path(mat["path"])
        if not p.exists() and (sweep_dir / p).exists():
            p = sweep_dir / p
        if not p.exists():
            raise CheckError(f"material: height map {mat['path']} not found (pass --height)")
        h = from_file(p)
    else:
        names = [n for n in (mat.get("builtin"), mat.get("name")) if materials.is_builtin(n)]
        source = str(mat.get("source", ""))
        m = re.match(r"built-in (.+), \d+x\d+$", source)
        if m:
            for n in materials.names():
                if n not in names and getattr(materials.get(n), "label", None) == m.group(1):
                    names.append(n)
        if not names:
            raise CheckError(
                f"material: {mat.get('name')!r} is no built-in and the report has no path (pass --height)"
            )
        h = None
        for n in names:
            cand = builtin(n)
            if not want or _digest_of_array(cand) == want:
                h = cand
                break
        if h is None:
            h = builtin(names[0])
            notes.append(f"built-in {names[0]}: regenerated digest differs from the report's")
    if rows is not None and cols is not None and h.shape != (int(rows), int(cols)):
        raise CheckError(f"material: height map is {h.shape[1]}x{h.shape[0]}, the report's {cols}x{rows}")
    return h, notes


def _read_visibility(path: Path) -> np.ndarray:
    from hzval.io import codecs

    if not path.exists():
        raise CheckError(f"missing {path}")
    try:
        ch = codecs.read_exr(path)
    except Exception as exc:
        raise CheckError(f"cannot read {path}: {exc}") from None
    for name in ("Y", "V", "R"):
        if name in ch:
            return np.asarray(ch[name], np.float64)
    if len(ch) == 1:
        return np.asarray(next(iter(ch.values())), np.float64)
    raise CheckError(f"{path}: no single visibility channel (has {', '.join(sorted(ch))})")


def check(
    sweep_dir,
    spp: int = 4,
    *,
    frames: str = "all",
    height: str | None = None,
    seed: int = 0,
    lift: float = LIFT,
    progress=None,
) -> dict:
    """March a sweep folder's camera and lights; compare with its ``visibility.exr`` files.

    Returns ``{"frames": [per-frame dicts], "mean_abs_diff": pooled mean |dV|, "compared": pixel
    count, "notes": [...], "seconds": {...}}``; each frame has ``name, azimuth_deg,
    elevation_deg, mean_abs_diff, compared, hzval_unseen, march_unseen, march_partial,
    disagree_seen`` (pixels hzval sees and the march does not, or the reverse), ``underside``.
    """
    sweep_dir = Path(sweep_dir)
    if not sweep_dir.is_dir():
        raise CheckError(f"no sweep folder {sweep_dir}")
    metrics = _read_json(sweep_dir / "metrics.json")
    frames_json = None
    if (sweep_dir / "frames.json").exists():
        frames_json = _read_json(sweep_dir / "frames.json")
    record = metrics.get("camera")
    if not isinstance(record, dict):
        raise CheckError(f"{sweep_dir / 'metrics.json'} has no camera record")
    params = metrics.get("parameters") or {}
    try:
        depth = float(params["depth"])
        boundary = str(params["boundary"])
    except KeyError as exc:
        raise CheckError(f"metrics.json parameters lack {exc}") from None
    notes: list[str] = []
    light = params.get("light", "hard")
    if light != "hard":
        notes.append(
            f"light is {light!r} (radius {params.get('light_radius_deg')} deg): "
            "using its centre direction, a hard light"
        )
    H, more = load_material(metrics, sweep_dir, height)
    notes += more
    h = (H.astype(np.float32) * np.float32(depth * H.shape[1])).astype(np.float64)
    rows, cols = image_shape(record)

    clock = time.perf_counter()
    O, D = camera_rays(record, spp, seed)
    points, hit, under = march_hits(h, boundary, O, D, return_underside=True)
    t_camera = time.perf_counter() - clock
    hits_px = hit.reshape(rows * cols, spp).sum(axis=1).reshape(rows, cols)
    all_seen, none_seen = hits_px == spp, hits_px == 0
    partial = ~all_seen & ~none_seen

    lights = {}
    if frames_json:
        for fr in frames_json.get("frames", []):
            if "light_direction" in fr:
                lights[(fr.get("azimuth_deg"), fr.get("elevation_deg"))] = np.asarray(
                    fr["light_direction"], float
                )
    todo = list(metrics.get("frames") or [])
    if not todo:
        raise CheckError("metrics.json lists no frames")
    if frames == "first":
        todo = todo[:1]
    out_frames, diffs = [], []
    t_shadow = 0.0
    for fr in todo:
        az, el = float(fr["azimuth_deg"]), float(fr["elevation_deg"])
        name = Path(str((fr.get("files") or {}).get("visibility", ""))).parent.name or f"az{az:g}"
        rel = (fr.get("files") or {}).get("visibility")
        if not rel:
            notes.append(f"frame az {az:g} el {el:g}: no visibility file (shadow not declared?); skipped")
            continue
        L = light_direction(az, el)
        given = lights.get((fr.get("azimuth_deg"), fr.get("elevation_deg")))
        if given is not None and np.abs(given - L).max() > 1e-6:
            notes.append(
                f"frame {name}: frames.json light_direction {given.tolist()} differs from "
                f"(az, el) ({L.tolist()}); using (az, el)"
            )
        clock = time.perf_counter()
        v = visible(h, boundary, points, L, lift=lift)
        t_shadow += time.perf_counter() - clock
        v_px = np.where(hit, v, 0.0).reshape(rows * cols, spp).sum(axis=1).reshape(rows, cols)
        with np.errstate(invalid="ignore", divide="ignore"):
            v_march = np.where(all_seen, v_px / spp, np.nan)
        v_hz = _read_visibility(sweep_dir / rel)
        if v_hz.shape != (rows, cols):
            raise CheckError(f"{rel}: {v_hz.shape[1]}x{v_hz.shape[0]} pixels, the camera's {cols}x{rows}")
        hz_seen = np.isfinite(v_hz)
        both = hz_seen & all_seen
        d = np.abs(v_hz[both] - v_march[both])
        diffs.append(d)
        out_frames.append(
            {
                "name": name,
                "azimuth_deg": az,
                "elevation_deg": el,
                "mean_abs_diff": float(d.mean()) if d.size else float("nan"),
                "max_abs_diff": float(d.max()) if d.size else float("nan"),
                "compared": int(both.sum()),
                "hzval_unseen": int((~hz_seen).sum()),
                "march_unseen": int(none_seen.sum()),
                "march_partial": int(partial.sum()),
                "disagree_seen": int((hz_seen & none_seen).sum() + (~hz_seen & all_seen).sum()),
                "underside": int(under.sum()),
                "mean_v_hzval": float(v_hz[both].mean()) if d.size else float("nan"),
                "mean_v_march": float(v_march[both].mean()) if d.size else float("nan"),
            }
        )
        if progress:
            progress(out_frames[-1])
    if not out_frames:
        raise CheckError("no frame has a visibility file")
    pooled = np.concatenate(diffs)
    return {
        "frames": out_frames,
        "mean_abs_diff": float(pooled.mean()) if pooled.size else float("nan"),
        "compared": int(pooled.size),
        "notes": notes,
        "boundary": boundary,
        "camera": record.get("kind"),
        "image": [cols, rows],
        "spp": spp,
        "seconds": {"camera": t_camera, "shadow": t_shadow},
    }


def _frame_line(fr: dict) -> str:
    return (
        f"{fr['name']:>10}  az {fr['azimuth_deg']:7.2f} el {fr['elevation_deg']:6.2f}  "
        f"|dV| {fr['mean_abs_diff']:.4f}  V hzval {fr['mean_v_hzval']:.4f} march {fr['mean_v_march']:.4f}  "
        f"compared {fr['compared']}  unseen hzval {fr['hzval_unseen']} march {fr['march_unseen']}  "
        f"partial {fr['march_partial']}  disagree {fr['disagree_seen']}"
    )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="march_check", description=__doc__.split("\n\n")[0])
    ap.add_argument("sweep_dir", type=Path)
    ap.add_argument("--spp", type=int, default=4, help="camera samples per pixel (default 4)")
    ap.add_argument("--tolerance", type=float, default=0.035, help="largest overall mean |dV| (0.035)")
    ap.add_argument("--frames", choices=("all", "first"), default="all")
    ap.add_argument(
        "--height", default=None, help="height map file or built-in name (overrides the report's)"
    )
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--lift", type=float, default=LIFT, help=f"shadow-ray offset in texels ({LIFT:g})")
    args = ap.parse_args(argv)
    if args.spp < 1:
        print("march_check: --spp must be at least 1", file=sys.stderr)
        return 1
    try:
        res = check(
            args.sweep_dir,
            args.spp,
            frames=args.frames,
            height=args.height,
            seed=args.seed,
            lift=args.lift,
            progress=lambda fr: print(_frame_line(fr), flush=True),
        )
    except CheckError as exc:
        print(f"march_check: {exc}", file=sys.stderr)
        return 1
    except Exception as exc:  # hzval's InputError and the like: one line, not a traceback
        print(
            f"march_check: {type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}",
            file=sys.stderr,
        )
        return 1
    for note in res["notes"]:
        print(f"note: {note}")
    s = res["seconds"]
    print(
        f"{res['camera']} camera, {res['image'][0]}x{res['image'][1]} px, {res['spp']} spp, "
        f"{res['boundary']}: camera march {s['camera']:.1f} s, shadow march {s['shadow']:.1f} s"
    )
    mean = res["mean_abs_diff"]
    print(f"overall |dV| {mean:.4f} over {res['compared']} pixel-frames (tolerance {args.tolerance:g})")
    if not mean <= args.tolerance:
        print(
            f"march_check: overall mean |V_hzval - V_march| {mean:.4f} exceeds {args.tolerance:g}",
            file=sys.stderr,
        )
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
