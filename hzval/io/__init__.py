"""Files in and out: atomic EXR, PNG and JSON writing and the staged output folder (files), height maps
from PNG, EXR and .npy (heightmap), a user's own horizon map and its convention (external), and how
a horizon map is stored for the GPU (storage), the path rule for paths read from files (paths), and JSON and
TOML read with one-line errors (documents).
"""

from hzval.core.exports import exports

__getattr__, __dir__ = exports(
    __name__,
    ("documents", "external", "files", "heightmap", "paths", "storage"),
)
