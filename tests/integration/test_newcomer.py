"""What a new user trips on (issue 41), one test (or a few) for each reproduction fixed so far."""

from __future__ import annotations

import errno
import os

import numpy as np
import pytest

from hzval.cli import main as cli


def one_line_naming(err: str, *needles: str) -> None:
    assert err.startswith("hzval: error: ") and err.count("\n") == 1, err
    assert "usage:" not in err and "Traceback" not in err
    for n in needles:
        assert n in err, (n, err)


# 7. Errors that name the flag ------------------------------------------------------------------


@pytest.mark.parametrize(
    "argv, flag",
    [
        (["sweep", "--light", "medium"], "--light"),
        (["sweep", "--spp", "x"], "--spp"),
        (["views", "--size", "1.5"], "--size"),
        (["score", "frames"], "--against"),
    ],
)
def test_an_argument_error_is_one_line_naming_the_flag_and_the_help(argv, flag, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(argv)
    assert exc.value.code == 2
    one_line_naming(capsys.readouterr().err, flag, f"see 'hzval {argv[0]} --help'")


@pytest.mark.parametrize("elevation", ["95", "-5", "0", "nan"])
def test_a_light_elevation_outside_0_to_90_is_refused_naming_the_flag(elevation, tmp_path, capsys):
    assert cli.main(["sweep", "--elevation", elevation, "--out", str(tmp_path / "o")]) == 2
    one_line_naming(capsys.readouterr().err, "--elevation", "(0, 90]")
    assert not (tmp_path / "o").exists()


def test_a_folder_that_cannot_be_written_is_named_not_its_lock_file(tmp_path, monkeypatch, capsys):
    from hzval.io import staging

    real = os.open

    def read_only(path, *a, **k):
        if str(path).endswith(staging.LOCK_NAME):
            raise PermissionError(errno.EACCES, "Permission denied", str(path))
        return real(path, *a, **k)

    monkeypatch.setattr(os, "open", read_only)
    out = tmp_path / "ro"
    assert cli.main(["sweep", "--size", "16", "--azimuths", "0", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    one_line_naming(err, str(out), "cannot be written")
    assert staging.LOCK_NAME not in err


def test_score_against_a_frames_folder_never_advises_writing_into_it(tmp_path, capsys):
    frames = tmp_path / "frames"
    frames.mkdir()
    np.save(frames / "note.npy", np.zeros(1))
    assert cli.main(["score", str(frames), "--against", str(frames)]) == 2
    err = capsys.readouterr().err
    one_line_naming(err, "--against", "is not a sweep's folder")
    assert f"--out {frames}" not in err


# 3. One rule for inputs --------------------------------------------------------------------------


def _photo(tmp_path, name: str, colour: bool, size: int = 24):
    from PIL import Image

    from hzval import materials

    h = materials.generate("gravel", size).height
    h = (h - h.min()) / (h.max() - h.min())
    pixels = np.stack([h, 0.8 * h, 0.3 * h], -1) if colour else h
    Image.fromarray((pixels * 255).astype(np.uint8)).save(tmp_path / name)
    return tmp_path / name


@pytest.mark.parametrize(
    "name, colour", [("c.png", True), ("c.jpg", True), ("g.jpg", False), ("g.tif", False)]
)
def test_any_image_pillow_reads_is_a_height_map_and_colour_says_so(tmp_path, capsys, name, colour):
    path = _photo(tmp_path, name, colour)
    argv = ["sweep", str(path), "--azimuths", "0", "--spp", "1", "--techniques", "horizon", "--quiet"]
    assert cli.main([*argv, "--out", str(tmp_path / "o")]) == 0
    err = capsys.readouterr().err
    said = [line for line in err.splitlines() if "a colour image, read as heights by its luminance" in line]
    assert len(said) == (1 if colour else 0), err


def test_a_jpeg_is_read_as_its_luminance():
    import tempfile
    from pathlib import Path

    from PIL import Image

    from hzval.core.srgb import luminance_weights
    from hzval.io import heightmap

    with tempfile.TemporaryDirectory() as d:
        rgb = np.random.default_rng(2).integers(0, 256, (9, 11, 3)).astype(np.uint8)
        Image.fromarray(rgb).save(Path(d) / "a.bmp")  # lossless, so the samples are known
        hm = heightmap.load_height(Path(d) / "a.bmp")
    np.testing.assert_allclose(hm.height, (rgb / 255.0) @ luminance_weights(), atol=1e-6)
    assert hm.colour and hm.height.shape == (9, 11)


@pytest.mark.parametrize("pixels, why", [(np.zeros((7, 30)), "at least 8x8")])
def test_a_tiny_map_is_refused_in_one_line(tmp_path, capsys, pixels, why):
    """(A flat map runs: the null test of tests/integration/test_user_trial.py.)"""
    np.save(tmp_path / "m.npy", pixels)
    assert cli.main(["sweep", str(tmp_path / "m.npy"), "--out", str(tmp_path / "o")]) == 2
    one_line_naming(capsys.readouterr().err, "m.npy", why)
    assert not (tmp_path / "o").exists()


# 6. Misnamed files are named, not ignored in silence ----------------------------------------------


@pytest.fixture(scope="module")
def small_sweep(tmp_path_factory, variant):
    out = tmp_path_factory.mktemp("newcomer") / "sweep"
    argv = ["sweep", "--size", "16", "--azimuths", "0,90", "--spp", "1", "--techniques", "horizon"]
    assert cli.main([*argv, "--quiet", "--all-files", "--out", str(out)]) == 0
    return out


def engine_frames_named(tmp_path, sweep, pattern: str):
    import json
    import shutil

    frames = tmp_path / "frames"
    frames.mkdir()
    for f in json.loads((sweep / "frames.json").read_text())["frames"]:
        shutil.copyfile(sweep / "frames" / f["name"] / "horizon.exr", frames / f"{f['name']}.exr")
        shutil.copyfile(
            sweep / "frames" / f["name"] / "horizon_factor.exr", frames / pattern.format(f["name"])
        )
    return frames


def test_misnamed_factor_files_are_named_in_a_warning(small_sweep, tmp_path, capsys):
    frames = engine_frames_named(tmp_path, small_sweep, "{}_F.exr")  # instead of f_az+0.exr
    assert cli.main(["score", str(frames), "--against", str(small_sweep), "--out", str(tmp_path / "o")]) == 0
    err = capsys.readouterr().err
    line = next(w for w in err.splitlines() if "match no frame" in w)
    assert "az+0_F.exr" in line and "f_<name>.exr" in line and "az+0" in line


def test_strict_makes_them_an_error(small_sweep, tmp_path, capsys):
    frames = engine_frames_named(tmp_path, small_sweep, "{}_F.exr")
    argv = ["score", str(frames), "--against", str(small_sweep), "--strict", "--out", str(tmp_path / "o")]
    assert cli.main(argv) == 2
    one_line_naming(capsys.readouterr().err, "--strict", "az+0_F.exr")
    assert not (tmp_path / "o").exists()


def test_well_named_frames_get_no_warning(small_sweep, tmp_path, capsys):
    frames = engine_frames_named(tmp_path, small_sweep, "f_{}.exr")
    assert cli.main(["score", str(frames), "--against", str(small_sweep), "--out", str(tmp_path / "o")]) == 0
    assert "match no frame" not in capsys.readouterr().err


# 2. The Reproduce line runs -------------------------------------------------------------------------


def test_the_reproduce_line_runs_from_where_the_sweep_ran_and_gives_the_same_scores(
    tmp_path, monkeypatch, variant
):
    import html
    import json
    import re
    import shlex

    from hzval import materials

    work = tmp_path / "work"
    (work / "maps").mkdir(parents=True)
    np.save(work / "maps" / "mymap.npy", materials.generate("gravel", 16).height)
    monkeypatch.chdir(work)
    argv = ["sweep", "maps/mymap.npy", "--azimuths", "0", "--spp", "1", "--techniques", "horizon"]
    assert cli.main([*argv, "--quiet", "--out", str(work / "runs" / "s1")]) == 0  # an absolute --out
    page = (work / "runs" / "s1" / "index.html").read_text()
    shown = next(c for c in re.findall(r"hzval sweep [^<]*", html.unescape(page)) if "--out" in c)
    assert "--out runs/s1" in shown and str(tmp_path) not in shown
    words = shlex.split(shown)
    words[words.index("--out") + 1] = "runs/s2"  # the same command into a second folder
    monkeypatch.chdir(tmp_path)  # from elsewhere it would not find maps/mymap.npy ...
    assert cli.main(words[1:]) == 2
    monkeypatch.chdir(work)  # ... from where it ran, it runs
    assert cli.main(words[1:]) == 0
    first, second = (json.loads((work / "runs" / s / "metrics.json").read_text()) for s in ("s1", "s2"))
    for k in ("visibility_mae", "flip_mean", "rmse"):
        assert (
            first["frames"][0]["techniques"]["horizon"][k] == second["frames"][0]["techniques"]["horizon"][k]
        )


# 9. docs/outputs.md's recipe runs ---------------------------------------------------------------------


def test_the_outputs_page_recipe_writes_frames_score_reads(tmp_path, monkeypatch, variant, capsys):
    import re
    from pathlib import Path

    from hzval import materials

    page = (Path(__file__).resolve().parents[2] / "docs" / "outputs.md").read_text()
    recipe = re.search(r"```python\n(.*?)```", page, re.S).group(1)
    assert len([line for line in recipe.splitlines() if line.strip()]) <= 14
    monkeypatch.chdir(tmp_path)
    np.save(tmp_path / "mymap.npy", materials.generate("gravel", 16).height)
    argv = ["sweep", "mymap.npy", "--azimuths", "0,90", "--spp", "1", "--techniques", "horizon"]
    assert cli.main([*argv, "--quiet", "--out", "runs/s1"]) == 0
    exec(compile(recipe, "docs/outputs.md", "exec"), {})
    assert cli.main(["score", "myframes", "--against", "runs/s1"]) == 0
    assert "match no frame" not in capsys.readouterr().err
    assert (tmp_path / "myframes" / "score" / "index.html").is_file()


# 1. frames.json names every input, and F alone can be scored ----------------------------------------


def test_a_built_in_albedo_image_is_written_beside_frames_json(tmp_path, variant):
    import json

    from hzval.io import codecs

    argv = ["sweep", "--material", "gravel", "--size", "16", "--azimuths", "0", "--spp", "1"]
    assert cli.main([*argv, "--techniques", "horizon", "--quiet", "--out", str(tmp_path / "s")]) == 0
    albedo = json.loads((tmp_path / "s" / "frames.json").read_text())["albedo"]
    assert albedo["kind"] == "image"
    linear = codecs.read_exr(tmp_path / "s" / albedo["linear"])
    assert linear["R"].shape == (16, 16) and (tmp_path / "s" / albedo["srgb"]).is_file()
    from hzval import materials

    np.testing.assert_allclose(linear["R"], materials.generate("gravel", 16).albedo[..., 0], atol=1e-6)


def test_f_alone_is_scored_as_visibility_and_said(small_sweep, tmp_path, capsys):
    import json
    import shutil

    frames = tmp_path / "frames"
    frames.mkdir()
    for f in json.loads((small_sweep / "frames.json").read_text())["frames"]:
        shutil.copyfile(
            small_sweep / "frames" / f["name"] / "horizon_factor.exr", frames / f"f_{f['name']}.exr"
        )
    out = tmp_path / "o"
    assert cli.main(["score", str(frames), "--against", str(small_sweep), "--out", str(out)]) == 0
    assert "scored the visibility alone" in capsys.readouterr().err
    scored = json.loads((out / "metrics.json").read_text())["frames"][0]["techniques"]["engine"]
    theirs = json.loads((small_sweep / "metrics.json").read_text())["frames"][0]["techniques"]["horizon"]
    assert scored["flip_mean"] is None and scored["visibility_mae"] == pytest.approx(theirs["visibility_mae"])


# 4. Model sweeps say which camera and separate parallax --------------------------------------------


def test_a_model_sweep_says_its_camera_and_shows_the_error_at_the_truths_hits(tmp_path, variant, capsys):
    import json

    argv = ["sweep", "--mesh", "sphere", "--size", "16", "--azimuths", "0", "--spp", "1", "--techniques"]
    assert cli.main([*argv, "horizon", "--quiet", "--out", str(tmp_path / "m")]) == 0
    out, err = capsys.readouterr()
    assert "a perspective view from 35 degrees up" in err
    head, _, row = out.splitlines()[:3]
    assert head.split()[:4] == ["technique", "|F-V|", "at", "hits"]  # beside the camera's |F-V|
    metrics = json.loads((tmp_path / "m" / "metrics.json").read_text())
    hits = metrics["frames"][0]["techniques"]["horizon"]["perfect_parallax_mae"]
    assert row.split()[0] == "horizon" and float(row.split()[2]) == pytest.approx(hits, abs=5e-5)
    assert "no parallax" in out
    assert (
        cli.main([*argv, "horizon", "--camera", "orthographic", "--quiet", "--out", str(tmp_path / "o")]) == 0
    )
    assert "a perspective view" not in capsys.readouterr().err  # a camera given: nothing to say


# 5. One owner of the technique colours ---------------------------------------------------------------


def test_a_technique_has_one_colour_on_every_page():
    """horizon is the same colour on a sweep's report, where it leads, and on a score's, where the
    engine leads (it was purple on one and yellow on the other)."""
    from hzval.report import columns

    sweep = {"techniques": {"horizon": {}, "terrain": {}, "pom": {}}, "frames": []}
    score = {"techniques": {"engine": {}, "horizon": {}, "terrain": {}, "pom": {}}, "frames": []}
    a = {v.name: v.colour for v in columns.technique_views(sweep)}
    b = {v.name: v.colour for v in columns.technique_views(score)}
    assert all(a[n] == b[n] for n in a) and b["engine"] not in a.values()
    assert len(set(b.values())) == len(b)


#: Every technique's colour is distinct on a page, the registry's and score's engine alike.
def test_every_registered_technique_has_its_own_colour():
    from hzval.report import columns
    from hzval.techniques import registry as technique

    score = {"techniques": {"engine": {}, **{n: {} for n in technique.names()}}, "frames": []}
    colours = [v.colour for v in columns.technique_views(score)]
    assert len(set(colours)) == len(colours)


#: The page script: every card whose box is taller than its content (a row of cards stretched to its
#: tallest), and every label whose text is wider than its box (clipped).
LAYOUT_PROBLEMS = """() => {
  const out = [];
  for (const card of document.querySelectorAll('.card')) {
    const box = card.getBoundingClientRect();
    let bottom = box.top;
    for (const child of card.children) bottom = Math.max(bottom, child.getBoundingClientRect().bottom);
    const style = getComputedStyle(card);
    const pad = parseFloat(style.paddingBottom) + parseFloat(style.borderBottomWidth);
    if (box.bottom - (bottom + pad) > 24) {
      const h = card.querySelector('h2');
      const content = Math.round(bottom + pad - box.top);
      out.push(`card ${h ? h.textContent : '?'}: ${Math.round(box.height)} px tall, content ${content} px`);
    }
  }
  for (const el of document.querySelectorAll('dt, dd, th, td, .tile-label, .ttl, .bar-name, .fx, caption')) {
    const scrolls = getComputedStyle(el).overflowX === 'auto';
    if (el.offsetParent !== null && el.scrollWidth > el.clientWidth + 1 && !scrolls) {
      const text = el.textContent.trim().slice(0, 40);
      out.push(`clipped: ${el.tagName.toLowerCase()} "${text}" (${el.scrollWidth} > ${el.clientWidth} px)`);
    }
  }
  return out;
}"""


@pytest.mark.browser
def test_the_sweep_and_score_pages_lay_out_at_1400_px(tmp_path, variant):
    """Every page at 1400 px in headless Chromium: no card taller than its content (the score page's
    effects card stretched its row to 1,300 px) and no clipped label, with every default technique."""
    from tests.helpers import chromium_page

    sweep, frames = tmp_path / "s", tmp_path / "engine"
    argv = ["sweep", "--material", "bricks", "--size", "24", "--azimuths", "-30,30", "--spp", "1"]
    assert cli.main([*argv, "--quiet", "--out", str(sweep)]) == 0
    frames.mkdir()
    for folder in (sweep / "frames").iterdir():  # an engine that renders the truth's V as its F
        (frames / f"f_{folder.name}.exr").write_bytes((folder / "visibility.exr").read_bytes())
    assert cli.main(["score", str(frames), "--against", str(sweep), "--out", str(tmp_path / "sc")]) == 0
    problems: list[str] = []
    with chromium_page(problems) as page:
        page.set_viewport_size({"width": 1400, "height": 900})
        for index in (sweep / "index.html", tmp_path / "sc" / "index.html"):
            page.goto(index.as_uri(), wait_until="load")
            assert page.evaluate(LAYOUT_PROBLEMS) == [], index
    assert not problems


# 8. The floor is never "worst" --------------------------------------------------------------------------


def test_the_perfect_shadows_floor_is_never_marked_worst(tmp_path, variant):
    """In the report's table of a sweep with shadows, the floor columns (a bound, not a technique's
    error) have no cell marked worst, while the technique's error columns have theirs."""
    import json

    from hzval.report import pages as report

    out = tmp_path / "s"
    argv = ["sweep", "--material", "gravel", "--size", "32", "--depth", "0.1", "--elevation", "20"]
    argv += ["--azimuths", "0,90,180", "--spp", "2", "--techniques", "horizon", "--quiet", "--out", str(out)]
    assert cli.main(argv) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    ctx = report.build_context(out, metrics, "", {"metrics": None, "timings": None})
    cells = [c for f in ctx["frames"] for c in f["cells"]]
    floor = [c for c in cells if c["key"].startswith("floor_")]
    assert floor and len({c["text"] for c in floor}) > 1 and not any(c["worst"] for c in floor)
    assert any(c["worst"] for c in cells if c["key"].startswith("horizon_"))  # errors are marked


def test_the_report_and_the_terminal_give_one_total_time(tmp_path, variant, capsys):
    """The report's total time is the terminal's (4.21 s against 6.7 s before: the report was timed
    before its own plots and the terminal after everything)."""
    import json
    import re

    out = tmp_path / "s"
    argv = ["sweep", "--material", "gravel", "--size", "24", "--azimuths", "0,90", "--spp", "1"]
    assert cli.main([*argv, "--quiet", "--out", str(out)]) == 0
    said = re.search(r"frames in ([0-9.]+) s", capsys.readouterr().out)
    total = json.loads((out / "metrics.json").read_text())["timings"]["total_s"]
    assert said and float(said.group(1)) == pytest.approx(total, abs=0.051)
    html = (out / "index.html").read_text()
    tile = re.search(r"total time</div>\s*<div class=\"tile-value\">([^<]+)<", html)
    from hzval.report import columns

    assert tile and tile.group(1) == columns.fmt_seconds(total)


def test_the_terminal_table_fits_100_columns_with_every_technique(tmp_path, variant, capsys):
    out = tmp_path / "s"
    argv = ["sweep", "--material", "gravel", "--size", "24", "--elevation", "20,60", "--azimuths", "0,90"]
    assert cli.main([*argv, "--spp", "1", "--quiet", "--out", str(out)]) == 0
    lines = capsys.readouterr().out.splitlines()
    table = lines[: lines.index("")] if "" in lines else lines
    assert max(len(line) for line in table) <= 100
    from hzval.techniques import registry as technique

    assert [r.split()[0] for r in table[2 : 2 + len(technique.defaults())]] == technique.defaults()
