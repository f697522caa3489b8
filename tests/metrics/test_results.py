"""The typed records over ``metrics.json`` and ``suite.json`` (:mod:`hzval.metrics.results`).

They must hand back the JSON they wrap unchanged, keep the run's order, read a damaged file leniently
(a wrong type reads as missing) and refuse to be written through.
"""

import copy
import json

import pytest

from hzval.metrics import results


def _metrics() -> dict:
    """A ``metrics.json`` of two techniques over two frames, in the sweep's layout."""
    return {
        "schema": 2,
        "parameters": {"techniques": ["horizon", "pom"]},
        "techniques": {
            "horizon": {"label": "horizon map", "file_stem": "hz", "parameters": {"k": 4}},
            "pom": {"fit_of": "horizon"},
        },
        "frames": [
            {
                "azimuth_deg": 0,
                "elevation_deg": 30.5,
                "techniques": {
                    "horizon": {"visibility_mae": 0.02, "flip_mean": 0.1, "files": {"png": "f0/hz.png"}},
                    "pom": {"visibility_mae": 0.01, "visibility_mae_facing": 0.03, "seconds": 2},
                },
                "no_shadows": {"visibility_mae": 0.2},
                "floor": {"flip_mean": 0.0},
                "files": {"image": "f0/truth.exr"},
            },
            {"azimuth_deg": 90, "elevation_deg": 30.5, "techniques": {"pom": {"visibility_mae": 0.05}}},
        ],
    }


def test_to_json_is_the_wrapped_object_and_writes_byte_for_byte():
    data = _metrics()
    before = json.dumps(data, indent=2)
    r = results.SweepResult.of(data)
    assert r.to_json() is data
    # reading every attribute leaves the JSON as it was
    [(f.techniques, f.no_shadows, f.floor, f.files) for f in r.frames]
    [(i.label, i.file_stem, i.parameters, i.fit_of) for i in r.techniques.values()]
    assert json.dumps(r.to_json(), indent=2) == before


def test_attributes_read_the_json():
    r = results.SweepResult.of(_metrics())
    assert r.names == ["horizon", "pom"] and r.chosen == ["horizon", "pom"]
    hz, pom = r.techniques["horizon"], r.techniques["pom"]
    assert (hz.label, hz.file_stem, hz.parameters, hz.fit_of) == ("horizon map", "hz", {"k": 4}, None)
    # a technique without a label or stem is named by its key
    assert (pom.label, pom.file_stem, pom.parameters, pom.fit_of) == ("pom", "pom", {}, "horizon")
    f0, f1 = r.frames
    assert (f0.azimuth_deg, f0.elevation_deg, f1.azimuth_deg) == (0.0, 30.5, 90.0)
    s = f0.scores("pom")
    assert (s.visibility_mae, s.visibility_mae_facing, s.flip_mean, s.seconds) == (0.01, 0.03, None, 2.0)
    assert isinstance(s.seconds, float)
    assert f0.scores("horizon").files == {"png": "f0/hz.png"}
    assert f0.no_shadows.visibility_mae == 0.2 and f0.floor.flip_mean == 0.0
    assert f1.scores("horizon") is None and f1.no_shadows is None and f1.files == {}


def test_order_follows_the_json():
    """Reordering the techniques reorders every reader: the run's order is the JSON's, not sorted."""
    data = _metrics()
    data["techniques"] = dict(reversed(data["techniques"].items()))
    data["frames"][0]["techniques"] = dict(reversed(data["frames"][0]["techniques"].items()))
    r = results.SweepResult.of(data)
    assert r.names == ["pom", "horizon"]
    assert list(r.frames[0].techniques) == ["pom", "horizon"]


def _pom(r):
    """The first frame's pom scores, as the record reads them."""
    return r.frames[0].scores("pom")


def _raw_pom(d):
    """The first frame's pom scores, as the JSON holds them."""
    return d["frames"][0]["techniques"]["pom"]


@pytest.mark.parametrize(
    "damage, check",
    [
        (lambda d: d.update(frames="none"), lambda r: r.frames == []),
        (lambda d: d["frames"].insert(0, 3), lambda r: [f.azimuth_deg for f in r.frames] == [0.0, 90.0]),
        (lambda d: d.update(techniques=["horizon"]), lambda r: r.techniques == {} and r.names == []),
        (lambda d: d["techniques"].update(pom="ray march"), lambda r: r.names == ["horizon"]),
        (lambda d: _raw_pom(d).update(seconds=True), lambda r: _pom(r).seconds is None),
        (lambda d: _raw_pom(d).update(seconds="2"), lambda r: _pom(r).seconds is None),
        (lambda d: d["frames"][0].update(no_shadows=0.2), lambda r: r.frames[0].no_shadows is None),
        (lambda d: d["techniques"]["pom"].update(fit_of=1), lambda r: r.techniques["pom"].fit_of is None),
        (lambda d: d["parameters"].update(techniques=["pom", 7]), lambda r: r.chosen == ["pom"]),
        (lambda d: d.pop("parameters"), lambda r: r.chosen == []),
    ],
    ids=["frames-not-list", "frame-not-object", "techniques-not-object", "technique-not-object",
         "bool-not-number", "string-not-number", "scores-not-object", "fit_of-not-string",
         "chosen-not-string", "no-parameters"],
)  # fmt: skip
def test_a_damaged_file_reads_as_missing(damage, check):
    data = _metrics()
    damage(data)
    assert check(results.SweepResult.of(data))


def test_malformed_and_raw_techniques():
    data = _metrics()["frames"][0]
    data["techniques"]["broken"] = [1]
    assert results.malformed_techniques(data) == ["broken"]
    assert list(results.techniques_of(data)) == ["horizon", "pom"]
    assert results.raw_techniques(data) is data["techniques"]
    assert results.raw_techniques({}) == {} and results.raw_techniques({"techniques": None}) == {}
    assert results.raw_techniques({"techniques": [1]}) is None
    assert results.malformed_techniques(None) == [] and results.techniques_of(None) == {}


def test_records_are_read_only_and_shared():
    data = _metrics()
    r = results.SweepResult.of(data)
    with pytest.raises(TypeError):
        r["schema"] = 3
    assert results.SweepResult.of(r) is r
    # another kind of record over the same JSON shares it rather than copying
    suite = results.SuiteResult.of(r)
    assert suite.record is data
    r.set_techniques({"pom": {}})
    assert data["techniques"] == {"pom": {}} and r.names == ["pom"]


def test_technique_info_needs_its_name():
    with pytest.raises(TypeError, match="needs its name"):
        results.TechniqueInfo.of({"label": "x"})


def test_suite_result():
    row = copy.deepcopy(_metrics()["frames"][0])
    suite = {"techniques": {"pom": {"label": "ray march"}}, "materials": [row, "bad", {"no_shadows": {}}]}
    s = results.SuiteResult.of(suite)
    assert s.names == ["pom"] and s.techniques["pom"].label == "ray march"
    assert len(s.materials) == 2
    assert list(s.materials[0].techniques) == ["horizon", "pom"]
    assert s.materials[0].no_shadows.visibility_mae == 0.2
    assert s.materials[1].techniques == {} and s.materials[1].no_shadows is not None
    assert results.SuiteResult.of({"materials": "x"}).materials == []
