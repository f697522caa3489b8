"""Fuzz-style faults (issue 42): every reader of a JSON or TOML file, fed truncated, deeply nested
and wrong-typed versions of a valid file, answers with its result or one :class:`InputError` line,
never another exception.

Each reader starts from a file hzval itself wrote (or a valid hand-written one), then Hypothesis
replaces one value anywhere in it (up to four levels deep) with any JSON or TOML value, or deletes
it; fixed examples add the truncations, a nesting far past :data:`hzval.io.documents.MAX_DEPTH`, an
empty file and bytes that are not UTF-8. Examples are derandomised: the run is the same every time.
Each reader must accept its seed, and a share of the generated cases (:data:`ACCEPTED`), so that
the test reaches past the first refusal. Images and the gates' grammar: test_fuzz_readers.py.
"""

from __future__ import annotations

import copy
import json
import shutil
import tomllib
from pathlib import Path

import pytest
import tomli_w
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hzval import materials
from hzval.bake import maps as bake
from hzval.cli import main as cli
from hzval.commands import gates
from hzval.commands import score as score_cmd
from hzval.core.errors import InputError
from hzval.geometry import model
from hzval.io import external, staging
from hzval.scene import files as scene_files
from hzval.scene import spec as sc
from tests.helpers import QUAD_F, QUAD_P, QUAD_UV, write_gltf

SETTINGS = settings(
    max_examples=30,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=list(HealthCheck),
)

scalars = st.one_of(
    st.booleans(),
    st.integers(-(2**70), 2**70),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=6),
)


def values(toml: bool):
    leaf = scalars if toml else st.one_of(st.none(), scalars)
    return st.recursive(
        leaf,
        lambda c: st.lists(c, max_size=3) | st.dictionaries(st.text(max_size=4), c, max_size=3),
        max_leaves=6,
    )


def paths_in(doc, depth: int = 4, prefix=()) -> list[tuple]:
    """Every key path of ``doc`` down to ``depth`` (a list's first two items)."""
    out = []
    items = doc.items() if isinstance(doc, dict) else enumerate(doc[:2]) if isinstance(doc, list) else []
    for k, v in items:
        out.append((*prefix, k))
        if depth > 1:
            out += paths_in(v, depth - 1, (*prefix, k))
    return out


@st.composite
def mutated(draw, doc, toml: bool):
    """``doc`` with one value replaced by any value, or deleted."""
    doc = copy.deepcopy(doc)
    path = draw(st.sampled_from(paths_in(doc)))
    parent = doc
    for k in path[:-1]:
        parent = parent[k]
    if isinstance(parent, dict) and draw(st.booleans()) and draw(st.booleans()):
        del parent[path[-1]]
    else:
        parent[path[-1]] = draw(values(toml))
    return doc


def dump(doc, toml: bool) -> str:
    return tomli_w.dumps(doc) if toml else json.dumps(doc)


