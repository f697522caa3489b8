"""Every memory estimate's figures and formulas live in :mod:`hzval.core.budget`.

The formulas are checked term by term against their constants, the scene-aware estimates against the
formulas they apply, and the code base for a fitted memory figure defined anywhere else.
"""

import ast
import re
from pathlib import Path

import pytest

from hzval.core import budget

PACKAGE = Path(__file__).resolve().parents[2] / "hzval"


def test_each_term_of_a_sweeps_peak_is_its_constant():
    base = budget.sweep_peak_bytes(1000, 4000, 4000, 0, 0)
    assert base == int(budget.PEAK_BASE_BYTES + 1000 * budget.PEAK_BYTES_PER_PIXEL + 4000 * (24 + 52))
    more = budget.sweep_peak_bytes(1000, 4000, 4000, 10**6, 3)
    assert (
        more - base
        == 10**6 * budget.PEAK_BYTES_PER_TRIANGLE + 3 * 1000 * budget.PEAK_BYTES_PER_TECHNIQUE_PIXEL
    )
    view = budget.sweep_peak_bytes(1000, 4000, 500, 0, 0, view=True) - budget.sweep_peak_bytes(
        1000, 4000, 500, 0, 0
    )
    assert view == budget.PEAK_BYTES_PER_VIEW_SAMPLE * 500 + budget.PEAK_BYTES_PER_SAMPLE * 4000


def test_a_bake_pays_per_texel_and_per_extra_direction():
    eight = budget.bake_bytes(64, 32, 8)
    assert eight == (budget.BAKE_BYTES_PER_TEXEL + budget.OCCLUSION_BYTES_PER_TEXEL) * 64 * 32
    assert (
        budget.bake_bytes(64, 32, 16) - eight == 8 * budget.BAKE_BYTES_PER_TEXEL_PER_EXTRA_DIRECTION * 64 * 32
    )
    # the seed's padding charges the padded map
    assert budget.bake_bytes(64, 32, 8, pad=3) == eight // (64 * 32) * 70 * 38


def test_a_fit_holds_every_lights_visibility_beside_the_larger_phase():
    small = budget.fit_bytes(100, 4, 10, 400)
    optimise = (
        budget.FIT_BASE_BYTES + 100 * 4 * budget.FIT_BYTES_PER_SAMPLE + 100 * budget.FIT_BYTES_PER_TEXEL
    )
    optimise += 400 * budget.FIT_BYTES_PER_BAND_SAMPLE
    assert small == int(budget.FIT_BYTES_PER_PIXEL_LIGHT * 100 * 10 + optimise)
    huge = 10 * 2**30
    assert budget.fit_bytes(100, 4, 10, 400, render=huge) == budget.FIT_BYTES_PER_PIXEL_LIGHT * 1000 + huge


def test_a_models_reflection_lobe_costs_per_sample():
    plain = budget.model_truth_bytes(10**6, 2000, 5000, reflection=False)
    lobe = budget.model_truth_bytes(10**6, 2000, 5000, reflection=True)
    assert lobe - plain == 5000 * budget.MODEL_BYTES_PER_REFLECTION_SAMPLE
    assert plain == 10**6 + 2000 * budget.MODEL_BYTES_PER_TRIANGLE + 5000 * budget.MODEL_BYTES_PER_SAMPLE
    sweep = budget.model_sweep_peak_bytes(10**6, 2000, 5000, False, pixels=1000, techniques=2)
    images = (budget.PEAK_BYTES_PER_PIXEL + 2 * budget.PEAK_BYTES_PER_TECHNIQUE_PIXEL) * 1000
    assert sweep == int(budget.PEAK_BASE_BYTES + plain + images)


@pytest.mark.parametrize("kind", ["top", "perspective"])
def test_the_sweeps_estimate_applies_the_formula(kind):
    """:func:`hzval.truth.memory.estimate_peak_bytes` is the formula on the scene's own counts."""
    from hzval.scene import spec as sc
    from hzval.truth import memory
    from hzval.truth import samples as truth_samples

    scene = sc.override(sc.Scene(), camera=kind, size=64)
    assert scene.camera.kind == kind
    H, W = sc.image_shape(64, 64, scene.camera)
    samples = H * W * scene.spp
    assert truth_samples.keeps_samples(H, W, scene.spp)
    want = budget.sweep_peak_bytes(H * W, samples, samples, 12345, 3, view=kind != "top")
    assert memory.estimate_peak_bytes(scene, 64, 64, 12345, techniques=3) == want


def _constants(path: Path) -> list[str]:
    names = []
    for node in ast.parse(path.read_text()).body:
        targets = node.targets if isinstance(node, ast.Assign) else [getattr(node, "target", None)]
        names += [t.id for t in targets if isinstance(t, ast.Name)]
    return names


#: A name that says "memory figure": bytes per something, a peak, a fit's bytes.
FIGURE = re.compile(r"BYTES_PER_|^PEAK_|_PEAK_|^FIT_.*BYTES")


def test_no_module_but_the_budget_defines_a_memory_figure():
    others = [
        f"{p.relative_to(PACKAGE)}: {n}"
        for p in PACKAGE.rglob("*.py")
        if p.name != "budget.py"
        for n in _constants(p)
        if FIGURE.search(n)
    ]
    assert others == []


def test_the_figure_check_finds_one(tmp_path):
    (tmp_path / "m.py").write_text("BYTES_PER_THING = 3\nX = 1\n")
    assert [n for n in _constants(tmp_path / "m.py") if FIGURE.search(n)] == ["BYTES_PER_THING"]
