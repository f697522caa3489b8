"""The foundations every layer stands on: the conventions (axes, directions, height scale, boundaries,
colour), how a point turns light into radiance (shading), the Mitsuba/Dr.Jit variant and its LLVM
(backend), the errors and exit codes, interrupts, strict TOML reading, memory plans (resources) and
the subpackages' lazy re-exports. Nothing here imports another hzval subpackage.
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
