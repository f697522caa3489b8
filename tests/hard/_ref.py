"""References for the hard cases, computed independently of the kernels under test.

* :func:`horizon_f64`: the seed bake in float64 NumPy, texel by texel, from
  the definition (max ``tan = dh / r`` per bin, ``sin = t / sqrt(1 + t^2)``,
  each channel the mean of its ``angles/8 + 1`` bins). It shares only the
  offset-to-bins table with :mod:`hzval.bake.maps` (``horizon_table``, which
  ``tests/bake/test_horizon_peer.py`` pins against libm and the seed's C code).
* :func:`mesh_horizon_tan`: the exact horizon of the displaced mesh along a
  direction, in float64: the ray's horizontal line is clipped against every
  triangle (Cyrus-Beck) and the largest ``(z - z0) / t`` at the clip points is
  taken (within a triangle ``(z - z0) / t`` is monotonic in ``t``, so its
  maximum is at an end). A point is in shadow of a hard light at elevation
  ``e`` iff that tangent is >= ``tan e``; the triangle under the point
  counts too, so a triangle facing away from the light shadows its points.
* :func:`gpu_weights`, :func:`exact_weights`: the channel weights of the two
  approximation paths, from :mod:`hzval.core.conventions` (as in tests/techniques/test_horizon.py).
"""

from __future__ import annotations

import math

import numpy as np

import hzval.bake as B
from hzval.core import conventions as cv
from hzval.geometry import tile as mesh
from hzval.scene import spec as sc

# --------------------------------------------------------------------------
# Checks every output must pass
# --------------------------------------------------------------------------


def assert_bake_sane(r, *, normal_tol=1e-5):
    """Every texture finite and in range: sines in [0, 1], unit normals facing up,
    0 < mean_cos2 <= mean_cos <= 1."""
    assert np.isfinite(r.horizon).all() and (r.horizon >= 0).all() and (r.horizon <= 1).all()
    assert np.isfinite(r.normal).all() and (r.normal[..., 2] > 0).all()
    assert np.allclose(np.linalg.norm(r.normal.astype(np.float64), axis=-1), 1.0, atol=normal_tol)
    for a in (r.mean_cos, r.mean_cos2):
        assert np.isfinite(a).all() and (a > 0).all() and (a <= 1).all()
    assert (r.mean_cos2 <= r.mean_cos * (1 + 1e-6)).all()


def assert_unit(x, what=""):
    x = np.asarray(x)
    assert np.isfinite(x).all() and (x >= 0).all() and (x <= 1).all(), what


# --------------------------------------------------------------------------
# The seed bake in float64
# --------------------------------------------------------------------------


def horizon_f64(h_texels, radius=16, angles=32, boundary="wrap", points=None, directions=8):
    """``(horizon (n, D), mean_cos (n,), mean_cos2 (n,))`` at texels ``points`` ((rows, cols) index
    arrays; all texels, row-major, if None), in float64; ``D = directions`` channels, channel
    ``k`` the mean of the ``angles/D + 1`` bins centred on bin ``k angles / D``."""
    h = np.asarray(h_texels, np.float64)
    rows, cols = h.shape
    pad = radius - 1
    P = cv.pad_heights(h, pad, boundary)
    if points is None:
        rr, cc = np.divmod(np.arange(rows * cols), cols)
    else:
        rr, cc = (np.asarray(p).ravel() for p in points)
    h0 = h[rr, cc]
    max_tan = np.zeros((rr.size, angles))
    for g in B.horizon_table(radius, angles):
        best = np.full(rr.size, -np.inf)
        for i, j in g.offsets:
            drow, dcol = cv.tangent_to_pixel_offset(i, j)
            with np.errstate(invalid="ignore"):
                best = np.maximum(best, (P[rr + pad + drow, cc + pad + dcol] - h0) / math.hypot(i, j))
        for b in g.bins:
            max_tan[:, b] = np.maximum(max_tan[:, b], best)
    sines = max_tan / np.sqrt(1.0 + max_tan**2)
    half = angles // (2 * directions)
    channels = []
    for k in range(directions):
        centre = k * angles // directions
        channels.append(np.mean([sines[:, (centre + d) % angles] for d in range(-half, half + 1)], axis=0))
    cos2 = 1.0 / (1.0 + max_tan**2)
    return np.stack(channels, axis=-1), np.sqrt(cos2).mean(axis=1), cos2.mean(axis=1)


