"""``hzval check``: the shipped references pass, and the check has teeth without crying wolf."""

from __future__ import annotations

import dataclasses
import shutil

import numpy as np
import pytest

from hzval import materials
from hzval.cli import main as cli
from hzval.commands import check
from hzval.io import codecs
from hzval.techniques import horizon
from hzval.techniques import registry as technique

SHIPPED = check.repository_path("reference")


@pytest.fixture
def refs(tmp_path):
    """A private copy of the shipped references, to change at will."""
    dst = tmp_path / "reference"
    shutil.copytree(SHIPPED, dst)
    return dst


def statuses(result) -> dict[str, str]:
    """Each image's status; a warning on another backend than its reference's (a few pixels a step
    of the technique apart) counts as the pass it is there, and only there."""
    return {r.name: "pass" if r.status == "warn" and r.other_backend else r.status for r in result.images}


# --------------------------------------------------------------------------
# The shipped references: the default test run fails on a regression
# --------------------------------------------------------------------------

#: Every kind of image of a scene with shadows: the truth and each check variant of each technique.
KINDS = {"truth"} | {v.name for n in technique.names() for v in technique.get(n).check_variants()}


def test_shipped_references_pass(variant):
    """This is the regression check of CI: every shipped scene against reference/."""
    result = check.run()
    failing = [f"{r.name}: {'; '.join(r.reasons)}" for r in result.images if r.status not in ("pass", "warn")]
    assert not failing, "\n".join(failing)
    scenes = {r.scene for r in result.images}
    assert {"bricks", "wall", "wall-soft"} | set(materials.names()) <= scenes  # every built-in material
    assert {r.kind for r in result.images} == KINDS


def test_references_are_small():
    for p in SHIPPED.rglob("*.exr"):
        ch = codecs.read_exr(p)
        h, w = next(iter(ch.values())).shape
        assert 32 <= max(h, w) <= check.MAX_CHECK_SIZE, p


# --------------------------------------------------------------------------
# No wolf: Monte Carlo noise passes
# --------------------------------------------------------------------------


@pytest.mark.parametrize(
    "seed", [5, pytest.param(123, marks=pytest.mark.slow(reason="a second seed, as the first but for noise"))]
)
def test_truth_rendered_with_another_seed_passes(variant, refs, seed):
    result = check.run(references=refs, seed=seed)
    assert result.passed, check.summary(result)
    # the new truth really is another render, not the reference again
    t = next(r for r in result.images if r.kind == "truth" and r.scene == "bricks")
    assert t.numbers["max_abs"] > 0.05


# --------------------------------------------------------------------------
# Teeth
# --------------------------------------------------------------------------


def _edit(path, fn):
    ch = codecs.read_exr(path)
    fn(ch)
    codecs.write_exr(path, ch)


def test_a_visibly_darker_patch_in_a_truth_reference_fails(variant, refs, tmp_path):
    target = check.reference_file(refs, "bricks", "az+0", "truth")

    def darken(ch):  # a 24x24 patch 15% darker: visible, and within each pixel's noise at 16 spp
        for c in "RGB":
            ch[c][30:54, 30:54] *= 0.85

    _edit(target, darken)
    result = check.run(references=refs, only=["bricks"])
    st = statuses(result)
    assert st["bricks/az+0/truth"] == "fail"
    assert all(s == "pass" for n, s in st.items() if n != "bricks/az+0/truth"), st
    r = next(r for r in result.images if r.name == "bricks/az+0/truth")
    assert r.numbers["failing_blocks"] > 0  # the block test sees what single pixels cannot

    index = check.write_report(result, tmp_path / "report", command="hzval check")
    html = index.read_text()
    first = html.index("<section")
    assert html.index("bricks/az+0/truth", first) < html.index("bricks/az-60/truth", first)  # failures first
    for name in ("ref", "new", "diff"):
        assert (tmp_path / "report" / "img" / f"000-{name}.png").is_file()


def test_a_changed_approximation_reference_fails(variant, refs):
    target = check.reference_file(refs, "wall", "az+135", "horizon")

    def nudge(ch):  # one pixel 0.01 brighter: invisible, but the approximation is deterministic
        ch["R"][10, 10] += 0.01

    # marked as this backend's (the exact path's images agree across backends to 3e-6), so that the
    # tight tiers apply here on CUDA too
    ch = codecs.read_exr(target)
    nudge(ch)
    codecs.write_exr(target, ch, attributes={check.BACKEND_ATTRIBUTE: check.backend_name(variant)})
    st = statuses(check.run(references=refs, only=["wall"]))
    assert st["wall/az+135/horizon"] == "fail"
    assert st["wall/az+135/horizon_gpu"] == "pass" and st["wall/az+135/truth"] == "pass"


