"""Files in and out: output folders written whole or not at all (staging), EXR and PNG (codecs),
JSON and TOML read and written with one-line errors (documents), height maps (heightmap), a user's
own horizon map and its convention (external), how a texture is stored for the GPU (storage), KTX2
containers (ktx2), and the path rule for paths read from files (paths).
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
