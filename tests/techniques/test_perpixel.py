"""The engines' per-pixel techniques (hzval.techniques.perpixel and its five plug-ins): each factor
probed at texel centres against its published formula evaluated here in NumPy from the same bake,
the limits each formula is documented to reach, and the mirror and rotation invariances."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hzval.bake import maps as bake
from hzval.bake import occlusion
from hzval.core import conventions as cv
from hzval.core.errors import InputError
from hzval.techniques import bent_cone
from hzval.techniques import registry as technique
from hzval.techniques.bent_cone import BentCone
from hzval.techniques.microshadow_filament import MicroshadowFilament
from hzval.techniques.microshadow_hdrp import MicroshadowHDRP
from hzval.techniques.perpixel import stored
from hzval.techniques.ssbump import SSBump
from hzval.techniques.terminator import Terminator
from tests.helpers import make_scene

N = 32
ENGINE = ["microshadow-filament", "microshadow-hdrp", "bent-cone", "ssbump", "terminator"]


def bumps(n: int = N, seed: int = 3) -> np.ndarray:
    """A smooth, wrapping height field with hills and pits, normalised to [0, 1]."""
    y, x = np.mgrid[0:n, 0:n] * (2 * math.pi / n)
    rng = np.random.default_rng(seed)
    h = sum(
        rng.uniform(0.3, 1) * np.sin(kx * x + rng.uniform(0, 6)) * np.cos(ky * y + rng.uniform(0, 6))
        for kx, ky in [(1, 2), (3, 1), (2, 3)]
    )
    return ((h - h.min()) / (h.max() - h.min())).astype(np.float32)


@pytest.fixture(scope="module")
def baked():
    h = bumps()
    return h, bake.bake(h, bake.BakeParams(depth=0.12, boundary="wrap"))


def probe(cls, h, baked, az, el, **kw):
    """``F`` at every texel centre, and the texels' ``(row, col)`` order: row-major."""
    rows, cols = h.shape
    r, c = np.mgrid[0:rows, 0:cols]
    t = cls(make_scene(h.shape, 0.12, "wrap"), baked, **kw)
    out = t.sample((c + 0.5).ravel(), (rows - r - 0.5).ravel(), az, el)
    return out["factor"].reshape(rows, cols)


def light(az, el):
    return np.asarray(cv.light_direction(az, el), np.float64)


FLOAT = {"storage": {"ao": "float", "bent-normal": "float", "ssbump": "float"}}


def _storage(cls):
    return {"storage": {t: "float" for t in cls.textures}}


@pytest.mark.parametrize("az, el", [(0, 15), (130, 30), (250, 60)])
def test_filament_is_chans_formula(baked, az, el):
    h, baked = baked
    n, L, ao = baked.normal.astype(np.float64), light(az, el), baked.mean_cos2.astype(np.float64)
    nl = n @ L
    with np.errstate(divide="ignore", invalid="ignore"):
        want = np.where(ao < 1, np.clip(nl / np.sqrt(1 - ao), 0, 1) ** 2, (nl > 0) * 1.0)
    got = probe(MicroshadowFilament, h, baked, az, el, **_storage(MicroshadowFilament))
    np.testing.assert_allclose(got, want, atol=2e-5)


@pytest.mark.parametrize("opacity", [1.0, 0.4])
def test_hdrp_is_brinck_and_maximovs_formula(baked, opacity):
    h, baked = baked
    n, L, ao = baked.normal.astype(np.float64), light(200, 25), baked.mean_cos2.astype(np.float64)
    nl = n @ L
    want = np.where(nl > 0, 1 + opacity * (np.clip(nl + 2 * ao * ao - 1, 0, 1) - 1), 1.0)
    got = probe(MicroshadowHDRP, h, baked, 200, 25, opacity=opacity, **_storage(MicroshadowHDRP))
    np.testing.assert_allclose(got, want, atol=2e-5)


