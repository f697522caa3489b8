"""Meshes: the tile's displaced triangle mesh (tile), a model's base mesh from the built-in shapes or
OBJ/PLY/glTF files (model; glTF through gltf), tangent frames (tangents, their one owner), a base mesh cut
along the
texel grid (cells), the displaced model the truth traces (displace), and the engine tangent-frame
bugs reproduced on purpose (tangent_bugs).
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