def test_flipping_the_sign_of_one_channel_weight_fails(variant, refs, monkeypatch):
    """Channel 0 faces azimuth 0: the exact path's frames at 0 degrees fail, the others do not."""
    original = horizon.Horizon._exact_weights

    def flipped(d, *directions):
        w = original(d, *directions)
        return [-w[0], *w[1:]]

    monkeypatch.setattr(horizon.Horizon, "_exact_weights", staticmethod(flipped))
    st = statuses(check.run(references=refs, only=["bricks", "wall"]))
    assert st["bricks/az+0/horizon"] == "fail" and st["wall/az+0/horizon"] == "fail"
    assert st["bricks/az+45/horizon"] == "pass" and st["wall/az+135/horizon"] == "pass"
    assert st["bricks/az+0/horizon_gpu"] == "pass"  # the GPU path reads the cube map instead


def test_a_softer_terrain_ramp_fails_the_terrain_images_only(variant, refs, monkeypatch):
    """The terrain technique is guarded too: a ramp 25x wider changes its penumbrae."""
    from hzval.techniques import terrain

    class Softer(terrain.TerrainShadow):
        def __init__(self, *args, **kw):
            super().__init__(*args, **{**kw, "ramp": 25 * terrain.DEFAULT_RAMP})

    monkeypatch.setattr(terrain, "TerrainShadow", Softer)
    st = statuses(check.run(references=refs, only=["bricks", "wall"]))
    assert all(v == "fail" for k, v in st.items() if k.endswith("/terrain") and k.startswith("bricks"))
    assert all(v == "pass" for k, v in st.items() if not k.endswith("/terrain"))


def test_a_biased_truth_fails_even_within_each_pixels_noise(variant, refs):
    target = check.reference_file(refs, "wall-soft", "az+0", "truth")

    def brighten(ch):  # everything 3% brighter: below one pixel's noise, a bias of the whole image
        for c in "RGBV":
            ch[c] *= 1.03

    _edit(target, brighten)
    result = check.run(references=refs, only=["wall-soft"])
    r = next(r for r in result.images if r.name == "wall-soft/az+0/truth")
    assert r.status == "fail", r.reasons


# --------------------------------------------------------------------------
# --update and the command line
# --------------------------------------------------------------------------


def test_update_rewrites_only_missing_and_failing_references(variant, refs):
    missing = check.reference_file(refs, "wall", "az+0", "horizon_gpu")
    broken = check.reference_file(refs, "wall", "az+135", "horizon")
    untouched = check.reference_file(refs, "wall", "az+0", "truth")
    missing.unlink()
    _edit(broken, lambda ch: ch["G"].__imul__(0.5))
    before = untouched.stat().st_mtime_ns
    result = check.run(references=refs, only=["wall"], update=True)
    assert sorted(result.updated) == sorted([str(missing), str(broken)])
    assert untouched.stat().st_mtime_ns == before
    assert check.run(references=refs, only=["wall"]).passed


def test_a_reference_from_another_backend_is_compared_at_the_cross_backend_tiers(variant, refs):
    """``--update`` records the backend in each reference; a reference without it is LLVM's. A few
    pixels a level apart (another backend's rounding at a quantisation step) fail on the reference's
    own backend and pass on another, flagged (warn); a regression fails on either."""
    here = check.backend_name(variant)
    other = "llvm" if here == "cuda" else "cuda"
    target = check.reference_file(refs, "wall", "az+135", "horizon_gpu")
    assert check.reference_backend(target) == "llvm"  # shipped, written before the attribute
    target.unlink()
    check.run(references=refs, only=["wall"], update=True)
    assert check.reference_backend(target) == here
    ref = codecs.read_exr(target)

    def status(change, backend):
        ch = {k: v.copy() for k, v in ref.items()}
        change(ch)
        codecs.write_exr(target, ch, attributes={check.BACKEND_ATTRIBUTE: backend})
        result = check.run(references=refs, only=["wall"])
        r = next(r for r in result.images if r.name == "wall/az+135/horizon_gpu")
        assert r.other_backend == (None if backend == here else backend)
        assert (f"rendered on {backend}" in check.summary(result)) == (backend != here)
        return r.status

    def level_flips(ch):  # three pixels one 8-bit level of a sine apart (8/255 in F at k = 8)
        ch["F"][5, 5:8] += 8 / 255

    def patch(ch):  # a 20 x 20 patch 0.002 brighter: 4% of the image beyond the per-pixel 1e-3
        ch["F"][20:40, 20:40] += 0.002

    def one_pixel(ch):  # a pixel off by 0.1, beyond any rounding
        ch["F"][50, 50] += 0.1

    assert status(level_flips, here) == "fail" and status(level_flips, other) == "warn"
    assert status(patch, other) == "fail" and status(one_pixel, other) == "fail"


