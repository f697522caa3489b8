"""The shipped GLSL shaders on a real OpenGL pipeline: the headless context (context) and the
``horizon-gl`` and ``pom-gl`` techniques (horizon_gl).
"""

from hzval.core.exports import exports

__getattr__, __dir__ = exports(
    __name__,
    ("context", "horizon_gl"),
)
