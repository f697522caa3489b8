"""The self-shadowing techniques, one plug-in per module, registered by name (registry): the flat
surface's shading they build on (surface), Lengyel's horizon mapping (horizon, horizon_curved),
Raudins' terrain shadows (terrain), the ray march (pom), the horizon map fitted to the truth
(fitted/) and the shipped GLSL on OpenGL (gl/). Adding a technique is a module and a line in the
registry.
"""

from hzval.core.exports import exports

__getattr__, __dir__ = exports(
    __name__,
    ("cubemap", "horizon", "horizon_curved", "pom", "registry", "surface", "terrain", "fitted", "gl"),
)