def test_cli_exit_codes_and_report(variant, refs, tmp_path, capsys):
    assert cli.main(["check", "--quiet", "--references", str(refs), "--scene", "wall"]) == 0
    capsys.readouterr()
    _edit(check.reference_file(refs, "wall", "az+0", "horizon"), lambda ch: ch["F"].__iadd__(0.2))
    report = tmp_path / "rep"
    assert (
        cli.main(["check", "--quiet", "--references", str(refs), "--scene", "wall", "--report", str(report)])
        == 1
    )
    out = capsys.readouterr().out
    assert out.splitlines()[0].startswith("FAIL  wall/az+0/horizon")
    assert (report / "index.html").is_file()
    # a folder without references: every image is new, which fails until --update writes them
    empty = tmp_path / "empty"
    assert (
        cli.main(["check", "--quiet", "--references", str(empty), "--scene", "wall", "--report", str(report)])
        == 1
    )
    assert cli.main(["check", "--quiet", "--references", str(empty), "--scene", "wall", "--update"]) == 0
    assert len(list(empty.rglob("*.exr"))) == 2 * len(KINDS)  # two lights
    assert cli.main(["check", "--quiet", "--references", str(empty), "--scene", "wall"]) == 0


# --------------------------------------------------------------------------
# The comparison itself, on synthetic images
# --------------------------------------------------------------------------


def _truth_channels(rng, mean, var, spp=16):
    noise = rng.standard_normal(mean.shape) * np.sqrt(var)
    ch = {c: (mean + noise).astype(np.float32) for c in "RGBV"}
    ch.update({f"var.{c}": np.full(mean.shape, var, np.float32) for c in "RGBV"})
    return ch


def test_pure_noise_passes_and_a_shift_of_a_few_sigma_over_a_block_fails():
    rng = np.random.default_rng(0)
    mean, var = np.full((64, 64), 0.5), 0.01
    tiers = check.DEFAULT_TIERS["truth"]
    fails = 0
    for _ in range(20):
        status, *_ = check.compare_image(
            _truth_channels(rng, mean, var), _truth_channels(rng, mean, var), "truth", tiers, 1.0, 16
        )
        fails += status == "fail"
    assert fails == 0
    shifted = mean.copy()
    shifted[:8, :8] += 0.15  # 1.5 sigma per pixel, 8.5 sigma for the block mean
    status, reasons, numbers, _ = check.compare_image(
        _truth_channels(rng, shifted, var), _truth_channels(rng, mean, var), "truth", tiers, 1.0, 16
    )
    assert status == "fail" and numbers["failing_blocks"] >= 1, reasons


def test_shape_mismatch_fails_with_a_reason():
    a = {c: np.zeros((8, 8), np.float32) for c in "RGBF"}
    b = {c: np.zeros((8, 9), np.float32) for c in "RGBF"}
    status, reasons, *_ = check.compare_image(a, b, "horizon", check.DEFAULT_TIERS["technique"], 1.0, 16)
    assert status == "fail" and "--update" in reasons[0]


def test_unknown_tolerance_is_an_input_error(variant):
    from hzval.core.errors import InputError
    from hzval.scene.spec import Scene

    s = dataclasses.replace(Scene(), tolerances={"truth": {"fial": 0.1}})
    with pytest.raises(InputError, match="fial"):
        check.Tiers.of(s, "truth")
    # every technique's tiers, then its own, then its variant's; schema 1's [tolerances.approx] still read
    s = dataclasses.replace(
        Scene(),
        tolerances={"technique": {"fail": 0.5}, "pom": {"fail": 0.25}, "horizon_gpu": {"hard_fail": 0.125}},
    )
    assert check.Tiers.of(s, "horizon", "horizon").fail == 0.5
    assert check.Tiers.of(s, "pom", "pom").fail == 0.25
    assert check.Tiers.of(s, "horizon_gpu", "horizon") == dataclasses.replace(
        check.DEFAULT_TIERS["technique"], fail=0.5, hard_fail=0.125
    )
    legacy = dataclasses.replace(Scene(), tolerances={"approx": {"fail": 0.5}})
    assert check.Tiers.of(legacy, "terrain", "terrain").fail == 0.5


def test_a_reference_folder_of_schema_1_is_read_and_renamed_by_update(variant, refs):
    """References named approx.exr / approx_gpu.exr (hzval 0.1) pass as they are; --update renames them."""
    for p in list(refs.rglob("horizon*.exr")):
        p.rename(p.with_name(p.name.replace("horizon", "approx")))
    result = check.run(references=refs, only=["wall"])
    assert result.passed, check.summary(result)
    assert {r.kind for r in result.images} >= {"horizon", "horizon_gpu"}
    check.run(references=refs, only=["wall"], update=True)
    assert not list((refs / "wall").rglob("approx*.exr")) and list((refs / "wall").rglob("horizon_gpu.exr"))
