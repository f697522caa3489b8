"""Every ``hzval`` command's work, one module each, as functions the CLI and tests call: the sweep
(sweep), a bake (bake), image-diff regression (check), gates that fail a build (gates), what
accuracy costs (tradeoff), many materials at once (suite), a set of views (views), an engine's own
frames scored (score), models of several curvatures (models), the truth as a Mitsuba scene
(export_scene), a run's textures as KTX2 (export_textures), a technique's textures fitted to the
truth (fit) and the built-in materials (materials).
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
