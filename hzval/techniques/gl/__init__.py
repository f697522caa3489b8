"""The shipped GLSL shaders on a real OpenGL pipeline.

- ``context``: the headless context and the sample pass.
- ``horizon_gl``: the ``horizon-gl`` and ``pom-gl`` techniques.
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
