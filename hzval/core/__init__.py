"""The foundations every layer stands on: the conventions (axes, directions, height scale, boundaries),
the sRGB encodings (srgb), how a point turns light into radiance (shading), the Mitsuba/Dr.Jit
variant and its LLVM (backend), the errors and exit codes, interrupts, strict TOML reading, memory
plans (resources) and the cube's face layout (cube). Nothing here imports another hzval subpackage.
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
