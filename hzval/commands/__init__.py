"""Every ``hzval`` command's work, one module each, as functions the CLI and tests call: the sweep
(sweep), a bake (bake), image-diff regression (check), gates that fail a build (gates), what
accuracy costs (tradeoff), many materials at once (suite), a set of views (views), an engine's own
frames scored (score), models of several curvatures (models), the truth as a Mitsuba scene
(export_scene), a run's textures as KTX2 (export_textures), a technique's textures fitted to the
truth (fit) and the built-in materials (materials).
"""

from hzval.core.exports import exports

__getattr__, __dir__ = exports(
    __name__,
    (
        "bake",
        "check",
        "export_scene",
        "export_textures",
        "fit",
        "gates",
        "materials",
        "models",
        "score",
        "suite",
        "sweep",
        "tradeoff",
        "views",
    ),
)
