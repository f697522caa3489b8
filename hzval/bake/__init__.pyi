# Written by tests/stubs.py from each module's __all__ (python -m tests.stubs); do not edit.
from . import exact, horizon, maps, occlusion
from .exact import (
    CHANNEL_STEPS as CHANNEL_STEPS,
    SweepLines as SweepLines,
    sweep_lines as sweep_lines,
    ambient_from_sines as ambient_from_sines,
    exact_horizon_map as exact_horizon_map,
)
from .horizon import (
    TEXEL_HALF_EXTENT as TEXEL_HALF_EXTENT,
    OffsetGroup as OffsetGroup,
    horizon_table as horizon_table,
    KERNELS as KERNELS,
    UNROLL_MAX_OFFSETS as UNROLL_MAX_OFFSETS,
    UNROLL_COMPILE_S as UNROLL_COMPILE_S,
    UNROLL_COMPILE_POWER as UNROLL_COMPILE_POWER,
    UNROLL_RUN_NS as UNROLL_RUN_NS,
    LOOP_RUN_NS as LOOP_RUN_NS,
    choose_kernel as choose_kernel,
    kernel_for as kernel_for,
    horizon_map as horizon_map,
)
from .maps import (
    CUBE_SIZE as CUBE_SIZE,
    BakeParams as BakeParams,
    METHODS as METHODS,
    Bake as Bake,
    normals_only as normals_only,
    normal_map as normal_map,
    weight_cube as weight_cube,
    estimate_bytes as estimate_bytes,
    check_fits as check_fits,
    METHOD_NOTES as METHOD_NOTES,
    CONTENTS as CONTENTS,
    needs_horizon as needs_horizon,
    needs_occlusion as needs_occlusion,
    OCCLUSION as OCCLUSION,
    bake as bake,
    write_bake as write_bake,
    read_bake as read_bake,
    cached_bake as cached_bake,
)
from .occlusion import (
    HL2_BASIS as HL2_BASIS,
    bent_normal as bent_normal,
    uniform_ao as uniform_ao,
    uniform_bent_normal as uniform_bent_normal,
    self_shadowed_bump as self_shadowed_bump,
)
