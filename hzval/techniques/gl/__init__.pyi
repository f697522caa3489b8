# Written by tests/stubs.py from each module's __all__ (python -m tests.stubs); do not edit.
from . import context, horizon_gl
from .context import (
    Unavailable as Unavailable,
    info as info,
    shader_source as shader_source,
    SamplePass as SamplePass,
    BAND_WIDTH as BAND_WIDTH,
    BAND_ROWS as BAND_ROWS,
)
from .horizon_gl import (
    HorizonGL as HorizonGL,
    PomGL as PomGL,
)
