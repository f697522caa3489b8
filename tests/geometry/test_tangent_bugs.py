"""Engine tangent-frame bugs on purpose (hzval.geometry.tangent_bugs): the techniques' frames change, the
truth's never do.

- ``none`` is today's render, bit for bit.
- Which bug is visible where: on the unit quad with UVs = (x, y) (``w = +1``, flat faces),
  ``ignore-handedness`` and ``per-face`` leave the frames as they are; on the quad mirrored in u
  (``w = -1``) ``ignore-handedness`` is ``flip-green``; ``swap-uv`` trades t and b everywhere.
- A bug that mirrors the lookup in v is invisible, pixel for pixel, on ridges that run along v
  (``H = f(x)``) and visible on ridges across them (``H = f(y)``).
- On the cube's mirrored face, under a relief that is not symmetric in v (a sawtooth),
  ``ignore-handedness`` at least doubles the horizon map's |F - V| there.
"""

import dataclasses

import numpy as np
import pytest

from hzval.bake.maps import BakeParams, bake
from hzval.core.errors import InputError
from hzval.geometry import model, tangent_bugs
from hzval.scene import spec as sc
from hzval.techniques import registry as technique
from hzval.truth.model import ModelTruth


def _scene(n=32, bug="none", **kw):
    base = dict(
        size=n,
        depth=0.08,
        spp=2,
        azimuths="-45,30",
        boundary="open",
        camera="orthographic",
        view_elevation=60,
        view_azimuth=-90,
        resolution=(n, n),
    )
    base.update(kw)
    scn = sc.override(sc.Scene(), **base)
    return dataclasses.replace(scn, mesh=dataclasses.replace(scn.mesh, tangent_bug=bug))


def _quad(uvs):
    p = np.array([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], float)
    return model.build("quad", p, np.array(uvs, float), np.array([(0, 1, 2), (0, 2, 3)]))


XY = [(0, 0), (1, 0), (1, 1), (0, 1)]
MIRRORED_U = [(1, 0), (0, 0), (0, 1), (1, 1)]


def _frames(uvs, bug, n=16):
    scn = _scene(n, bug)
    h = np.zeros((n, n), np.float32)
    mt = ModelTruth(scn, h, _quad(uvs))
    return mt.samples().frames[mt.seen_samples]  # a missed sample keeps the world's frame


def _horizon(mt, scn, h):
    b = bake(h, BakeParams(depth=scn.material.depth, boundary=scn.material.boundary))
    ctx = technique.Context(scn, h, b, sc.load_albedo(scn.material, *h.shape), points=mt.samples())
    return technique.get("horizon").build(ctx)


def test_none_is_the_frames_themselves():
    f = np.random.default_rng(1).normal(size=(10, 12)).astype(np.float32)
    assert tangent_bugs.apply("none", f) is f
    with pytest.raises(InputError, match="--tangent-bug"):
        tangent_bugs.apply("upside-down", f)


def test_none_renders_as_before(variant):
    scn = _scene(24, mesh="cube", boundary="wrap", camera="perspective", view_azimuth=150)
    h = sc.load_material_height(scn.material).height
    a = ModelTruth(
        sc.override(
            sc.Scene(),
            size=24,
            depth=0.08,
            spp=2,
            azimuths="-45,30",
            boundary="wrap",
            camera="perspective",
            view_elevation=60,
            view_azimuth=150,
            resolution=(24, 24),
            mesh="cube",
        ),
        h,
        model.load("cube"),
    ).samples()
    b = ModelTruth(scn, h, model.load("cube")).samples()
    np.testing.assert_array_equal(a.frames, b.frames)
    np.testing.assert_array_equal(a.x, b.x)


