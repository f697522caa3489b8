"""The ``hzval`` command: a thin layer that turns flags into the dataclasses the commands take.

``main`` builds the parser from one module per command (``sweep``, ``check``, ...); ``flags`` holds the
flags commands share and ``scenes`` the one way to build a scene from them.
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