def test_an_open_flat_surface_is_never_shadowed_by_any_of_them():
    h = np.zeros((16, 16), np.float32)
    baked = bake.bake(h, bake.BakeParams(depth=0.12, boundary="wrap"))
    assert np.all(baked.mean_cos2 == 1.0)
    for name in ENGINE:
        cls = technique.get(name)
        for el in (1.0, 20.0, 89.0):
            for storage in ("float", "u8"):
                kw = {"storage": dict.fromkeys(cls.textures, storage)}
                F = probe(cls, h, baked, 33.0, el, **kw)
                # 8 bits store ssbump's open 1/sqrt(3) as 147/255: the one rounding an engine sees
                tol = {"u8": 0.5 / 255 * math.sqrt(3), "float": 1e-6}[storage] if name == "ssbump" else 0.0
                assert np.all(np.abs(F - 1.0) <= tol), (name, el, storage, F.min())


def test_hdrp_at_zero_opacity_shadows_nothing(baked):
    h, baked = baked
    assert np.all(probe(MicroshadowHDRP, h, baked, 10, 10, opacity=0.0) == 1.0)


def test_bent_cone_of_a_hard_light_is_the_step_at_the_cones_edge(baked):
    h, baked = baked
    L = light(75, 20)
    Bn, ao = baked.bent_normal.astype(np.float64), baked.mean_cos2.astype(np.float64)
    margin = Bn @ L - np.sqrt(1 - ao)
    got = probe(BentCone, h, baked, 75, 20, **_storage(BentCone))
    decided = np.abs(margin) > 1e-4
    np.testing.assert_array_equal(got[decided], (margin[decided] >= 0) * 1.0)


def _mc_caps(r1, r2, d, n=400_000, seed=0):
    v = np.random.default_rng(seed).normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    a, b = np.array([0, 0, 1.0]), np.array([math.sin(d), 0, math.cos(d)])
    return np.mean((v @ a >= math.cos(r1)) & (v @ b >= math.cos(r2))) * 4 * math.pi


@pytest.mark.parametrize(
    "r1, r2, d", [(0.5, 0.3, 0.6), (1.2, 0.2, 1.25), (1.5, 0.8, 1.0), (0.3, 0.3, 0.1), (1.0, 0.1, 0.5)]
)
def test_the_exact_cap_intersection_against_monte_carlo(variant, r1, r2, d):
    from hzval.core.backend import dr, mi

    got = bent_cone.cap_intersection(mi.Float(r1), mi.Float(r2), mi.Float(d))
    dr.eval(got)
    assert float(got[0]) == pytest.approx(_mc_caps(r1, r2, d), abs=0.01)


def test_filaments_cap_approximation_meets_the_exact_one_at_its_ends(variant):
    from hzval.core.backend import mi

    d = mi.Float(np.linspace(0.0, 2.0, 41))
    exact = np.asarray(bent_cone.cap_intersection(mi.Float(0.9), mi.Float(0.2), d))
    smooth = np.asarray(bent_cone.cap_intersection_filament(mi.Float(0.9), mi.Float(0.2), d))
    dd = np.linspace(0.0, 2.0, 41)
    ends = (dd <= 0.7) | (dd >= 1.1)
    np.testing.assert_allclose(smooth[ends], exact[ends], atol=1e-6)
    assert np.all(np.diff(smooth) <= 1e-7) and np.abs(smooth - exact).max() < 0.05


def test_a_soft_light_inside_a_wide_cone_is_whole_and_outside_it_none():
    h = np.zeros((8, 8), np.float32)
    baked = bake.bake(h, bake.BakeParams(depth=0.1, boundary="wrap"))
    scene = make_scene(h.shape, 0.1, "wrap", kind="soft", radius=5.0)
    for variant in bent_cone.VARIANTS:
        for intersection in bent_cone.INTERSECTIONS:
            t = BentCone(scene, baked, variant=variant, intersection=intersection, **_storage(BentCone))
            assert np.allclose(t.sample([4.5], [4.5], 0.0, 45.0)["factor"], 1.0, atol=1e-5)
            assert np.allclose(t.sample([4.5], [4.5], 0.0, 0.0)["factor"], 0.5, atol=1e-4)  # half the disc up
    # the disc's centre 2.5 degrees up: the segment below the plane is 0.195 of a 5-degree disc
    t = BentCone(scene, baked, intersection="exact", **_storage(BentCone))
    assert np.allclose(t.sample([4.5], [4.5], 0.0, 2.5)["factor"], 0.805, atol=0.005)


