"""The sweep: the truth and every technique for every light of a scene, compared, written and reported."""

from hzval.core.exports import exports

__getattr__, __dir__ = exports(
    __name__,
    ("records", "renders", "sweep", "writing"),
)
