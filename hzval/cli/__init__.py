"""The ``hzval`` command: a thin layer that turns flags into the dataclasses the commands take.

``main`` builds the parser from one module per command, each its flags over :mod:`hzval.commands`'s
module of the same name: ``sweep``, ``bake``, ``fit``, ``check``, ``tradeoff``, ``suite``, ``views``,
``models``, ``score``, ``export_scene``, ``export_textures`` and ``materials``. ``flags`` holds the
flags commands share and ``scenes`` the one way to build a scene from them.
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
