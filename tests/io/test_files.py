"""Outputs appear whole or not at all."""

import numpy as np
import pytest

from hzval.io import codecs, documents, staging


def test_staging_commits_all_files_together(tmp_path):
    out = tmp_path / "out"
    with staging.Staging(out) as stage:
        documents.write_json(stage.path("a.json"), {"x": 1}, atomic=False)
        codecs.write_png(stage.path("sub/b.png"), np.zeros((2, 2), np.uint8), atomic=False)
        assert not (out / "a.json").exists()  # nothing visible before commit
        stage.commit()
    assert sorted(p.name for p in out.rglob("*") if p.is_file()) == ["a.json", "b.png"]
    assert [p.name for p in out.iterdir() if p.name.startswith(".")] == []


def test_staging_leaves_nothing_when_interrupted(tmp_path):
    out = tmp_path / "out"
    with pytest.raises(RuntimeError):
        with staging.Staging(out) as stage:
            documents.write_json(stage.path("a.json"), {}, atomic=False)
            raise RuntimeError("disk full")
    assert not out.exists()


def test_staging_keeps_an_existing_folder_and_its_files(tmp_path):
    (tmp_path / "keep.txt").write_text("mine")
    with pytest.raises(RuntimeError):
        with staging.Staging(tmp_path) as stage:
            documents.write_json(stage.path("a.json"), {}, atomic=False)
            raise RuntimeError
    assert [p.name for p in tmp_path.iterdir()] == ["keep.txt"]


def test_atomic_write_keeps_the_old_file_on_failure(tmp_path):
    target = tmp_path / "x.json"
    documents.write_json(target, {"v": 1})
    with pytest.raises(TypeError):
        documents.write_json(target, {"v": object()})
    assert target.read_text().strip().endswith("}") and '"v": 1' in target.read_text()
    assert [p.name for p in tmp_path.iterdir()] == ["x.json"]


def test_exr_round_trip(tmp_path):
    rgba = np.random.default_rng(0).random((5, 7, 4)).astype(np.float32)
    codecs.write_exr(tmp_path / "a.exr", {"RGBA": rgba, "extra": rgba[..., 0]})
    back = codecs.read_exr(tmp_path / "a.exr")
    assert set(back) == {"R", "G", "B", "A", "extra"}
    assert np.array_equal(back["B"], rgba[..., 2]) and np.array_equal(back["extra"], rgba[..., 0])


def test_writers_wait_for_every_file_and_raise_a_writers_error(tmp_path):
    """Writers start at once; the block's end waits for them, and a writer's error is raised there after
    the others are done or cancelled."""
    import time

    def slow():
        time.sleep(0.05)
        (tmp_path / "slow").write_text("done")

    def fails():
        raise OSError("disk full")

    with pytest.raises(OSError, match="disk full"):
        with codecs.Writers() as writers:
            writers.submit(slow)
            writers.submit(fails)
    assert (tmp_path / "slow").read_text() == "done"
    with codecs.Writers() as writers:
        writers.submit(slow)
    assert (tmp_path / "slow").exists()
