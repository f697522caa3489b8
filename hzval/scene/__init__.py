"""The scene one description gives the truth and every technique: material, lights, effects and sweep
(spec), the camera and its rays and footprints (camera), and where a technique reads its textures on
the plane or on a model (lookup).
"""

from hzval.core.exports import exports

__getattr__, __dir__ = exports(
    __name__,
    ("camera", "lookup", "spec"),
)
