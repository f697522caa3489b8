"""The commands past the sweep, each a function the CLI and tests call: image-diff regression (check),
gates that fail a build (gates), what accuracy costs (tradeoff), many materials at once (suite), a
set of views (views), an engine's own frames scored (score), the truth as a Mitsuba scene
(export), a run's textures as KTX2 (export_textures) and a technique's textures fitted to the truth
(fit).
"""

from hzval.core.exports import exports

__getattr__, __dir__ = exports(
    __name__,
    ("check", "export", "export_textures", "fit", "gates", "score", "suite", "tradeoff", "views"),
)
