"""Your own horizon map (hzval.io.external): conventions converted, conventions detected, and an
independent bake driving the horizon technique."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from hzval.bake import maps as bake
from hzval.cli import main as cli
from hzval.core.errors import InputError
from hzval.io import codecs, external
from hzval.io.external import Encoding
from hzval.materials.bricks import bricks
from tests.helpers import GCC, run_peer


def encode(sines: np.ndarray, enc: Encoding) -> np.ndarray:
    """hzval-layout sines stored the way ``enc`` says, written independently of to_hzval: the
    baker's channel j holds the sine toward hzval azimuth s_y (azimuth0 + s_d 45 j)."""
    D = enc.channels
    sy, sd = (-1 if enc.y == "down" else 1), (-1 if enc.direction == "cw" else 1)
    out = np.empty_like(sines)
    for j in range(D):
        phi = sy * (enc.azimuth0 + sd * 360.0 / D * j)
        out[..., j] = sines[..., int(round(phi / (360.0 / D))) % D]
    a = np.arcsin(np.clip(out, 0, 1))
    return {
        "sine": out,
        "cosine": np.cos(a),
        "angle": a / (math.pi / 2),
        "tangent": np.tan(a),
        "sqrt": np.sqrt(out),
    }[enc.values].astype(np.float32)


def some_sines(seed=1):
    return (np.random.default_rng(seed).random((6, 5, 8)) * 0.7).astype(np.float32)


@pytest.mark.parametrize(
    "enc",
    [
        Encoding(),
        Encoding(azimuth0=90.0),
        Encoding(direction="cw"),
        Encoding(y="down"),
        Encoding(y="down", direction="cw", azimuth0=135.0),
        Encoding(values="cosine"),
        Encoding(values="angle"),
        Encoding(values="tangent"),
        Encoding(values="sqrt", azimuth0=315.0),
    ],
)
def test_every_declared_convention_converts_back_to_hzvals(enc):
    s = some_sines()
    np.testing.assert_allclose(external.to_hzval(encode(s, enc), enc), s, atol=1e-5)  # float32 sqrt, squared


def test_an_azimuth_between_channels_interpolates_around_the_ring():
    s = some_sines()
    raw = encode(s, Encoding())
    half = external.to_hzval(raw, Encoding(azimuth0=22.5))
    # hzval's channel k lies halfway between the baker's k and k - 1 (channel 0 at 22.5 degrees)
    np.testing.assert_allclose(half, 0.5 * (raw + np.roll(raw, 1, axis=-1)), atol=1e-6)


@pytest.fixture(scope="module")
def bricks64():
    h = bricks(64)
    exact = bake.bake(h, bake.BakeParams(depth=0.05, method="exact")).horizon
    seed4 = bake.bake(h, bake.BakeParams(depth=0.05, radius=4)).horizon
    return h, exact, seed4


@pytest.mark.parametrize(
    "stored, declared, expect",
    [
        (Encoding(), Encoding(), None),
        (Encoding(y="down"), Encoding(), "mirrored: is +y down?"),
        (Encoding(azimuth0=90.0), Encoding(), "rotated: does channel 0 point to 90 degrees?"),
        (Encoding(values="sqrt"), Encoding(), "the values look like sqrt"),
        (Encoding(y="down", values="angle"), Encoding(y="down", values="angle"), None),
    ],
)
def test_detection_names_what_looks_wrong(variant, bricks64, stored, declared, expect):
    """A radius-4 bake (not the exact bake's unlimited radius) stored in one convention and declared
    in another: the best match is the stored one, and the advice says how the two differ."""
    _, exact, seed4 = bricks64
    found = external.detect(encode(seed4, stored), exact, declared)
    line = external.advice(found)
    if expect is None:
        assert found["matches"] and line is None
    else:
        assert not found["matches"] and expect in line, line
        assert found["suggested"]["mae"] < found["declared"]["mae"] * 0.85
        raw = encode(seed4, stored)
        np.testing.assert_allclose(
            external.to_hzval(
                raw,
                Encoding(**{k: v for k, v in found["suggested"].items() if k not in ("mae", "shadow_error")}),
            ),
            seed4,
            atol=1e-5,
        )
    # best_match is the lowest score of all (issue 32), whatever is declared or suggested
    assert found["best_match"]["mae"] == min(r["mae"] for r in found["scores"]) <= found["suggested"]["mae"]
    assert found["describes"] and found["correlation"] > external.DESCRIBES_CORRELATION