def test_ssbump_is_greens_projection_onto_the_basis(baked):
    h, baked = baked
    L, n, S = light(300, 35), baked.normal.astype(np.float64), baked.ssbump.astype(np.float64)
    w = np.maximum(occlusion.HL2_BASIS @ L, 0)
    open_ = np.maximum(n @ occlusion.HL2_BASIS.T, 0) @ w
    want = np.where(open_ > 0, (S @ w) / np.where(open_ > 0, open_, 1), 0.0)
    got = probe(SSBump, h, baked, 300, 35, **_storage(SSBump))
    np.testing.assert_allclose(got, np.clip(want, 0, 1), atol=2e-5)


@pytest.mark.parametrize("variant", ["conty", "chiang"])
def test_terminator_terms_are_the_published_formulas(baked, variant):
    h, baked = baked
    n, L = baked.normal.astype(np.float64), light(45, 12)
    cos_d, cos_i, nl = n[..., 2], L[2], n @ L
    if variant == "conty":
        a2 = np.clip((1 / cos_d**2 - 1) / 8, 0, 1)
        want = 2 / (1 + np.sqrt(1 + a2 * (1 / cos_i**2 - 1)))
    else:
        g = cos_i / np.where(nl > 0, nl * cos_d, 1)
        want = np.where(nl > 0, np.where(g >= 1, 1, np.where(g <= 0, 0, -(g**3) + g**2 + g)), 1.0)
    got = probe(Terminator, h, baked, 45, 12, variant=variant)
    np.testing.assert_allclose(got, want, atol=3e-5)
    assert got.min() < 0.999  # the bumps tilt the normals enough for the term to act


@pytest.mark.parametrize("name", ENGINE)
def test_a_mirrored_map_gives_the_mirrored_factor(name):
    """Mirror in y (rows reversed) and the light with it (azimuth -phi): F mirrors. The HL2 basis
    maps onto itself under this mirror, so ssbump must too."""
    cls = technique.get(name)
    h = bumps(seed=5)
    m = h[::-1].copy()
    p = bake.BakeParams(depth=0.12, boundary="wrap")
    kw = _storage(cls)
    a = probe(cls, h, bake.bake(h, p), 35.0, 25.0, **kw)
    b = probe(cls, m, bake.bake(m, p), -35.0, 25.0, **kw)
    np.testing.assert_allclose(b[::-1], a, atol=2e-4)


@pytest.mark.parametrize("name", ["microshadow-filament", "microshadow-hdrp", "bent-cone", "terminator"])
def test_a_quarter_turned_map_gives_the_turned_factor(name):
    cls = technique.get(name)
    h = bumps(seed=7)
    t = np.rot90(h).copy()  # counterclockwise on screen: +x goes to +y
    p = bake.BakeParams(depth=0.12, boundary="wrap")
    kw = _storage(cls)
    a = probe(cls, h, bake.bake(h, p), 20.0, 30.0, **kw)
    b = probe(cls, t, bake.bake(t, p), 110.0, 30.0, **kw)
    np.testing.assert_allclose(b, np.rot90(a), atol=2e-4)


def test_eight_bit_storage_rounds_to_the_nearest_level_and_keeps_unit_vectors():
    v = np.random.default_rng(0).uniform(0, 1, 1000).astype(np.float32)
    q = stored(v, "u8")
    assert np.abs(q - v).max() <= 0.5 / 255 + 1e-7 and len(np.unique(q)) <= 256
    n = np.random.default_rng(1).normal(size=(100, 3)).astype(np.float32)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    np.testing.assert_allclose(np.linalg.norm(stored(n, "u8", signed=True), axis=1), 1.0, atol=1e-6)