def bins_of(i, j, angles=32):
    """The bins an offset ``(i, j)`` updates, in float64 (independent of the float32 table)."""
    k = angles / (2 * math.pi)
    d, delta = math.atan2(j, i), math.atan(0.7071 / math.hypot(i, j))
    return {n % angles for n in range(math.floor((d - delta) * k), math.ceil((d + delta) * k) + 1)}


def channel_share(i, j, channel, angles=32):
    """Fraction of channel ``channel``'s bins that offset ``(i, j)`` covers."""
    half = angles // 16
    centre = channel * angles // 8
    mine = {(centre + d) % angles for d in range(-half, half + 1)}
    return len(mine & bins_of(i, j, angles)) / len(mine)


# --------------------------------------------------------------------------
# The displaced mesh's exact horizon (float64 ray caster)
# --------------------------------------------------------------------------


def mesh_triangles(h_texels, boundary, margin=None, tolerance=None):
    """``(T, 3, 3)`` float64 triangles of the mesh that :mod:`hzval.geometry.tile` builds: the tessellation of
    the bilinear surface at ``tolerance`` (default :data:`hzval.geometry.tile.DEFAULT_TOLERANCE`, the
    truth's).
    The references below trace these triangles in float64, independently of Mitsuba."""
    g = mesh.grid(np.asarray(h_texels, np.float32), boundary, margin=margin)
    pos, faces, _ = mesh.tessellate(g, mesh.DEFAULT_TOLERANCE if tolerance is None else tolerance)
    return pos.astype(np.float64)[faces.astype(np.int64)]


def mesh_horizon_tan(tris, x0, y0, azimuth_deg, near=0.05, chunk=48):
    """The displaced mesh's horizon along azimuth ``azimuth_deg`` from the surface points above ``(x0, y0)``.

    Returns a dict of float64 arrays, one value per point: ``slope``, the rise
    per unit run of the triangle under the point along the azimuth (``>= tan e``
    means it faces away from a light at elevation ``e``); ``far``, the largest
    ``(z(t) - z0) / t`` over the surface at horizontal distances ``t >= near``;
    ``close``, the same for ``0 < t < near`` (the creases right around a point
    that sits a few ulps from a mesh vertex); ``z0``, the surface height.
    """
    x0 = np.asarray(x0, np.float64).ravel()
    y0 = np.asarray(y0, np.float64).ravel()
    phi = math.radians(azimuth_deg)
    d = np.array([math.cos(phi), math.sin(phi)])
    v = tris[:, :, :2]  # (T, 3, 2), counterclockwise
    e = np.roll(v, -1, axis=1) - v  # edges v_i -> v_i+1
    den = e[..., 0] * d[1] - e[..., 1] * d[0]  # cross(e, d): (T, 3)
    # plane z = a x + b y + c of each triangle
    A = np.concatenate([tris[:, :, :2], np.ones(tris.shape[:2] + (1,))], axis=-1)
    abc = np.linalg.solve(A, tris[:, :, 2:])[..., 0]  # (T, 3)
    along = abc[:, 0] * d[0] + abc[:, 1] * d[1]  # rise per unit run along d
    out = {k: np.full(x0.size, -np.inf) for k in ("slope", "far", "close", "z0")}
    for s in range(0, x0.size, chunk):
        px, py = x0[s : s + chunk, None], y0[s : s + chunk, None]
        num = e[None, ..., 0] * (py[..., None] - v[None, ..., 1]) - e[None, ..., 1] * (
            px[..., None] - v[None, ..., 0]
        )
        with np.errstate(divide="ignore", invalid="ignore"):
            tt = -num / den[None]
        lower = np.where(den[None] > 0, tt, -np.inf).max(axis=-1)  # (S, T)
        upper = np.where(den[None] < 0, tt, np.inf).min(axis=-1)
        ok = (lower <= upper) & ~((den[None] == 0) & (num < 0)).any(axis=-1)
        under = ok & (lower <= 0) & (upper >= 0)  # triangles under the point
        zp = abc[None, :, 0] * px + abc[None, :, 1] * py + abc[None, :, 2]
        z0 = np.where(under, zp, -np.inf).max(axis=1)
        sl = np.where(under, along[None], -np.inf).max(axis=1)

        def ratio(t, valid):
            with np.errstate(invalid="ignore", divide="ignore"):
                z = abc[None, :, 0] * (px + t * d[0]) + abc[None, :, 1] * (py + t * d[1]) + abc[None, :, 2]  # noqa: B023 - called within this iteration
                r = (z - z0[:, None]) / t  # noqa: B023 - called within this iteration
            return np.where(valid & np.isfinite(r), r, -np.inf).max(axis=1)

        t0 = np.maximum(lower, 0.0)
        far_ok = ok & (upper > near)
        far = np.maximum(ratio(np.maximum(t0, near), far_ok), ratio(upper, far_ok))
        close_ok = ok & (upper > 1e-12) & (t0 < near)
        close = np.maximum(
            ratio(np.where(t0 > 1e-12, t0, np.minimum(upper, near)), close_ok),
            ratio(np.minimum(upper, near), close_ok),
        )
        for k, val in (("slope", sl), ("far", far), ("close", close), ("z0", z0)):
            out[k][s : s + chunk] = val
    return out


