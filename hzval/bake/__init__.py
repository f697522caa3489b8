"""A height map turned into the techniques' textures: the normal map, the horizon map, the ambient map
and the weight cube map, written to and read from a bake folder.
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
