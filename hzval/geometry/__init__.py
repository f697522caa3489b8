"""Meshes: the tile's and a model's, their tangent frames, and the displaced model the truth traces.

- ``tile``: the tile's displaced triangle mesh.
- ``model``: a model's base mesh, built in or read from OBJ, PLY or glTF (``gltf``).
- ``tangents``: tangent frames, their one owner; ``mikktspace``: MikkTSpace's frames.
- ``cells``: a base mesh cut along the texel grid; ``displace``: the displaced model.
- ``tangent_bugs``: engine tangent-frame bugs, reproduced on purpose.
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
