"""A height map turned into the techniques' textures: the normal map, the horizon map, the ambient map
and the weight cube map, written to and read from a bake folder.
"""

from hzval.core.exports import exports

__getattr__, __dir__ = exports(
    __name__,
    ("maps", "horizon", "exact"),
)
