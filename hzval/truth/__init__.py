"""The ground truth: Mitsuba 3 traces the displaced surface with real shadows, on the plane (plane), a
band of rows at a time when the whole mesh would not fit (bands), and on a model (model).
"""

from hzval.core.exports import exports

__getattr__, __dir__ = exports(
    __name__,
    ("bands", "model", "plane"),
)
