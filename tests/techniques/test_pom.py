"""Ray-marched height-field shadows (hzval.techniques.pom) against answers known in advance.

A flat plane is fully lit; a plateau wall of height h casts a hard shadow
h / tan(e) long behind its far edge, to within one step of the march; a thin
(one-texel) wall's shadow converges to that length as the steps grow; the
soft variant never darkens what the hard one lights and follows Tatarchuk's
formula behind a wall; lights at the zenith and below the horizon; and on
the bricks the factor converges to the truth's visibility as steps grow.
"""

import json
import math

import numpy as np
import pytest

from hzval.cli import main as cli
from hzval.core.errors import InputError
from hzval.techniques import pom
from hzval.truth import plane as truth
from tests.helpers import WALL_AT, WALL_H, column_wall, make_scene, row_wall, wall_shadow_extents


def march(h, depth, boundary="open", **kw):
    settings = {k: kw.pop(k) for k in ("steps", "variant", "softness") if k in kw}
    return pom.RayMarchShadow(
        make_scene(np.shape(h), depth, boundary, **kw), np.asarray(h, np.float32), **settings
    )


@pytest.mark.parametrize("boundary", ["wrap", "open"])
@pytest.mark.parametrize("variant_", pom.VARIANTS)
def test_flat_plane_is_fully_lit(variant, boundary, variant_):
    m = march(np.full((12, 16), 0.3), 0.1, boundary, elevation=10.0, spp=4, variant=variant_, steps=16)
    for azimuth in (0.0, 77.0, 200.0, -45.0):
        f = m.render(azimuth)
        assert np.all(f.layers["factor"] == 1.0)
        assert np.all(f.image == 1.0)  # shadow only: E times the factor


def plateau_wall(width: int = 4, first: int = 16, n: int = 40, axis: str = "col") -> np.ndarray:
    h = np.zeros((n, n), np.float32)
    if axis == "col":
        h[:, first : first + width] = 1.0
    else:
        h[first : first + width, :] = 1.0
    return h


@pytest.mark.parametrize("steps", [4, 8, 32])
@pytest.mark.parametrize("elevation", [30.0, 50.0])
@pytest.mark.parametrize("azimuth", [180.0, 0.0, 90.0, 270.0])
def test_plateau_wall_shadow_is_h_over_tan_e_long_within_one_step(variant, steps, elevation, azimuth):
    """A 4-texel-thick wall of height 4 at columns (or rows) 16-19 of 40: its top's far edge, a mesh
    vertex half a texel inside the wall's last texel, casts a shadow h / tan(e) long; the march finds
    its end to within one step (t_max / N = h / (N tan e) on flat ground)."""
    axis = "col" if azimuth in (0.0, 180.0) else "row"
    m = march(plateau_wall(axis=axis), WALL_H / 40, steps=steps, elevation=elevation)
    F = m.render(azimuth).layers["factor"]
    length = WALL_H / math.tan(math.radians(elevation))
    step = length / steps
    lines = F[10:30] if axis == "col" else F[:, 10:30].T  # lines across the wall, texels along the light
    # light from -x (180) or from +y, up the image (90): the shadow runs toward larger columns / rows
    behind = lines[:, 20:] if azimuth in (180.0, 90.0) else lines[:, :16][:, ::-1]
    in_front = lines[:, :16] if azimuth in (180.0, 90.0) else lines[:, 20:]
    # the far top edge is a mesh vertex half a texel before the first texel behind the wall
    measured = (1.0 - behind).sum(axis=1).mean()
    assert length - 0.5 - step - 0.05 <= measured <= length - 0.5 + 0.05, (measured, length, step)
    assert np.all(in_front == 1.0)


@pytest.mark.parametrize("elevation", [30.0, 50.0])
def test_thin_wall_shadow_converges_to_h_over_tan_e(variant, elevation):
    """A one-texel wall is a tent of the bilinear height field: the march must land a step inside its
    narrow tip to see it, so the shadow comes out short by about 1.7 steps, and converges."""
    expected = WALL_H / math.tan(math.radians(elevation))
    errors = []
    for steps in (8, 32, 128):
        col = march(column_wall(40, 40, WALL_AT), WALL_H / 40, elevation=elevation, steps=steps)
        row = march(row_wall(40, 40, WALL_AT), WALL_H / 40, elevation=elevation, steps=steps)
        worst = 0.0
        for az in (0.0, 45.0, 180.0):
            for across, c in wall_shadow_extents(
                lambda az=az, m=col: m.render(az).layers["factor"],
                lambda az=az, m=row: m.render(az).layers["factor"],
                az,
            ):
                assert across <= expected * c + 0.05  # never longer than the geometry's
                worst = max(worst, (expected * c - across) / c)
        assert worst <= 2.0 * expected / steps + 0.1, (steps, worst)
        errors.append(worst)
    assert errors[0] > errors[1] > errors[2]


