"""Textures fitted to the truth: the floor of each texture-driven technique.

- ``model``: what every fit shares (training lights in batches, Adam); ``training``: what it trains on.
- ``fit``: the horizon map's fit; ``textures``: a per-pixel technique's.
- ``guard``: the bake kept where the fit is worse; ``store``: fits on disk and their cache.
- ``horizon_fit``, ``perpixel_fit``: the ``horizon-fit`` and ``NAME-fit`` techniques.
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