def test_which_bug_shows_on_which_quad(variant):
    xy = {bug: _frames(XY, bug) for bug in tangent_bugs.NAMES}
    np.testing.assert_allclose(xy["ignore-handedness"], xy["none"], atol=1e-6)
    np.testing.assert_allclose(xy["per-face"], xy["none"], atol=1e-5)
    assert np.abs(xy["flip-green"] - xy["none"]).max() > 1.5  # b turned over
    np.testing.assert_array_equal(xy["swap-uv"][:, 0:3], xy["none"][:, 3:6])
    np.testing.assert_array_equal(xy["swap-uv"][:, 3:6], xy["none"][:, 0:3])
    mu = {bug: _frames(MIRRORED_U, bug) for bug in ("none", "ignore-handedness", "flip-green", "per-face")}
    np.testing.assert_allclose(mu["ignore-handedness"], mu["flip-green"], atol=1e-6)
    np.testing.assert_allclose(mu["per-face"], mu["none"], atol=1e-5)
    assert np.abs(mu["ignore-handedness"] - mu["none"]).max() > 1.5
    for f in list(xy.values()) + list(mu.values()):  # every bug's frame stays orthonormal
        t, b, n = f[:, 0:3], f[:, 3:6], f[:, 6:9]
        for u, v in ((t, b), (t, n), (b, n)):
            assert np.abs(np.sum(u * v, axis=1)).max() < 1e-5


def _ridges(n, along):
    """Asymmetric ridges (a sawtooth of period 8 texels): ``H = f(x)`` (``along="v"``) or ``f(y)``."""
    f = ((np.arange(n) % 8) / 7.0).astype(np.float32)
    return np.ascontiguousarray(np.tile(f, (n, 1)) if along == "v" else np.tile(f[::-1, None], (1, n)))


@pytest.mark.parametrize("bug", ["flip-green"])
def test_a_mirror_in_v_is_invisible_on_ridges_along_v(variant, bug):
    n = 32
    F = {}
    for along in ("v", "u"):
        h = _ridges(n, along)
        for b in ("none", bug):
            scn = _scene(n, b, azimuths="-60,60,150", boundary="wrap")  # no edge to mirror
            mt = ModelTruth(scn, h, _quad(XY))
            tech = _horizon(mt, scn, h)
            F[along, b] = np.stack(
                [tech.render(az).layers["factor"][mt.seen] for az in scn.light.azimuths_deg]
            )
    np.testing.assert_allclose(F["v", bug], F["v", "none"], atol=2e-3)
    assert np.abs(F["u", bug] - F["u", "none"]).mean() > 0.05


@pytest.mark.parametrize("frames", ["fged2", "mikktspace"])
def test_ignore_handedness_doubles_the_error_on_the_cubes_mirrored_face(variant, frames):
    """The cube's -x face is mirrored (w = -1; its b is +z). Lights that graze it from above, a
    sawtooth across v: dropping w sends each shadow up the face instead of down; with FGED2's frames
    and with MikkTSpace's alike."""
    n = 64
    h = _ridges(n, "u")
    err, mirrored = {}, None
    for bug in ("none", "ignore-handedness"):
        scn = _scene(
            n,
            bug,
            mesh="cube",
            boundary="wrap",
            camera="perspective",
            view_elevation=20,
            view_azimuth=180,
            azimuths="135,225",
            resolution=(48, 48),
            elevation=30,
        )
        mt = ModelTruth(scn, h, model.load("cube", tangents=frames))
        f = mt.samples().frames
        if mirrored is None:
            w = np.sign(np.sum(np.cross(f[:, 6:9], f[:, 0:3]) * f[:, 3:6], axis=1))
            mirrored = (w.reshape(-1, scn.spp) < 0).all(axis=1).reshape(mt.shape) & mt.seen
            assert mirrored.sum() > 200
        tech = _horizon(mt, scn, h)
        err[bug] = np.mean(
            [
                np.abs(tech.render(az).layers["factor"] - mt.render(az).layers["visibility"])[mirrored]
                for az in scn.light.azimuths_deg
            ]
        )
    assert err["ignore-handedness"] >= 2.0 * err["none"], err


SMALL = [
    "sweep",
    "--size",
    "24",
    "--depth",
    "0.1",
    "--spp",
    "1",
    "--azimuths",
    "-30,30",
    "--quiet",
    "--resolution",
    "32x32",
    "--technique",
    "horizon",
]


def test_a_sweep_records_its_bug(tmp_path):
    import json

    from hzval.cli import main as cli

    out = tmp_path / "bug"
    assert cli.main(SMALL + ["--mesh", "cube", "--tangent-bug", "swap-uv", "--out", str(out)]) == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["parameters"]["tangent_bug"] == "swap-uv"
    assert all(0.0 <= f["techniques"]["horizon"]["visibility_mae"] <= 1.0 for f in m["frames"])