def test_settings_out_of_range_are_refused_naming_the_setting(baked):
    h, baked = baked
    scene = make_scene(h.shape, 0.12, "wrap")
    with pytest.raises(InputError, match="opacity"):
        MicroshadowHDRP(scene, baked, opacity=1.5)
    with pytest.raises(InputError, match="variant"):
        Terminator(scene, baked, variant="blinn")
    with pytest.raises(InputError, match="ao-storage"):
        MicroshadowFilament(scene, baked, storage={"ao": "bc7"})


def test_every_engine_technique_is_on_by_default_for_shadows_and_renders_on_models():
    for name in ENGINE:
        cls = technique.get(name)
        assert name in technique.defaults() and cls.needs == ("shadow",) and not cls.not_on_models
        assert {
            v.settings.get("storage", {}).get(t) for v in cls.tradeoff_variants() for t in cls.textures
        } >= ({"float", "u8"} if cls.textures else set())


def _cap_numpy(r1: float, r2: float, d: float) -> float:
    """The intersection of two caps, written here from Mazonka 2012, eq. 35 (independently of the
    technique's Dr.Jit code)."""
    if d <= abs(r1 - r2):
        return 2 * math.pi * (1 - math.cos(min(r1, r2)))
    if d >= r1 + r2:
        return 0.0
    c1, c2, cd, s1, s2, sd = math.cos(r1), math.cos(r2), math.cos(d), math.sin(r1), math.sin(r2), math.sin(d)
    return 2 * (
        math.pi
        - math.acos((cd - c1 * c2) / (s1 * s2))
        - c1 * math.acos((c2 - cd * c1) / (sd * s1))
        - c2 * math.acos((c1 - cd * c2) / (sd * s2))
    )


@pytest.mark.parametrize("wall_deg, az, offset", [(30.0, 0.0, -4.0), (45.0, 60.0, 0.0), (20.0, 90.0, 3.0)])
def test_bent_cone_in_a_v_groove_is_the_analytic_cap_intersection(wall_deg, az, offset):
    """A V-groove along y with walls at ``wall_deg``: toward azimuth phi its horizon rises at
    ``atan(tan(wall) |cos phi|)``. From those horizons alone, the open fraction and the cosine-weighted
    mean open direction (dense quadrature) give the cone; a soft light's F is then the caps' intersection
    over the disc (Mazonka 2012), evaluated here in float64. The light sits ``offset`` degrees from the
    cone's edge, where the disc straddles it."""
    D = 16
    phi = np.radians([cv.channel_azimuth_deg(k, D) for k in range(D)])
    sines = np.sin(np.arctan(math.tan(math.radians(wall_deg)) * np.abs(np.cos(phi))))
    sines = np.broadcast_to(sines, (8, 8, D)).astype(np.float32)
    normal = np.broadcast_to(np.array([0, 0, 1], np.float32), (8, 8, 3))
    ao = np.mean(1 - sines.astype(np.float64) ** 2, axis=-1)
    baked = bake.Bake(
        bake.BakeParams(depth=0.1, boundary="wrap", directions=D),
        sines,
        normal.copy(),
        ao.astype(np.float32),
        ao.astype(np.float32),
        bent_normal=occlusion.bent_normal(sines),
        ssbump=occlusion.self_shadowed_bump(sines, normal),
    )
    from tests.helpers import dense_bent_normal

    Bn = dense_bent_normal(sines[0, 0].astype(np.float64))
    assert abs(Bn[0]) < 1e-9 and abs(Bn[1]) < 1e-9  # the groove is symmetric: B is +z
    radius = 6.0
    scene = make_scene((8, 8), 0.1, "wrap", kind="soft", radius=radius)
    t = BentCone(scene, baked, intersection="exact", **_storage(BentCone))
    theta_v = math.acos(math.sqrt(1 - ao[0, 0]))
    el = 90.0 - math.degrees(theta_v) + offset
    got = float(t.sample([4.5], [4.5], az, el)["factor"][0])
    L = np.asarray(cv.light_direction(az, el), np.float64)
    d = math.acos(np.clip(Bn @ L, -1, 1))
    r = math.radians(radius)
    want = _cap_numpy(theta_v, r, d) / (2 * math.pi * (1 - math.cos(r)))
    assert 0.05 < want < 0.95 and got == pytest.approx(want, abs=2e-3)


