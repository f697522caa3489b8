"""A height map turned into the techniques' textures, written to and read from a bake folder.

- ``maps``: the bake (normal, horizon, ambient and weight cube maps) and its folder.
- ``horizon``: the seed horizon bake (Lengyel).
- ``exact``: the exact horizon map, by line sweeps.
- ``occlusion``: the bent normal and Valve's self-shadowed bump map, from the horizon map.
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