def test_soft_variant_follows_tatarchuks_formula_behind_a_wall(variant):
    """Behind a plateau wall of height h (light from -x at elevation e) a ground point at distance d from
    the wall's far top edge sees the edge rise (h - d tan e) / d above its ray: F = 1 - w (h / d - tan e)
    while that is positive, 1 beyond; and the soft factor is never below the hard one."""
    e, w = 30.0, 2.0
    hard = march(plateau_wall(), WALL_H / 40, elevation=e, steps=256, spp=16).render(180.0).layers["factor"]
    soft = (
        march(plateau_wall(), WALL_H / 40, elevation=e, steps=256, spp=16, variant="soft", softness=w)
        .render(180.0)
        .layers["factor"]
    )
    assert np.all(soft >= hard - 1e-6)
    tan_e = math.tan(math.radians(e))
    d = np.arange(20, 40) + 0.5 - 19.5  # pixel centres behind the far edge at x = 19.5
    expect = np.clip(1.0 - w * (WALL_H / d - tan_e), 0.0, 1.0)
    got = soft[10:30, 20:].mean(axis=0)
    # a pixel spans d +- 0.5, over which the formula is curved: compare within that spread
    spread = np.abs(
        np.clip(1.0 - w * (WALL_H / np.maximum(d - 0.5, 0.3) - tan_e), 0, 1)
        - np.clip(1.0 - w * (WALL_H / (d + 0.5) - tan_e), 0, 1)
    )
    assert np.all(np.abs(got - expect) <= spread + 0.02), np.c_[d, got, expect]


@pytest.mark.parametrize("variant_", pom.VARIANTS)
def test_zenith_lights_all_and_below_the_horizon_none(variant, variant_):
    h = np.random.default_rng(3).random((16, 16)).astype(np.float32)
    m = march(h, 0.2, "wrap", spp=1, variant=variant_)
    assert np.all(m.render(10.0, elevation_deg=90.0).layers["factor"] == 1.0)
    assert np.all(m.render(10.0, elevation_deg=0.0).layers["factor"] == 0.0)
    F = m.render(10.0, elevation_deg=1.0).layers["factor"]
    assert np.isfinite(F).all() and F.min() >= 0 and F.max() <= 1 and F.mean() < 0.5


def test_converges_to_the_truths_visibility_on_the_bricks(variant):
    """On the 64 x 64 built-in bricks (hard light at 30 degrees) |F - V| falls as steps grow,
    from about 0.013 at 4 steps to about 0.005 at 64 (spp 4; the rest is the bilinear height field
    against the mesh's triangles and the truth's noise)."""
    from hzval.materials.bricks import bricks
    from hzval.scene import spec as sc

    h = bricks(64)
    scene = sc.override(sc.Scene(), size=64, effects="shadow", spp=4)
    t = truth.Truth(scene, h)
    azimuths = (-60.0, 0.0, 45.0)
    V = [t.render(az).layers["visibility"] for az in azimuths]
    maes = []
    for steps in (4, 16, 64):
        m = pom.RayMarchShadow(scene, h, steps=steps)
        maes.append(
            float(np.mean([np.abs(m.render(az).layers["factor"] - v).mean() for az, v in zip(azimuths, V)]))
        )
    assert maes[0] > maes[1] > maes[2], maes
    assert maes[2] < 0.008 and maes[0] < 0.03, maes


@pytest.mark.parametrize(
    "kw, needle",
    [
        ({"steps": 0}, "steps"),
        ({"steps": 2.5}, "steps"),
        ({"variant": "fuzzy"}, "variant"),
        ({"softness": -1.0}, "softness"),
        ({"softness": float("nan")}, "softness"),
    ],
)
def test_bad_settings_are_input_errors(variant, kw, needle):
    with pytest.raises(InputError, match=needle):
        march(np.zeros((4, 4)), 0.1, **kw)


