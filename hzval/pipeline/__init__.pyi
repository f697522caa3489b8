# Written by tests/stubs.py from each module's __all__ (python -m tests.stubs); do not edit.
from . import bug_match, records, renders, sweep, writing
from .bug_match import (
    MARGIN as MARGIN,
    scene_of as scene_of,
    bug_factors as bug_factors,
    diagnose as diagnose,
)
from .records import (
    frame_folder as frame_folder,
    frame_name as frame_name,
    engine_frames as engine_frames,
    scene_parameters as scene_parameters,
    view_parameters as view_parameters,
    mesh_parameters as mesh_parameters,
    summary_table as summary_table,
)
from .renders import (
    finite as finite,
    metrics_record as metrics_record,
    Setup as Setup,
    cpu_time as cpu_time,
    stage_time as stage_time,
    lights as lights,
    render_frames as render_frames,
)
from .sweep import (
    SCHEMA_VERSION as SCHEMA_VERSION,
    Options as Options,
    peak_rss_bytes as peak_rss_bytes,
    reset_peak_rss as reset_peak_rss,
    set_up as set_up,
    truth_of as truth_of,
    view_errors as view_errors,
    run as run,
)
from .writing import (
    write_view_maps as write_view_maps,
    UNSEEN_DISPLAY as UNSEEN_DISPLAY,
    PNG_LEVEL as PNG_LEVEL,
    PNG_RUNS as PNG_RUNS,
    shown as shown,
    FrameWriter as FrameWriter,
    write_albedo as write_albedo,
)