def fixed_texts(text: str) -> list[bytes]:
    """The truncations, the deep nestings, an empty file and bytes that are not UTF-8."""
    raw = text.encode()
    return [raw[: len(raw) // 3], raw[: 2 * len(raw) // 3], raw[:-1], b"", b"\xff\xfe\x00", b"[" * 100_000]


def answers(reader, path: Path, data: bytes) -> bool:
    """``reader`` on ``path`` holding ``data``: a result (``True``), or one line of InputError
    (``False``); anything else fails the test."""
    path.write_bytes(data)
    try:
        reader()
    except InputError as exc:
        assert "\n" not in str(exc), str(exc)
        return False
    return True


# --------------------------------------------------------------------------------------------------
# The files and their readers
# --------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def sweep_dir(tmp_path_factory, variant):
    out = tmp_path_factory.mktemp("fuzz") / "sweep"
    argv = ["sweep", "--size", "16", "--azimuths", "0,90", "--spp", "1", "--techniques", "horizon"]
    assert cli.main([*argv, "--quiet", "--all-files", "--out", str(out)]) == 0
    frames = out.parent / "engine"
    frames.mkdir()
    for f in json.loads((out / "frames.json").read_text())["frames"]:
        shutil.copyfile(out / "frames" / f["name"] / "horizon.exr", frames / f"{f['name']}.exr")
    # a sidecar the reader accepts: [engine] and [parameters] (a top-level label is refused)
    (frames / "engine.toml").write_text(
        '[engine]\nlabel = "engine"\nsummary = "a test renderer"\n[parameters]\nexposure = 1.0\nmips = 4\n'
    )
    return out, frames


def _copy(tmp_path_factory, src: Path) -> Path:
    dst = tmp_path_factory.mktemp("case") / src.name
    shutil.copytree(src, dst)
    return dst


def readers(sweep_dir, tmp_path_factory):
    """``{name: (file, reader, toml)}``: a fresh copy of each file and its reader."""
    sweep, frames = sweep_dir
    s, f = _copy(tmp_path_factory, sweep), _copy(tmp_path_factory, frames)
    own = (sweep / "metrics.json").read_text()
    b = _copy(tmp_path_factory, sweep / "bake")
    h = materials.generate(sc.Scene().material.height, 16).height
    record = json.loads((b / "bake.json").read_text())
    params = bake.BakeParams.from_record(bake.BakeParams.normalise_record(record["parameters"]))
    gltf_dir = tmp_path_factory.mktemp("gltf")
    gltf = Path(write_gltf(gltf_dir / "q.gltf", QUAD_P, QUAD_UV, QUAD_F))
    scene = tmp_path_factory.mktemp("scene") / "s.toml"
    scene.write_text('[material]\nheight = "gravel"\nsize = 16\n[light]\nazimuths = [0, 90]\n')
    enc = tmp_path_factory.mktemp("enc") / "e.toml"
    enc.write_text('[encoding]\nchannels = 8\nazimuth0 = 0.0\ndirection = "ccw"\n')
    return {
        "frames.json (score)": (s / "frames.json", lambda: score_cmd.score(f, s), False),
        "metrics.json (score)": (s / "metrics.json", lambda: score_cmd.score(f, s), False),
        "engine.toml (score)": (f / "engine.toml", lambda: score_cmd.score(f, s), True),
        "metrics.json (--baseline)": (s / "metrics.json", lambda: gates.read_baseline(s), False),
        # read, then compared with the run's own: the tests a baseline feeds
        "metrics.json (--baseline, compared)": (
            s / "metrics.json",
            lambda: gates.Gates(["horizon.flip_mean>1"], s).failures(json.loads(own)),
            False,
        ),
        "scene (--scene)": (scene, lambda: scene_files.load_scene(scene), True),
        "encoding (--horizon-encoding)": (enc, lambda: external.Encoding.from_toml(enc), True),
        "bake.json (a cached bake)": (
            b / "bake.json",
            lambda: bake.cached_bake(h, record["input"]["digest"], params, b, {}, write_to=b.parent / "new"),
            False,
        ),
        "glTF (--mesh)": (gltf, lambda: model.load(str(gltf)), False),
        "the folder's marker": (s / staging.MARKER_NAME, lambda: staging.foreign_files(s), False),
    }


NAMES = [
    "frames.json (score)",
    "metrics.json (score)",
    "engine.toml (score)",
    "metrics.json (--baseline)",
    "metrics.json (--baseline, compared)",
    "scene (--scene)",
    "encoding (--horizon-encoding)",
    "bake.json (a cached bake)",
    "glTF (--mesh)",
    "the folder's marker",
]


#: The least share of the generated cases each reader must accept: a seed it refused, or mutations
#: that never get past its first check, would test nothing (the sidecar's seed was once refused whole).
ACCEPTED = 0.1


@pytest.mark.parametrize("name", NAMES)
def test_every_reader_answers_broken_files_in_one_line(name, sweep_dir, tmp_path_factory):
    path, reader, toml = readers(sweep_dir, tmp_path_factory)[name]
    text = path.read_text()
    assert answers(reader, path, text.encode()), f"the seed of {name} is refused"
    for data in fixed_texts(text):
        answers(reader, path, data)
    doc = tomllib.loads(text) if toml else json.loads(text)
    accepted = []

    @SETTINGS
    @given(mutated(doc, toml))
    def fuzz(changed):
        accepted.append(answers(reader, path, dump(changed, toml).encode()))

    fuzz()
    share = sum(accepted) / len(accepted)
    print(f"{name}: {share:.0%} of {len(accepted)} cases accepted")
    assert share >= ACCEPTED, f"{name}: only {share:.0%} of the cases got past the reader's checks"


def test_the_readers_list_is_every_reader(sweep_dir, tmp_path_factory):
    assert sorted(readers(sweep_dir, tmp_path_factory)) == sorted(NAMES)
