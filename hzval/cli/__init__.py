"""The ``hzval`` command: a thin layer that turns flags into the dataclasses the commands take."""

from hzval.core.exports import exports

__getattr__, __dir__ = exports(
    __name__,
    ("main",),
)
