"""The scene one description gives the truth and every technique.

- ``spec``: material, lights, effects and sweep; ``files``: a scene file read into one.
- ``camera``: the camera, its rays and footprints.
- ``lookup``: where a technique reads its textures, on the plane or on a model.
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
