"""Files in and out: atomic EXR, PNG and JSON writing and the staged output folder (files), height maps
from PNG, EXR and .npy (heightmap), a user's own horizon map and its convention (external), and how
a horizon map is stored for the GPU (storage).
"""

from hzval.core.exports import exports

__getattr__, __dir__ = exports(
    __name__,
    ("external", "files", "heightmap", "storage"),
)
