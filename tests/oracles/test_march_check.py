"""tests/oracles/march_check.py: the independent camera + shadow march, on analytic cases."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from tests.oracles import march_check as mc


def _top(rows, cols):
    return {
        "kind": "top",
        "eye": [cols / 2, rows / 2, 1e6],
        "target": [cols / 2, rows / 2, 0.0],
        "up": [0.0, 1.0, 0.0],
        "fov_deg": None,
        "film_size": [float(cols), float(rows)],
        "resolution": [cols, rows],
    }


def _angle(a, b):
    return math.degrees(math.acos(np.clip(np.dot(a, b) / np.linalg.norm(a) / np.linalg.norm(b), -1, 1)))


def test_independent_of_hzval_renderers():
    """The oracle imports none of the modules it checks: the truth, the scene (camera, lookups),
    the tile mesh or a technique."""
    import ast

    imported = set()
    for node in ast.walk(ast.parse(Path(mc.__file__).read_text())):
        if isinstance(node, ast.Import):
            imported |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module:
            imported |= {node.module} | {f"{node.module}.{a.name}" for a in node.names}
    renderers = ("hzval.truth", "hzval.scene", "hzval.geometry.tile", "hzval.techniques")
    assert not [m for m in imported if m.startswith(renderers)]


def test_top_camera_rays_are_texel_centres():
    rows, cols = 6, 10
    o, d = mc.camera_rays(_top(rows, cols), spp=1, seed=0)
    assert o.shape == (rows * cols, 3) and d.shape == (rows * cols, 3)
    row, col = np.divmod(np.arange(rows * cols), cols)
    np.testing.assert_allclose(o[:, 0], col + 0.5, atol=1e-9)
    np.testing.assert_allclose(o[:, 1], rows - row - 0.5, atol=1e-9)
    np.testing.assert_allclose(d, np.tile([0.0, 0.0, -1.0], (rows * cols, 1)), atol=1e-12)


def test_top_camera_jitter_stays_in_its_pixel():
    rows, cols, spp = 4, 5, 4
    o, _ = mc.camera_rays(_top(rows, cols), spp=spp, seed=3)
    row, col = np.divmod(np.arange(rows * cols).repeat(spp), cols)
    assert np.all((o[:, 0] >= col) & (o[:, 0] < col + 1))
    assert np.all((o[:, 1] > rows - row - 1) & (o[:, 1] <= rows - row))
    # stratified 2x2: one sample per quarter of each pixel
    q = (np.floor(2 * (o[:, 0] - col)) + 2 * np.floor(2 * (rows - row - o[:, 1]))).reshape(-1, spp)
    assert np.all(np.sort(q, axis=1) == [0, 1, 2, 3])


def test_perspective_rays():
    rows, cols, fov = 7, 9, 60.0
    eye, target = np.array([8.0, -20.0, 30.0]), np.array([8.0, 8.0, 0.0])
    rec = {
        "kind": "perspective",
        "eye": eye.tolist(),
        "target": target.tolist(),
        "up": [0.0, 0.0, 1.0],
        "fov_deg": fov,
        "film_size": None,
        "resolution": [cols, rows],
    }
    o, d = mc.camera_rays(rec, spp=1)
    np.testing.assert_allclose(o, np.tile(eye, (rows * cols, 1)))
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0)
    f = (target - eye) / np.linalg.norm(target - eye)
    r = np.cross(f, [0, 0, 1.0])
    r /= np.linalg.norm(r)
    t = np.cross(r, f)

    def at(row, col):
        return d[row * cols + col]

    np.testing.assert_allclose(at(3, 4), f, atol=1e-12)  # the centre pixel looks at the target
    half_px = fov / cols / 2
    left, right = at(3, 0), at(3, cols - 1)
    assert abs(_angle(left, f) - fov / 2) <= half_px
    assert abs(_angle(right, f) - fov / 2) <= half_px
    assert np.dot(left, r) < 0 < np.dot(right, r)
    vfov = 2 * math.degrees(math.atan(math.tan(math.radians(fov / 2)) * rows / cols))
    top = at(0, 4)
    assert abs(_angle(top, f) - vfov / 2) <= vfov / rows / 2
    assert np.dot(top, t) > 0


@pytest.mark.parametrize("boundary", ["wrap", "open"])
def test_flat_plane_oblique_orthographic(boundary):
    n, z = 16, 3.0
    h = np.full((n, n), z)
    eye = np.array([8.0, 8.0 - 100.0, z + 100.0])
    rec = {
        "kind": "orthographic",
        "eye": eye.tolist(),
        "target": [8.0, 8.0, z],
        "up": [0.0, 0.0, 1.0],
        "fov_deg": None,
        "film_size": [8.0, 8.0],
        "resolution": [8, 8],
    }
    o, d = mc.camera_rays(rec, spp=4, seed=1)
    np.testing.assert_allclose(d, np.tile([0.0, math.sqrt(0.5), -math.sqrt(0.5)], (len(d), 1)), atol=1e-12)
    p, hit = mc.march_hits(h, boundary, o, d)
    assert hit.all()
    tt = (o[:, 2] - z) / -d[:, 2]
    np.testing.assert_allclose(p, o + tt[:, None] * d, atol=1e-9)
    np.testing.assert_allclose(p[:, 2], z, atol=1e-9)
    for az in (-170.0, -45.0, 0.0, 90.0, 135.0):
        v = mc.visible(h, boundary, p, mc.light_direction(az, 30.0))
        assert np.all(v == 1.0)
    assert np.all(mc.visible(h, boundary, p, mc.light_direction(0.0, -5.0)) == 0.0)


@pytest.mark.parametrize("boundary", ["wrap", "open"])
def test_wall_shadow_length(boundary):
    rows, cols, c0, hw = 8, 32, 10, 5.0
    h = np.zeros((rows, cols))
    h[:, :c0] = hw  # high on the left: the wall's top edge at x = c0 - 0.5
    L = mc.light_direction(180.0, 45.0)  # the light toward -x
    x = np.linspace(c0 + 0.55, 28.0, 500)
    pts = np.stack([x, np.full_like(x, 4.3), np.zeros_like(x)], axis=1)
    v = mc.visible(h, boundary, pts, L)
    edge = c0 - 0.5 + hw / math.tan(math.radians(45.0))
    shadowed = x[v == 0]
    lit = x[v == 1]
    assert len(shadowed) and len(lit) and len(shadowed) + len(lit) == len(x)
    assert shadowed.max() < lit.min()  # one shadow, then light
    assert abs(shadowed.max() - edge) < 1.0 and abs(lit.min() - edge) < 1.0
    # the ramp down from the wall faces away from the light: self-shadowed
    ramp = np.array([[c0 - 0.2, 4.3, 0.0], [c0 + 0.3, 2.1, 0.0]])
    assert np.all(mc.visible(h, boundary, ramp, L) == 0.0)
    # and the top of the wall is lit
    assert np.all(mc.visible(h, boundary, np.array([[3.2, 4.3, 0.0]]), L) == 1.0)


def _ridge_column(n=16, col=2, height=10.0):
    h = np.zeros((n, n))
    h[:, col] = height  # a tent from x = col - 0.5 to col + 1.5, peak at col + 0.5
    return h


@pytest.mark.parametrize(
    "origin, direction, expect",
    [
        ((12.0, 8.3, 10.0), (1.0, 0.0, -1.0), 197.0 / 11.0),  # into the next tile, +x
        ((1.0, 8.3, 10.0), (-1.0, 0.0, -0.3), -134.7 / 10.3),  # into the previous tile, -x
    ],
)
def test_wrap_ray_continues_into_the_next_tile(origin, direction, expect):
    h = _ridge_column()
    o = np.array([origin])
    d = np.array([direction]) / np.linalg.norm(direction)
    p, hit = mc.march_hits(h, "wrap", o, d)
    assert hit[0]
    assert p[0, 0] == pytest.approx(expect, abs=1e-6)
    z, _ = mc.surface(h, "wrap", p[:, 0], p[:, 1])
    assert p[0, 2] == pytest.approx(z[0], abs=1e-6)
    # the same ray over an open tile leaves it and sees nothing
    p, hit = mc.march_hits(h, "open", o, d)
    assert not hit[0] and np.isnan(p[0]).all()


def test_wrap_ray_continues_along_y():
    h = _ridge_column().T.copy()  # a ridge along row 2: y from 12.5 to 14.5, peak 13.5
    o = np.array([[8.3, 15.0, 10.0]])
    d = np.array([[0.0, 1.0, -0.3]]) / math.hypot(1.0, 0.3)
    p, hit = mc.march_hits(h, "wrap", o, d)
    assert hit[0] and p[0, 1] == pytest.approx(299.5 / 10.3, abs=1e-6)


def test_wrap_shadow_from_the_next_tile():
    h = _ridge_column()
    pts = np.array([[14.2, 8.3, 0.0]])
    L = mc.light_direction(0.0, 30.0)  # toward +x: the ridge of the next tile blocks it
    assert mc.visible(h, "wrap", pts, L)[0] == 0.0
    assert mc.visible(h, "open", pts, L)[0] == 1.0
    assert mc.visible(h, "wrap", pts, mc.light_direction(0.0, 70.0))[0] == 1.0


def _write_sweep(tmp_path, H, depth, record, V, boundary="open"):
    from hzval.io import codecs

    np.save(tmp_path / "height.npy", H.astype(np.float32))
    rel = "frames/f0/visibility.exr"
    (tmp_path / "frames" / "f0").mkdir(parents=True)
    codecs.write_exr(tmp_path / rel, {"Y": V.astype(np.float32)})
    metrics = {
        "material": {
            "name": "t",
            "path": str(tmp_path / "height.npy"),
            "rows": H.shape[0],
            "cols": H.shape[1],
            "digest": None,
            "source": ".npy float32",
        },
        "parameters": {"depth": depth, "boundary": boundary, "light": "hard"},
        "camera": record,
        "frames": [{"azimuth_deg": 30.0, "elevation_deg": 40.0, "files": {"visibility": rel}}],
    }
    (tmp_path / "metrics.json").write_text(json.dumps(metrics))


def test_check_counts_and_compares(tmp_path):
    rng = np.random.default_rng(5)
    H = rng.random((8, 8)).astype(np.float32)
    depth, spp = 0.25, 4
    rec = _top(8, 8)
    rec.update(eye=[4.0, 4.0, 1e6], target=[4.0, 4.0, 0.0], film_size=[12.0, 12.0], resolution=[12, 12])
    h = (H * np.float32(depth * 8)).astype(np.float64)
    o, d = mc.camera_rays(rec, spp, seed=0)
    p, hit = mc.march_hits(h, "open", o, d)
    v = mc.visible(h, "open", p, mc.light_direction(30.0, 40.0))
    seen = hit.reshape(144, spp).all(axis=1).reshape(12, 12)
    assert seen.sum() == 64 and not (hit.reshape(144, spp).any(axis=1).reshape(12, 12) & ~seen).any()
    V = np.where(seen, np.nan_to_num(v).reshape(144, spp).mean(axis=1).reshape(12, 12), np.nan)
    assert 0 < np.nanmean(V) < 1
    V[5, 5] = 1.0 - V[5, 5]  # one seen pixel off by |1 - 2V|
    off = abs(1.0 - 2.0 * (1.0 - V[5, 5]))
    V[6, 6] = np.nan  # one seen pixel hzval does not see
    V[0, 0] = 0.3  # one unseen pixel hzval claims to see
    _write_sweep(tmp_path, H, depth, rec, V)
    res = mc.check(tmp_path, spp=spp, seed=0)
    fr = res["frames"][0]
    assert fr["compared"] == 63
    assert fr["march_unseen"] == 144 - 64 and fr["march_partial"] == 0
    assert fr["hzval_unseen"] == 80  # the 80 unseen, less [0, 0], plus [6, 6]
    assert fr["disagree_seen"] == 2
    assert fr["mean_abs_diff"] == pytest.approx(off / 63, abs=1e-6)
    assert res["mean_abs_diff"] == pytest.approx(off / 63, abs=1e-6)
    assert mc.main([str(tmp_path), "--spp", "4", "--tolerance", "1"]) == 0


def test_cli_missing_metrics(tmp_path, capsys):
    assert mc.main([str(tmp_path / "nope")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "nope" in err[0]
    assert mc.main([str(tmp_path)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "metrics.json" in err[0]


@pytest.mark.parametrize("boundary", ["wrap", "open"])
def test_surface_is_the_bilinear_field_hzvals_mesh_approximates(boundary):
    """The checker's own surface is the bilinear interpolation of the centres, and hzval's mesh
    (read here, in the test, never by the checker) is within its tolerance of it."""
    from hzval.geometry import tile as mesh

    rng = np.random.default_rng(2)
    h = rng.random((6, 7)) * 4.0
    # at texel centres and half-way between two: the samples and their mean
    z, _ = mc.surface(h, boundary, np.array([2.5, 3.0, 3.0]), np.array([6 - 1 - 0.5, 6 - 1 - 0.5, 6 - 1.0]))
    assert z[0] == pytest.approx(h[1, 2])
    assert z[1] == pytest.approx((h[1, 2] + h[1, 3]) / 2)
    assert z[2] == pytest.approx((h[0, 2] + h[0, 3] + h[1, 2] + h[1, 3]) / 4)
    tol = 0.01
    g = mesh.grid(h.astype(np.float32), boundary, margin=1)
    P, F, _ = mesh.tessellate(g, tol)
    tri = P.astype(np.float64)[F.astype(np.int64)]  # (F, 3 vertices, 3)
    x, y = rng.uniform(0.0, 7.0, 300), rng.uniform(0.0, 6.0, 300)
    a, b, c = tri[:, 0, :2], tri[:, 1, :2], tri[:, 2, :2]
    p = np.stack([x, y], axis=1)[:, None, :]

    def cross(u, v):
        return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]

    area = cross(b - a, c - a)
    w1, w2 = cross(p - a, c - a) / area, cross(b - a, p - a) / area
    w0 = 1 - w1 - w2
    inside = (w0 >= -1e-9) & (w1 >= -1e-9) & (w2 >= -1e-9)
    f = inside.argmax(axis=1)
    assert inside.any(axis=1).all()
    k = np.arange(len(x))
    z_mesh = w0[k, f] * tri[f, 0, 2] + w1[k, f] * tri[f, 1, 2] + w2[k, f] * tri[f, 2, 2]
    z, n = mc.surface(h, boundary, x, y)
    assert np.abs(z - z_mesh).max() <= tol + 1e-5  # float32 mesh heights
    assert np.abs(z - z_mesh).max() > tol / 50  # a surface of its own, not the mesh
    assert (n[:, 2] > 0).all()


def _brute_first_hit(h, boundary, o, d, t0, t1, dt=2e-3):
    """First f <= 0 by small steps and bisection: a slow second opinion."""
    t = np.arange(t0, t1, dt)
    P = o + t[:, None] * d
    z, _ = mc.surface(h, boundary, P[:, 0], P[:, 1])
    f = P[:, 2] - z
    below = np.flatnonzero(np.isfinite(f) & (f <= 0))
    if not len(below):
        return None
    lo, hi = t[below[0] - 1], t[below[0]]
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        pm = o + mid * d
        if pm[2] - mc.surface(h, boundary, pm[:1], pm[1:2])[0][0] <= 0:
            hi = mid
        else:
            lo = mid
    return o + hi * d


@pytest.mark.parametrize("boundary", ["wrap", "open"])
def test_exact_traversal_agrees_with_small_steps(boundary):
    rng = np.random.default_rng(7)
    h = rng.random((12, 12)) * 3.0
    n = 60
    az = rng.uniform(-math.pi, math.pi, n)
    el = rng.uniform(math.radians(15), math.radians(70), n)
    d = -np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=1)
    target = np.stack([rng.uniform(1, 11, n), rng.uniform(1, 11, n), np.full(n, 1.5)], axis=1)
    o = target - 8.0 * d
    p, hit = mc.march_hits(h, boundary, o, d)
    agree = 0
    for i in range(n):
        t0 = (o[i, 2] - h.max()) / -d[i, 2]
        q = _brute_first_hit(h, boundary, o[i], d[i], t0, t0 + 30.0)
        if q is None:
            assert not hit[i] or boundary == "wrap"
            continue
        z_q, _ = mc.surface(h, boundary, np.array([q[0]]), np.array([q[1]]))
        if (
            boundary == "open"
            and (min(q[0], q[1]) < 1e-9 or q[0] > 12 - 1e-9 or q[1] > 12 - 1e-9)
            and q[2] < z_q[0] - 1e-3
        ):
            continue  # entered the open tile's side below the surface: an underside hit, if it comes back up
        assert hit[i]
        agree += np.abs(p[i] - q).max() < 1e-6
    assert (
        hit.sum() >= n // 2 and agree >= hit.sum() - 2
    )  # small steps may skip a sliver of a peak the exact march finds
    # and the shadow rays from those points, against small steps toward the light
    L = mc.light_direction(40.0, 25.0)
    v = mc.visible(h, boundary, p[hit], L)
    z, nrm = mc.surface(h, boundary, p[hit, 0], p[hit, 1])
    t = np.arange(1e-3, 30.0, 2e-3)
    for k, i in enumerate(np.flatnonzero(hit)):
        if nrm[k] @ L <= 0:
            assert v[k] == 0
            continue
        P = np.array([p[i, 0], p[i, 1], z[k] + mc.LIFT]) + t[:, None] * L
        zz, _ = mc.surface(h, boundary, P[:, 0], P[:, 1])
        blocked = np.any(np.isfinite(zz) & (P[:, 2] < zz))
        assert v[k] == (0.0 if blocked else 1.0)
