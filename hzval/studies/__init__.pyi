# Written by tests/stubs.py from each module's __all__ (python -m tests.stubs); do not edit.
from . import bug_signatures, curvature_band, seam_share
from .bug_signatures import (
    CASES as CASES,
    run as run,
    page_context as page_context,
)
from .curvature_band import (
    BAND_DEG as BAND_DEG,
    WINDOW as WINDOW,
    AZIMUTHS as AZIMUTHS,
    RESOLUTION as RESOLUTION,
    band_scene as band_scene,
    paired as paired,
    trend as trend,
    texel_means as texel_means,
    in_band as in_band,
)
from .seam_share import (
    SEAM_TEXELS as SEAM_TEXELS,
    seam_distance_texels as seam_distance_texels,
    shares as shares,
)
