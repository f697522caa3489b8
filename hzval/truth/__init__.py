"""The ground truth: Mitsuba 3 traces the displaced surface with real shadows.

- ``plane``: on the plane, from its rays (``rays``) and samples (``samples``).
- ``bands``: a band of rows at a time, when the whole mesh would not fit.
- ``model``: on a model.
- ``common``: what the plane's and the model's share; ``memory``: the sweep's memory plan.
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
