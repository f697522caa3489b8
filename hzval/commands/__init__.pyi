# Written by tests/stubs.py from each module's __all__ (python -m tests.stubs); do not edit.
from . import bake, check, export_scene, export_textures, fit, gates, materials, models, score, suite, sweep, tradeoff, views
from .bake import (
    BakeRun as BakeRun,
)
from .check import (
    Tiers as Tiers,
    DEFAULT_TIERS as DEFAULT_TIERS,
    CROSS_BACKEND_TIERS as CROSS_BACKEND_TIERS,
    BACKEND_ATTRIBUTE as BACKEND_ATTRIBUTE,
    backend_name as backend_name,
    reference_backend as reference_backend,
    across_backends as across_backends,
    BLOCK as BLOCK,
    ImageResult as ImageResult,
    CheckResult as CheckResult,
    check_scene as check_scene,
    render_references as render_references,
    check_material as check_material,
    compare_image as compare_image,
    write_report as write_report,
    repository_path as repository_path,
    p_value as p_value,
    sidak_level as sidak_level,
)
from .export_scene import (
    write_scene as write_scene,
    mitsuba_render as mitsuba_render,
    FILES as FILES,
)
from .export_textures import (
    export as export,
    FILE as FILE,
    plan as plan,
)
from .fit import (
    HORIZON as HORIZON,
    fit_horizon as fit_horizon,
    fit_technique as fit_technique,
    summary as summary,
)
from .gates import (
    Operand as Operand,
    Condition as Condition,
    parse as parse,
    evaluate as evaluate,
    read_baseline as read_baseline,
    check_same_settings as check_same_settings,
    baseline_tests as baseline_tests,
    frame_noise as frame_noise,
    regressions as regressions,
    Gates as Gates,
    check_names as check_names,
    check_shape as check_shape,
    DIRECTION as DIRECTION,
    FRAME_METRICS as FRAME_METRICS,
    TECHNIQUE_METRICS as TECHNIQUE_METRICS,
    FLOOR_METRICS as FLOOR_METRICS,
    TRUTH_METRICS as TRUTH_METRICS,
    ALPHA as ALPHA,
    ABS_TOLERANCE as ABS_TOLERANCE,
    REL_TOLERANCE as REL_TOLERANCE,
)
from .materials import (
    table as table,
)
from .models import (
    summary_table as summary_table,
    RADII as RADII,
    BOWLS as BOWLS,
    RING as RING,
    cap_obj as cap_obj,
    ring_obj as ring_obj,
)
from .score import (
    write as write,
    read_frame as read_frame,
    read_factor as read_factor,
    read_sidecar as read_sidecar,
    sampling_flip as sampling_flip,
    ALIASING_FLIP as ALIASING_FLIP,
    LABEL as LABEL,
    NAME as NAME,
    SIDECAR as SIDECAR,
)
from .suite import (
    Entry as Entry,
    Task as Task,
    entries as entries,
    sweep_material as sweep_material,
    summarise as summarise,
    gate_failures as gate_failures,
    material_baseline as material_baseline,
    HEIGHT_SUFFIXES as HEIGHT_SUFFIXES,
    LIGHTS_SHOWN as LIGHTS_SHOWN,
)
from .sweep import (
    selected as selected,
    run_line as run_line,
)
from .tradeoff import (
    Point as Point,
    Setting as Setting,
    settings as settings,
    measure as measure,
    mark_pareto as mark_pareto,
    recommend as recommend,
    write_tradeoff as write_tradeoff,
    DEFAULT_TRUTH_SPP as DEFAULT_TRUTH_SPP,
    DEFAULT_SIZE as DEFAULT_SIZE,
)
from .views import (
    VIEWS as VIEWS,
    LOOKUPS as LOOKUPS,
    headline as headline,
)
