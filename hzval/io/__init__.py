"""Files in and out: output folders, images, documents, height maps, horizon maps and textures.

- ``staging``: output folders written whole or not at all; ``atomic``: one file written atomically.
- ``codecs``: EXR, PNG and figures; ``documents``: JSON and TOML with one-line errors.
- ``heightmap``: height maps; ``external``: a user's own horizon map and its convention.
- ``storage``: how a texture is stored for the GPU; ``ktx2``: KTX2 containers.
- ``paths``: the rule for paths read from files.
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
