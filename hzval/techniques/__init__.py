"""The self-shadowing techniques, one plug-in per module, registered by name (registry): the flat
surface's shading they build on (surface), Lengyel's horizon mapping (horizon, horizon_curved),
Raudins' terrain shadows (terrain), the ray march (pom), the horizon map fitted to the truth
(fitted/), the shipped GLSL on OpenGL (gl/), and what engines ship, each a per-pixel factor
(perpixel): AO micro-shadowing (microshadow_filament, microshadow_hdrp), bent cones (bent_cone),
Valve's self-shadowed bump maps (ssbump) and the bump-terminator term (terminator). Adding a
technique is a module and a line in the registry.
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
