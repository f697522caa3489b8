"""The scene one description gives the truth and every technique: material, lights, effects and sweep
(spec), the camera and its rays and footprints (camera), and where a technique reads its textures on
the plane or on a model (lookup).
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