def classify(ref, elevation_deg, margin):
    """``(lit, shadowed)`` masks of the points whose answer is certain for a hard light.

    Shadowed: the triangle under the point faces away from the light, or the
    surface at ``t >= near`` rises above the ray, each by more than ``margin``
    in tangent. Lit: both are below by more than ``margin`` and nothing closer
    rises above it. The rest (the answer hinges on the last ``margin``, or on
    a crease a few ulps from the point) are left out.
    """
    tan_e = math.tan(math.radians(elevation_deg))
    worst = np.maximum(ref["slope"], ref["far"])
    shadowed = worst > tan_e + margin
    lit = (worst < tan_e - margin) & (ref["close"] < tan_e)
    return lit, shadowed


def texel_centres_flat(rows, cols):
    """Sample positions exactly on the texel centres (mesh vertices), one per pixel, pixel-major."""
    x, y = cv.texel_centres(rows, cols)
    return np.ascontiguousarray(x, np.float32).ravel(), np.ascontiguousarray(y, np.float32).ravel()


# --------------------------------------------------------------------------
# Scenes and the approximation's weights
# --------------------------------------------------------------------------


def make_scene(
    shape,
    depth,
    boundary="open",
    *,
    effects=("shadow",),
    elevation=30.0,
    kind="hard",
    radius=0.0,
    spp=4,
    seed=0,
    irradiance=1.0,
    albedo=0.5,
):
    return sc.Scene(
        name="hard",
        material=sc.MaterialSpec(
            height="hard", size=max(shape[1], 2), depth=depth, boundary=boundary, albedo=albedo
        ),
        light=sc.Light(kind=kind, radius_deg=radius, elevation_deg=elevation, irradiance=irradiance),
        effects=tuple(effects),
        spp=spp,
        seed=seed,
    ).validate()


def truth(h, depth, boundary="open", positions=None, **kw):
    from hzval.truth.plane import Truth

    return Truth(
        make_scene(np.shape(h), depth, boundary, **kw), np.asarray(h, np.float32), positions=positions
    )


CUBE_SIZE = 16
_CUBE = B.weight_cube(CUBE_SIZE).astype(np.float64) / 255.0


def light32(azimuth, elevation):
    return cv.light_direction(azimuth, elevation).astype(np.float32)


def exact_weights(d):
    d = np.asarray(d, np.float32).astype(np.float64)
    return cv.channel_weights(d[0], d[1])


def gpu_weights(d):
    """Listing 5.1's 8 channel factors from the 8-bit cube map at ``d``, filtered seamlessly across
    the faces as OpenGL does (tests/oracles/cube_reference.py)."""
    from tests.oracles.cube_reference import seamless_bilinear

    f = seamless_bilinear(_CUBE, np.asarray(d, np.float32).astype(np.float64))
    return np.concatenate([np.clip(2 * f - 1, 0, 1), np.clip(1 - 2 * f, 0, 1)])


def uniform_bake(horizon, normal=(0.0, 0.0, 1.0), rows=4, cols=4, boundary="wrap"):
    """A synthetic bake with the same horizon sines and normal in every texel."""
    n = np.asarray(normal, np.float64)
    n = n / np.linalg.norm(n)
    return B.Bake(
        B.BakeParams(boundary=boundary),
        np.broadcast_to(np.asarray(horizon, np.float32), (rows, cols, 8)).copy(),
        np.broadcast_to(n.astype(np.float32), (rows, cols, 3)).copy(),
        np.ones((rows, cols), np.float32),
        np.ones((rows, cols), np.float32),
    )
