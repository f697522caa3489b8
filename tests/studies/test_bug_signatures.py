"""Tangent-bug signatures on models with mirrored UVs (hzval.studies.bug_signatures, the built-in
mirrored sphere): a bug of the handedness touches only the mirrored half, pixel for pixel."""

import numpy as np

from hzval.geometry import model, tangent_bugs
from hzval.geometry import tangents as tg
from hzval.scene import spec as sc
from hzval.studies import bug_signatures


def test_mirrored_sphere_mirrors_the_minus_y_half():
    m = model.load("mirrored-sphere", shape_args={"segments": 16, "rings": 8})
    assert abs(m.mirrored_fraction - 0.5) < 1e-12
    y, w = m.positions[:, 1], m.tangents[:, 3]
    assert (w[y > 1e-9] == 1).all() and (w[y < -1e-9] == -1).all()
    # a point and its mirror image in the xz plane read the same texel
    # a point and its mirror image in the xz plane read the same texel (the poles' vertices aside:
    # one position, one UV per column)
    body = np.abs(m.positions[:, 2]) < 1 - 1e-9
    key = {tuple(np.round(p * [1, -1, 1], 9)): uv for p, uv in zip(m.positions[body], m.uvs[body])}
    hits = [
        np.allclose(key[tuple(np.round(p, 9))], uv)
        for p, uv in zip(m.positions[body], m.uvs[body])
        if tuple(np.round(p, 9)) in key
    ]
    assert len(hits) == body.sum() and all(hits)
    assert np.allclose(np.linalg.norm(m.tangents[:, :3], axis=1), 1)


def test_handedness_is_the_frames_sign():
    rng = np.random.default_rng(0)
    t, n = rng.normal(size=(50, 3)), rng.normal(size=(50, 3))
    w = rng.choice([-1.0, 1.0], 50)
    assert (tg.handedness(t, w[:, None] * np.cross(n, t), n) == w).all()


def test_a_handedness_bug_moves_only_the_mirrored_half():
    scn = sc.override(
        sc.Scene(),
        height="spikes",
        size=32,
        spp=1,
        azimuths="-40,40",
        camera="orthographic",
        resolution=(32, 32),
    )
    h = sc.load_material_height(scn.material).height
    rec, maps = bug_signatures.measure(scn, h, "horizon", "mirrored-sphere", 0.0, -90.0, uv_scale=2.0)
    bugs = rec["bugs"]
    assert rec["mirrored_pixels"] > 50 and rec["unmirrored_pixels"] > 50
    assert set(bugs) == set(tangent_bugs.NAMES)
    # ignore-handedness: the unmirrored half is the correct render, bit for bit; the mirrored one is not
    assert bugs["ignore-handedness"]["unmirrored"] == bugs["none"]["unmirrored"]
    assert bugs["ignore-handedness"]["mirrored"] != bugs["none"]["mirrored"]
    # on the mirrored half flip-green is ignore-handedness (both give b = n x t there)
    assert bugs["flip-green"]["mirrored"] == bugs["ignore-handedness"]["mirrored"]
    assert bugs["none"]["mirrored_ratio"] == 1.0
    seen = ~np.isnan(maps["none"])
    assert seen.any() and np.nanmax(np.abs(maps["swap-uv"])) <= 1.0


def test_a_sweep_splits_the_error_by_handedness(tmp_path):
    """metrics.json's visibility_mae_mirrored / _unmirrored: a handedness bug moves only the first."""
    import json

    from hzval.cli import main as cli

    small = [
        "sweep",
        "--material",
        "spikes",
        "--size",
        "24",
        "--spp",
        "1",
        "--azimuths",
        "210,270",
        "--resolution",
        "32x32",
        "--mesh",
        "cube",
        "--view-azimuth",
        "150",
        "--techniques",
        "horizon",
    ]
    got = {}
    for bug in ("none", "ignore-handedness"):
        out = tmp_path / bug
        assert cli.main(small + ["--tangent-bug", bug, "--out", str(out), "--quiet"]) == 0
        got[bug] = [
            f["techniques"]["horizon"] for f in json.loads((out / "metrics.json").read_text())["frames"]
        ]
    for a, b in zip(got["none"], got["ignore-handedness"]):
        assert a["visibility_mae_unmirrored"] == b["visibility_mae_unmirrored"]
        assert 0.0 <= a["visibility_mae_mirrored"] <= 1.0
    assert [a["visibility_mae_mirrored"] for a in got["none"]] != [
        b["visibility_mae_mirrored"] for b in got["ignore-handedness"]
    ]
