"""The horizon map fitted to the truth: the optimiser (fit), its guard against overfitting (guard) and
the ``horizon-fit`` technique (horizon_fit).
"""

from hzval.core.exports import exports

__getattr__, __dir__ = exports(
    __name__,
    ("fit", "guard", "horizon_fit", "store", "training"),
)
