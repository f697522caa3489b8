# Written by tests/stubs.py from each module's __all__ (python -m tests.stubs); do not edit.
from . import bake, check, export_scene, export_textures, fit, flags, main, materials, models, scenes, score, suite, sweep, tradeoff, views
from .main import (
    COMMANDS as COMMANDS,
    build_parser as build_parser,
    typed_flags as typed_flags,
)
