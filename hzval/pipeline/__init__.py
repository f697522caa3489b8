"""The sweep: the truth and every technique for every light of a scene, compared, written and reported."""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
