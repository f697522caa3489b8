"""The curvature study's meshes (hzval.models_study): caps on their sphere, UVs at one texture per
world unit, a bowl the cap's mirror; ``hzval models`` end to end (slow)."""

import json
import math

import numpy as np
import pytest

from hzval import model, models_study


@pytest.mark.parametrize("radius,sign", [(0.5, 1), (2.0, 1), (1.0, -1), (math.inf, 1)])
def test_a_cap_lies_on_its_sphere(tmp_path, radius, sign):
    path = tmp_path / "cap.obj"
    models_study.cap_obj(path, radius, sign)
    m = model.load(str(path), up="z")
    p, n = m.positions, m.normals
    if math.isinf(radius):
        assert np.abs(p[:, 2]).max() < 1e-9 and np.allclose(n, [0, 0, 1])
    else:
        centre = np.array([0.0, 0.0, -sign * radius])
        np.testing.assert_allclose(np.linalg.norm(p - centre, axis=1), radius, rtol=1e-6)
        np.testing.assert_allclose(n, sign * (p - centre) / radius, atol=1e-6)   # outward, or inward for a bowl
    assert n[:, 2].min() > 0                                                     # every normal faces up
    assert abs(m.world_per_uv - 1.0) < 0.06                                      # one texture per world unit
    assert m.mirrored_fraction == 0.0


@pytest.mark.slow
def test_the_study_end_to_end(tmp_path):
    from hzval import cli

    out = tmp_path / "m"
    assert cli.main(["models", "--material", "spikes", "--size", "24", "--resolution", "24x24", "--spp", "1",
                     "--azimuths", "0,180", "--quiet", "--out", str(out)]) == 0
    d = json.loads((out / "models.json").read_text())
    cases = [r["case"] for r in d["rows"]]
    assert cases == [f"cap+{r:g}" for r in models_study.RADII] + [f"bowl+{r:g}" for r in models_study.BOWLS] \
        + ["flat", "cube"]
    for r in d["rows"]:
        assert 0.0 <= r["techniques"]["horizon"]["visibility_mae"] <= 1.0
        assert 0.0 < r["techniques"]["horizon"]["reflection_mae"] < 1.0      # reflection occlusion by default
        assert r["techniques"]["pom"]["reflection_mae"] is None               # pom has no fade
    assert (out / "index.html").is_file() and (out / "plots" / "models.png").is_file()
    assert (out / "plots" / "reflection.png").is_file()
    bugs = d["bugs"]["cases"]
    assert set(bugs) == {"cube", "mirrored-sphere"} and (out / "plots" / "bugs.png").is_file()
    assert all(c["bugs"]["none"]["mirrored_ratio"] == 1.0 for c in bugs.values())
    assert "Tangent-bug signatures" in (out / "index.html").read_text()