@pytest.mark.parametrize(
    "extra,needle",
    [
        (["--mesh", "cube", "--tangent-bug", "upside-down"], "unknown tangent bug"),
        (["--camera", "orthographic", "--tangent-bug", "swap-uv"], "needs a model"),
    ],
)
def test_a_bad_bug_is_one_line(tmp_path, capsys, extra, needle):
    from hzval.cli import main as cli

    out = tmp_path / "out"
    assert cli.main(SMALL + extra + ["--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0] and "--tangent-bug" in err[0]
    assert not out.exists()


def _engine_frames(sweep, folder):
    """An engine's frames made of a sweep's own: its truth as the image, its horizon F (0 where the
    sweep saw nothing) as ``f_<name>.exr``."""
    import json

    from hzval.io import codecs

    folder.mkdir()
    for f in json.loads((sweep / "metrics.json").read_text())["frames"]:
        name = f["files"]["truth"].split("/")[-2]
        ch = codecs.read_exr(sweep / f["techniques"]["horizon"]["files"]["factor"])
        codecs.write_exr(folder / f"f_{name}.exr", {"Y": np.nan_to_num(next(iter(ch.values())), nan=0.0)})
        codecs.write_exr(folder / f"{name}.exr", codecs.read_exr(sweep / f["files"]["truth"]))
    return folder


@pytest.mark.parametrize("bug", ["ignore-handedness", "swap-uv", "none"])
def test_score_names_the_bug_of_frames_rendered_with_it(tmp_path, bug):
    """The cube seen from -x (its mirrored face) and +y: frames hzval renders with a bug, scored
    against the correct sweep, are named after that bug; the correct frames name none."""
    from hzval.cli import main as cli
    from hzval.commands import score

    args = [
        "sweep",
        "--size",
        "32",
        "--depth",
        "0.1",
        "--spp",
        "1",
        "--azimuths",
        "135,225",
        "--quiet",
        "--resolution",
        "40x40",
        "--technique",
        "horizon",
        "--mesh",
        "cube",
        "--view-azimuth",
        "150",
        "--view-elevation",
        "20",
    ]
    assert cli.main(args + ["--out", str(tmp_path / "ref")]) == 0
    assert cli.main(args + ["--tangent-bug", bug, "--out", str(tmp_path / "bugged")]) == 0
    result, _ = score.score(_engine_frames(tmp_path / "bugged", tmp_path / "engine"), tmp_path / "ref")
    match = result["tangent_bug"]
    assert match["best"] == bug
    assert match["named"] == (bug != "none")
    assert any(bug in w for w in result["warnings"]) == (bug != "none")
    for f in result["frames"]:  # V is NaN off the model: scored over the seen pixels
        assert 0.0 <= f["techniques"]["engine"]["visibility_mae"] <= 1.0


def test_per_face_is_faceted_on_a_curved_model(variant):
    """On the sphere the per-face frame is each triangle's own: constant over the triangle (as few
    distinct normals as triangles seen) and off the interpolated frame, which varies smoothly."""
    scn = _scene(16, "per-face", mesh="sphere", boundary="wrap", camera="perspective", resolution=(32, 32))
    h = np.zeros((16, 16), np.float32)
    sphere = model.load("sphere", shape_args={"segments": 12, "rings": 6})
    mt = ModelTruth(scn, h, sphere)
    face = mt.samples().frames[mt.seen_samples]
    none = (
        ModelTruth(
            dataclasses.replace(scn, mesh=dataclasses.replace(scn.mesh, tangent_bug="none")), h, sphere
        )
        .samples()
        .frames[mt.seen_samples]
    )
    assert len(np.unique(np.round(face[:, 6:9], 5), axis=0)) <= len(sphere.faces)
    assert len(np.unique(np.round(none[:, 6:9], 5), axis=0)) > 4 * len(sphere.faces)
    assert np.degrees(np.arccos(np.clip(np.sum(face[:, 6:9] * none[:, 6:9], axis=1), -1, 1))).max() > 5.0
