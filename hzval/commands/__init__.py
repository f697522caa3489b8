"""The commands past the sweep, each a function the CLI and tests call: image-diff regression (check),
gates that fail a build (gates), what accuracy costs (tradeoff), many materials at once (suite), a
set of views (views), an engine's own frames scored (score), and the truth as a Mitsuba scene
(export).
"""

from hzval.core.exports import exports

__getattr__, __dir__ = exports(
    __name__,
    ("check", "export", "gates", "score", "suite", "tradeoff", "views"),
)
