"""The ground truth: Mitsuba 3 traces the displaced surface with real shadows, on the plane (plane), a
band of rows at a time when the whole mesh would not fit (bands), and on a model (model).
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