@pytest.mark.gcc
@pytest.mark.skipif(GCC is None, reason="gcc is not installed: cannot compile the seed peer")
def test_an_independent_radius_4_bake_drives_the_horizon_technique(
    variant,
    seed_peer,  # tests/conftest.py's compiled-once fixture
    tmp_path,
    capsys,
):
    """The C seed peer bakes at radius 4; as 8-bit PNGs in hzval's layout it replaces hzval's bake
    (F follows it: mirrored it shadows elsewhere), its convention is confirmed, and the same map
    mirrored (+y down) is reported as a different convention, in metrics.json and a warning line."""
    h = bricks(64)
    depth = 0.2  # 12.8 texels of relief: a radius of 4 sees less than 16 does
    peer = run_peer(seed_peer, h, depth, 4, 32, "wrap", tmp_path)[..., :8]
    u8 = codecs.unit_to_u8(peer)
    mirrored = u8[..., [(8 - k) % 8 for k in range(8)]]
    np.save(tmp_path / "bricks.npy", h)
    results = {}
    for name, layers in (("own", u8), ("mirrored", mirrored)):
        codecs.write_png(tmp_path / f"{name}0.png", layers[..., :4])
        codecs.write_png(tmp_path / f"{name}1.png", layers[..., 4:])
        out = tmp_path / name
        assert (
            cli.main(
                [
                    "sweep",
                    str(tmp_path / "bricks.npy"),
                    "--depth",
                    str(depth),
                    "--azimuths",
                    "0,45",
                    "--spp",
                    "4",
                    "--quiet",
                    "--techniques",
                    "horizon",
                    "--horizon-map",
                    f"{tmp_path / (name + '0.png')},{tmp_path / (name + '1.png')}",
                    "--out",
                    str(out),
                ]
            )
            == 0
        )
        results[name] = (json.loads((out / "metrics.json").read_text()), capsys.readouterr().err, out)
    m, err, out = results["own"]
    assert m["external_bake"]["matches"] and "warning" not in err
    assert m["techniques"]["horizon"]["parameters"]["bake"].startswith("external: ")
    assert "external: " in (out / "index.html").read_text(encoding="utf-8")
    # F follows the external map: it is the factor of the peer's sines, not of hzval's radius-16 bake
    from hzval.scene import spec as sc
    from hzval.techniques import horizon

    scn = sc.override(sc.Scene(), height=str(tmp_path / "bricks.npy"), depth=depth, azimuths="0", spp=4)
    own_bake = bake.bake(h, bake.BakeParams(depth=depth))
    theirs = (
        horizon.Horizon(
            scn,
            bake.Bake(
                own_bake.params,
                u8.astype(np.float32) / 255,
                own_bake.normal,
                own_bake.mean_cos,
                own_bake.mean_cos2,
            ),
        )
        .render(0.0)
        .layers["factor"]
    )
    F = codecs.read_exr(out / m["frames"][0]["techniques"]["horizon"]["files"]["factor"])["Y"]
    np.testing.assert_allclose(F, theirs, atol=2**-12 + 1e-6)  # the file is half float: 2^-12 in [0, 1]
    assert np.abs(F - horizon.Horizon(scn, own_bake).render(0.0).layers["factor"]).mean() > 1e-3
    m2, err2, _ = results["mirrored"]
    assert not m2["external_bake"]["matches"] and m2["external_bake"]["best_match"]["y"] == "down"
    assert err2.startswith("hzval: warning: horizon map: the channels look mirrored: is +y down?")
    assert m2["warnings"] and (
        m2["frames"][1]["techniques"]["horizon"]["visibility_mae"]
        > m["frames"][1]["techniques"]["horizon"]["visibility_mae"]
    )


def test_encoding_from_toml_and_bad_layers(tmp_path):
    (tmp_path / "enc.toml").write_text(
        '[encoding]\nchannels = 8\nazimuth0 = 90\ny = "down"\nvalues = "angle"\n'
    )
    enc = Encoding.from_toml(tmp_path / "enc.toml")
    assert enc == Encoding(azimuth0=90.0, y="down", values="angle")
    (tmp_path / "bad.toml").write_text("[encoding]\nchanels = 8\n")
    with pytest.raises(InputError, match="unknown key 'chanels' in \\[encoding\\]; did you mean 'channels'"):
        Encoding.from_toml(tmp_path / "bad.toml")
    with pytest.raises(InputError, match="values"):
        Encoding(values="cubic").validate()
    codecs.write_png(tmp_path / "a.png", np.zeros((4, 4, 4), np.uint8))
    codecs.write_png(tmp_path / "b.png", np.zeros((4, 5, 4), np.uint8))
    with pytest.raises(InputError, match="differ in size"):
        external.read_layers([tmp_path / "a.png", tmp_path / "b.png"])
    with pytest.raises(InputError, match="no such"):
        external.read_layers([tmp_path / "nope.png"])


