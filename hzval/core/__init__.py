"""The foundations every layer stands on, which import no other hzval subpackage.

- ``conventions``: axes, directions, height scale, boundaries; ``cube``: the weight cube map's layout.
- ``shading``: how a point turns light into radiance; ``srgb``: the sRGB encodings.
- ``budget``: every memory estimate's figures and formulas; ``resources``: the memory available and
  the refusal of a run that would not fit.
- ``backend``: the Mitsuba/Dr.Jit variant and its LLVM.
- ``errors``, ``interrupts``, ``strict``: one-line errors and exit codes, signals, strict TOML.
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