@pytest.mark.parametrize(
    "argv, flag",
    [
        (["--microshadow-hdrp-opacity", "2"], "--microshadow-hdrp-opacity"),
        (["--ao-storage", "bc7"], "--ao-storage"),
    ],
)
def test_a_bad_setting_is_one_line_naming_its_flag(tmp_path, capsys, argv, flag):
    from hzval.cli import main as cli

    try:
        code = cli.main(["sweep", "--size", "16", *argv, "--out", str(tmp_path / "o")])
    except SystemExit as exc:  # argparse's own refusal of a choice
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err
    assert err.startswith(f"hzval: error: {flag}") or f"argument {flag}" in err
    assert err.count("\n") == 1 and not (tmp_path / "o").exists()


def test_oat_and_sanders_cone_is_the_open_solid_angle_about_the_plain_mean_direction():
    """Against a Monte Carlo count that shares nothing with the formulas: directions uniform on the
    hemisphere, open where above their wedge's horizon; the open share is V, their mean direction bake."""
    from hzval.bake import occlusion

    rng = np.random.default_rng(4)
    sines = np.array([[[0.9, 0.5, 0.0, 0.2, 0.7, 0.1, 0.0, 0.3]]], np.float32)
    z = rng.random(400_000)  # uniform on the hemisphere: z uniform, azimuth uniform
    phi = rng.random(400_000) * 2 * np.pi
    w = np.stack([np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z], -1)
    wedge = np.round(phi / (2 * np.pi / 8)).astype(int) % 8
    open_ = z > sines[0, 0][wedge]
    assert occlusion.uniform_ao(sines)[0, 0] == pytest.approx(open_.mean(), abs=3e-3)
    mean = w[open_].mean(0)
    B = occlusion.uniform_bent_normal(sines)[0, 0]
    assert np.allclose(B, mean / np.linalg.norm(mean), atol=5e-3)
    # a closed texel has no open direction: +z, and an empty cone (V = 0, cos = 1)
    assert occlusion.uniform_bent_normal(np.ones((1, 1, 8), np.float32))[0, 0].tolist() == [0.0, 0.0, 1.0]


def test_the_oat_sander_variant_reads_its_own_planes_and_a_wider_cone(baked):
    """Both conventions make a horizon the same all round into the open cap itself (cos = 1 - V =
    sqrt(1 - AO) = s); on a bumpy terrain they differ, the plain mean and the solid angle lighting more
    at 12 degrees here."""
    from hzval.bake import occlusion

    s = np.full((1, 1, 8), 0.3, np.float32)
    assert 1.0 - occlusion.uniform_ao(s)[0, 0] == pytest.approx(0.3, abs=1e-6)
    h, baked = baked
    t = BentCone(make_scene(h.shape, 0.12, "wrap"), baked, variant="oat-sander", **_storage(BentCone))
    assert t.plane_name("ao") == "ao_uniform" and t.plane("ao").shape == baked.mean_cos2.shape
    j = BentCone(make_scene(h.shape, 0.12, "wrap"), baked, variant="jimenez", **_storage(BentCone))
    assert j.plane_name("ao") == "mean_cos2"
    fo = probe(BentCone, h, baked, 30.0, 12.0, variant="oat-sander", **_storage(BentCone))
    fj = probe(BentCone, h, baked, 30.0, 12.0, variant="jimenez", **_storage(BentCone))
    assert fo.mean() > fj.mean()


def test_the_cli_takes_the_variant_and_the_intersection(tmp_path, variant):
    import json

    from hzval.cli import main as cli

    argv = ["sweep", "--size", "32", "--azimuths", "0", "--spp", "1", "--techniques", "bent-cone", "--quiet"]
    argv += ["--bent-cone-variant", "oat-sander", "--light", "soft", "--light-radius", "3"]
    assert cli.main([*argv, "--bent-cone-intersection", "filament", "--out", str(tmp_path / "o")]) == 0
    params = json.loads((tmp_path / "o" / "metrics.json").read_text())["techniques"]["bent-cone"][
        "parameters"
    ]
    assert params["variant"] == "oat-sander" and params["intersection"] == "filament"
