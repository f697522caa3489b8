"""The ``hzval`` command: a thin layer that turns flags into the dataclasses the commands take."""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