def test_a_map_of_another_size_is_refused_before_anything_is_written(variant, tmp_path, capsys):
    codecs.write_png(tmp_path / "h0.png", np.zeros((8, 8, 4), np.uint8))
    codecs.write_png(tmp_path / "h1.png", np.zeros((8, 8, 4), np.uint8))
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
                "--quiet",
                "--horizon-map",
                f"{tmp_path / 'h0.png'},{tmp_path / 'h1.png'}",
                "--out",
                str(out),
            ]
        )
        == 2
    )
    err = capsys.readouterr().err.strip()
    assert "h0.png" in err and "8x8" in err and "\n" not in err


@pytest.mark.parametrize("other", ["gravel", "panels", "spikes"])
def test_a_map_of_another_surface_does_not_describe_it(variant, bricks64, other):
    """hzval's own bake of another built-in material, declared in hzval's convention: its best
    convention correlates below the bound, the warning names both files and the flag; the bricks' own
    map (radius 4) and the same map mirrored do describe it."""
    from hzval import materials

    h, exact, seed4 = bricks64
    m = materials.get(other)
    theirs = bake.bake(
        materials.generate(other, 64).height, bake.BakeParams(depth=m.depth, boundary=m.boundary)
    ).horizon
    found = external.detect(np.round(np.clip(theirs, 0, 1) * 255) / 255, exact, Encoding())
    assert (
        not found["describes"]
        and not found["matches"]
        and found["correlation"] < external.DESCRIBES_CORRELATION
    )
    (line,) = external.warnings(found, ["a0.png", "a1.png"], "bricks.png")
    assert (
        line.startswith("horizon map a0.png,a1.png does not describe this height map bricks.png")
        and "--horizon-map" in line
    )
    for raw in (seed4, encode(seed4, Encoding(y="down"))):
        own = external.detect(raw, exact, Encoding())
        assert own["describes"] and own["correlation"] > 0.7


def test_each_convention_warning_names_its_flags(bricks64):
    _, exact, seed4 = bricks64
    for stored, flags in (
        (Encoding(y="down"), "try --horizon-y down"),
        (Encoding(azimuth0=90.0), "try --horizon-azimuth0 90"),
        (Encoding(values="sqrt"), "try --horizon-values sqrt"),
    ):
        (line,) = external.warnings(
            external.detect(encode(seed4, stored), exact, Encoding()), ["m.png"], "h.png"
        )
        assert line.endswith(flags), line


def test_strict_fails_a_sweep_on_a_map_that_does_not_describe_it(variant, tmp_path, capsys):
    from hzval import materials

    np.save(tmp_path / "bricks.npy", bricks(32))
    other = bake.bake(materials.generate("gravel", 32).height, bake.BakeParams(depth=0.05)).horizon
    u8 = codecs.unit_to_u8(np.clip(other, 0, 1))
    codecs.write_png(tmp_path / "g0.png", u8[..., :4])
    codecs.write_png(tmp_path / "g1.png", u8[..., 4:])
    argv = [
        "sweep",
        str(tmp_path / "bricks.npy"),
        "--azimuths",
        "0",
        "--spp",
        "1",
        "--quiet",
        "--techniques",
        "horizon",
        "--horizon-map",
        f"{tmp_path / 'g0.png'},{tmp_path / 'g1.png'}",
    ]
    assert cli.main([*argv, "--out", str(tmp_path / "loose")]) == 0
    assert "does not describe this height map" in capsys.readouterr().err
    assert cli.main([*argv, "--out", str(tmp_path / "strict"), "--strict"]) == 1
    err = capsys.readouterr().err
    assert "gate failed: --strict: horizon map" in err and "g0.png" in err and "bricks.npy" in err
    m = json.loads((tmp_path / "strict" / "metrics.json").read_text())
    assert m["gates"]["strict"] and m["external_bake"]["warnings"] and not m["external_bake"]["describes"]


def test_a_flat_surface_is_not_judged():
    """Flat: every exact horizon is 0, nothing to correlate; no map is said not to describe it."""
    exact = np.zeros((16, 16, 8))
    for raw in (np.zeros((16, 16, 8), np.float32), some_sines().repeat(3, 0).repeat(4, 1)[:16, :16]):
        found = external.detect(raw, exact, Encoding())
        assert found["describes"] and found["correlation"] is None
