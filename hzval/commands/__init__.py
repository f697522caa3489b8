"""Every ``hzval`` command's work, one module each, as functions the CLI and tests call.

- ``sweep``: the light sweep, scored, reported and gated; ``gates``: what fails a build.
- ``bake``, ``fit``: a height map's textures, baked or fitted to the truth.
- ``check``: the image-diff regression against ``reference/``.
- ``tradeoff``: what accuracy costs; ``suite``: many materials at once.
- ``views``, ``models``: the sweep from a set of views, and on models of several curvatures.
- ``score``: an engine's own frames scored.
- ``export_scene``, ``export_textures``: the truth as a Mitsuba scene, a run's textures as KTX2.
- ``materials``: the built-in materials.
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
