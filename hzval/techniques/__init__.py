"""The self-shadowing techniques, one plug-in per module, registered by name (``registry``).

- ``surface``: the flat surface's shading every technique builds on.
- ``horizon``, ``horizon_curved``: Lengyel's horizon mapping; ``cubemap``: its weight cube's sampling.
- ``terrain``: Raudins' terrain shadows; ``pom``: the ray march.
- ``perpixel``: the base of what engines ship, a factor per pixel: AO micro-shadowing
  (``microshadow_filament``, ``microshadow_hdrp``), bent cones (``bent_cone``), Valve's
  self-shadowed bump maps (``ssbump``) and the bump-terminator term (``terminator``).
- ``fitted/``: textures fitted to the truth; ``gl/``: the shipped GLSL on OpenGL.

Adding a technique is a module and a line in the registry.
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
