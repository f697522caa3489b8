"""The foundations every layer stands on: the conventions (axes, directions, height scale, boundaries,
colour), how a point turns light into radiance (shading), the Mitsuba/Dr.Jit variant and its LLVM
(backend), the errors and exit codes, interrupts, strict TOML reading, memory plans (resources) and
the subpackages' lazy re-exports. Nothing here imports another hzval subpackage.
"""

from hzval.core.exports import exports

__getattr__, __dir__ = exports(
    __name__,
    (
        "backend",
        "conventions",
        "cube",
        "errors",
        "exports",
        "interrupts",
        "resources",
        "shading",
        "srgb",
        "strict",
    ),
)
