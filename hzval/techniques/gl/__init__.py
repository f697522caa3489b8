"""The shipped GLSL shaders on a real OpenGL pipeline: the headless context (context) and the
``horizon-gl`` and ``pom-gl`` techniques (horizon_gl).
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