def test_sweep_scores_it_with_its_own_options(variant, tmp_path, capsys):
    out = tmp_path / "out"
    assert (
        cli.main(
            [
                "sweep",
                "--size",
                "24",
                "--azimuths",
                "0",
                "--spp",
                "1",
                "--techniques",
                "pom,horizon",
                "--pom-steps",
                "8",
                "--pom-variant",
                "soft",
                "--quiet",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    m = json.loads((out / "metrics.json").read_text())
    assert list(m["techniques"]) == ["horizon", "pom"]  # registry order
    assert m["techniques"]["pom"]["parameters"] == {
        "technique": "height-field ray march (parallax occlusion mapping's shadows)",
        "steps": 8,
        "variant": "soft",
        "softness": pom.DEFAULT_SOFTNESS,
        "simulated": ["shadow", "diffuse"],
    }
    assert 0 <= m["frames"][0]["techniques"]["pom"]["visibility_mae"] <= 1
    # bad steps: one line, exit 2, nothing written
    bad = tmp_path / "bad"
    capsys.readouterr()
    assert cli.main(["sweep", "--size", "24", "--pom-steps", "0", "--quiet", "--out", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("hzval: error: --pom-steps") and "\n" not in err and not bad.exists()


def _adversarial_maps(rng):
    """Maps where the skip table's bound is tight: plateaus at a few exact levels (a ray's height
    meets a maximum exactly), white noise, and sparse spikes one texel wide on a flat floor."""
    levels = rng.integers(0, 4, (6, 6)).astype(np.float32) / 3
    plateaus = np.kron(levels, np.ones((5, 5), np.float32))
    spikes = np.where(rng.random((30, 30)) < 0.03, rng.random((30, 30)), 0).astype(np.float32)
    return {"plateaus": plateaus, "noise": rng.random((30, 30)).astype(np.float32), "spikes": spikes}


@pytest.mark.parametrize("boundary", ["wrap", "open"])
@pytest.mark.parametrize("variant_", pom.VARIANTS)
def test_the_skip_table_leaves_every_factor_bit_for_bit(variant, monkeypatch, boundary, variant_):
    """The march that passes over samples below its skip table's maximum (pom.SKIP_RADIUS) gives the
    full march's F exactly, at low and high suns and every octant, with 1 to 128 steps (many steps a
    texel: where the table lets the march jump several at once)."""
    rng, reach = np.random.default_rng(5), pom.SKIP_RADIUS
    for name, h in _adversarial_maps(rng).items():
        shadowed = False
        for steps in (1, 7, 32, 128):
            factors = {}
            for table in (reach, None):
                monkeypatch.setattr(pom, "SKIP_RADIUS", table)
                factors[table] = [
                    march(h, 0.2, boundary, elevation=e, spp=4, steps=steps, variant=variant_).factor(az, e)
                    for e in (3.0, 12.0, 25.0, 45.0, 70.0)
                    for az in (0.0, 45.0, 100.0, 163.0, 200.0, 290.0)
                ]
            skipped, full = factors.values()
            for a, b in zip(skipped, full):
                assert a.tobytes() == b.tobytes(), (name, steps)
            shadowed |= any((f < 1).any() for f in full)
        assert shadowed, name  # each map casts shadows


@pytest.mark.parametrize("boundary", ["wrap", "open"])
@pytest.mark.parametrize("radius", [0.0, 1.5, 2.0])
def test_the_skip_table_is_the_windowed_maximum_read_at_the_texel_that_holds_p(variant, boundary, radius):
    """A 7 x 11 map (no power of two): the table is the maximum over every texel within ceil(r) + 1
    (wrapped, or clamped at the border), brute force; ``at`` reads the texel holding ``p``, for
    ``p`` inside, on texel edges, exactly at multiples of the tile and far outside it."""
    import mitsuba as mi

    rng = np.random.default_rng(3)
    h = rng.random((7, 11)).astype(np.float32)
    t = pom.SkipTable(h, radius, boundary)
    k = int(math.ceil(radius)) + 1
    rows, cols = h.shape
    want = np.empty_like(h)
    for r in range(rows):
        for c in range(cols):
            rr, cc = np.arange(r - k, r + k + 1), np.arange(c - k, c + k + 1)
            rr, cc = (
                (rr % rows, cc % cols) if boundary == "wrap" else (rr.clip(0, rows - 1), cc.clip(0, cols - 1))
            )
            want[r, c] = h[np.ix_(rr, cc)].max()
    assert np.array_equal(t.table, want)
    edges = np.array([0.0, 1.0, 2.0, -1.0, -3.0, 5 / 11, 3 / 7, 0.9999999, -0.5 / 11, 1.5 / 11, 7.25, -6.4])
    px, py = (a.ravel().astype(np.float32) for a in np.meshgrid(edges, edges))
    got = np.asarray(t.at(mi.Point2f(px, py)))
    if boundary == "wrap":
        ux, uy = px - np.floor(px), py - np.floor(py)
    else:
        ux, uy = px, py
    x = np.clip(np.floor(ux * np.float32(cols)), 0, cols - 1).astype(int)  # float32, as the kernel
    y = np.clip(np.floor(uy * np.float32(rows)), 0, rows - 1).astype(int)
    assert np.array_equal(got, t.table[y, x])
    with pytest.raises(ValueError, match="reach"):
        pom.SkipTable(h, -1.0, boundary)
