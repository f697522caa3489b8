"""The horizon map fitted to the truth: the optimiser (fit), its guard against overfitting (guard) and
the ``horizon-fit`` technique (horizon_fit).
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
