# Written by tests/stubs.py from each module's __all__ (python -m tests.stubs); do not edit.
from . import bands, common, memory, model, plane, rays, samples
from .bands import (
    PAD_TEXELS as PAD_TEXELS,
    why_not as why_not,
    reach as reach,
    cover_runs as cover_runs,
    group_bands as group_bands,
    band_y as band_y,
    band_triangles as band_triangles,
    band_scene as band_scene,
    band_pass as band_pass,
)
from .common import (
    relight as relight,
    LIFT_TEXELS as LIFT_TEXELS,
    LIFT_PER_HEIGHT as LIFT_PER_HEIGHT,
    AMBIENT_STREAM as AMBIENT_STREAM,
    REFLECTION_STREAM as REFLECTION_STREAM,
    lift_for as lift_for,
    specular_sampling_share as specular_sampling_share,
    sample_bsdf as sample_bsdf,
    stream_rng as stream_rng,
    lobe_sample as lobe_sample,
    reflection_estimate as reflection_estimate,
    mean_and_variance as mean_and_variance,
)
from .memory import (
    TruthPlan as TruthPlan,
    estimate_peak_bytes as estimate_peak_bytes,
    band_peak_bytes as band_peak_bytes,
    truth_plan as truth_plan,
    material_shape as material_shape,
    check_frame_pixels as check_frame_pixels,
    check_fits as check_fits,
)
from .model import (
    ModelTruth as ModelTruth,
    model_view as model_view,
)
from .plane import (
    surface_margin as surface_margin,
    mesh_grid as mesh_grid,
    mesh_triangles as mesh_triangles,
    Truth as Truth,
)
from .rays import (
    MIN_TRACED_ELEVATION_DEG as MIN_TRACED_ELEVATION_DEG,
    CameraRays as CameraRays,
    RayQueries as RayQueries,
    PathTracing as PathTracing,
)
from .samples import (
    KEEP_SAMPLES as KEEP_SAMPLES,
    BAND_SAMPLES as BAND_SAMPLES,
    KEPT_BAND_SAMPLES as KEPT_BAND_SAMPLES,
    keeps_samples as keeps_samples,
    band_ranges as band_ranges,
    Samples as Samples,
    off_edge_lines as off_edge_lines,
)
