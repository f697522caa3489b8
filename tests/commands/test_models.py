"""The curvature study's meshes (hzval.commands.models): caps on their sphere, UVs at one texture per
world unit, a bowl the cap's mirror; ``hzval models`` end to end (slow)."""

import json
import math

import numpy as np
import pytest

from hzval.commands import models as models_command
from hzval.geometry import model


@pytest.mark.parametrize("radius,sign", [(0.5, 1), (2.0, 1), (1.0, -1), (math.inf, 1)])
def test_a_cap_lies_on_its_sphere(tmp_path, radius, sign):
    path = tmp_path / "cap.obj"
    models_command.cap_obj(path, radius, sign)
    m = model.load(str(path), up="z")
    p, n = m.positions, m.normals
    if math.isinf(radius):
        assert np.abs(p[:, 2]).max() < 1e-9 and np.allclose(n, [0, 0, 1])
    else:
        centre = np.array([0.0, 0.0, -sign * radius])
        np.testing.assert_allclose(np.linalg.norm(p - centre, axis=1), radius, rtol=1e-6)
        np.testing.assert_allclose(
            n, sign * (p - centre) / radius, atol=1e-6
        )  # outward, or inward for a bowl
    assert n[:, 2].min() > 0  # every normal faces up
    assert abs(m.world_per_uv - 1.0) < 0.06  # one texture per world unit
    assert m.mirrored_fraction == 0.0


@pytest.mark.slow
def test_the_study_end_to_end(tmp_path):
    from hzval.cli import main as cli

    out = tmp_path / "m"
    assert (
        cli.main(
            [
                "models",
                "--material",
                "spikes",
                "--size",
                "24",
                "--resolution",
                "24x24",
                "--spp",
                "1",
                "--azimuths",
                "0,180",
                "--quiet",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    d = json.loads((out / "models.json").read_text())
    cases = [r["case"] for r in d["rows"]]
    assert cases == [f"cap+{r:g}" for r in models_command.RADII] + [
        f"bowl+{r:g}" for r in models_command.BOWLS
    ] + ["ring", "flat", "cube"]
    for r in d["rows"]:
        assert 0.0 <= r["techniques"]["horizon"]["visibility_mae"] <= 1.0
        assert 0.0 < r["techniques"]["horizon"]["reflection_mae"] < 1.0  # reflection occlusion by default
        assert r["techniques"]["pom"]["reflection_mae"] is None  # pom has no fade
        band = r["band"]["techniques"]["horizon"]
        assert 0.0 <= band["mae"]["mean"] <= 1.0 and band["mae"]["se"] >= 0.0
        assert ("excess" in band) == (r["case"] not in ("flat", "cube"))
        assert ("seam" in band) == (r["case"] == "cube")  # the cube alone has seams
    rows = {r["case"]: r for r in d["rows"]}
    # the truth is more lit on a convex cap than on the flat patch's same texels, less in a bowl
    assert rows["cap+0.5"]["band"]["lit_excess"]["mean"] > 0 > rows["bowl+1"]["band"]["lit_excess"]["mean"]
    assert d["trend"]["horizon"]["mae"]["verdict"] in (
        "rises monotonically",
        "rises within noise",
        "does not rise",
    )
    assert rows["ring"]["principal_curvatures"] == {"along_ring_x": -0.5, "across_tube_y": 1.0}
    assert (out / "index.html").is_file() and (out / "plots" / "models.png").is_file()
    assert (out / "plots" / "reflection.png").is_file()
    bugs = d["bugs"]["cases"]
    assert set(bugs) == {"cube", "mirrored-sphere"} and (out / "plots" / "bugs.png").is_file()
    assert all(c["bugs"]["none"]["mirrored_ratio"] == 1.0 for c in bugs.values())
    assert "Tangent-bug signatures" in (out / "index.html").read_text()


def test_the_ring_is_concave_along_the_ring_and_convex_across_the_tube(tmp_path):
    tube, rho = models_command.RING
    path = tmp_path / "ring.obj"
    models_command.ring_obj(path, tube, rho)
    m = model.load(str(path), up="z")
    p, n = m.positions, m.normals
    assert np.allclose(p[np.argmin(np.linalg.norm(p, axis=1))], 0.0) and n[:, 2].min() > 0
    on_x, on_y = np.abs(p[:, 1]) < 1e-12, np.abs(p[:, 0]) < 1e-12
    x, zx = p[on_x, 0], p[on_x, 2]
    y, zy = p[on_y, 1], p[on_y, 2]
    # the normal curvature is the height's second derivative at the centre: z ~ k_n s^2 / 2 toward n
    kx = np.polyfit(x, zx, 4)[2] * 2
    ky = np.polyfit(y, zy, 4)[2] * 2
    assert kx == pytest.approx(1.0 / rho, rel=0.02)  # bends toward +n (up): concave along x
    assert ky == pytest.approx(-1.0 / tube, rel=0.02)  # bends away: convex across the tube
    # every point lies on the torus: distance to the tube's centre circle is the tube radius
    c = np.array([0.0, 0.0, rho])
    q = p - c
    radial = np.hypot(q[:, 0], q[:, 2])
    np.testing.assert_allclose(np.hypot(radial - (rho + tube), q[:, 1]), tube, rtol=1e-6)
    assert abs(m.world_per_uv - 1.0) < 0.03


def test_the_rings_normal_curvature_along_each_light_is_eulers():
    row = {
        "principal_curvatures": {"along_ring_x": -0.5, "across_tube_y": 1.0},
        "band": {"techniques": {"horizon": {"per_frame_excess": [0.1, 0.2, 0.3]}}},
    }
    by = models_command._by_azimuth(row, (0.0, 45.0, 90.0))
    assert [round(b["normal_curvature"], 12) for b in by] == [-0.5, 0.25, 1.0]
    assert [b["excess"]["horizon"] for b in by] == [0.1, 0.2, 0.3]


def test_the_terminal_table_shows_reflection_and_the_bugs():
    t = {"visibility_mae": 0.1, "perfect_parallax_mae": 0.05, "reflection_mae": 0.2}
    data = {
        "rows": [
            {"case": "flat", "curvature": 0.0, "techniques": {"horizon": t}},
            {"case": "cube", "curvature": None, "techniques": {"horizon": {**t, "reflection_mae": None}}},
        ],
        "bugs": {
            "technique": "horizon",
            "cases": {
                "cube": {"bugs": {"none": {"mirrored_ratio": 1.0}, "swap-uv": {"mirrored_ratio": 1.5}}}
            },
        },
    }
    text = models_command.summary_table(data).splitlines()
    assert "horizon |o-R|" in text[0] and text[1].split()[-1] == "0.2000" and text[2].split()[-1] == "-"
    assert text[-1].endswith("swap-uv 1.50x") and "none" not in text[-1].split(":")[-1]
    assert text[2].split()[:2] == ["cube", "-"] and "nan" not in "\n".join(text).lower()  # no 1/R on a cube
