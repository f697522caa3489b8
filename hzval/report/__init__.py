"""What a person reads: the sweep's HTML report and its plots (pages), the visibility-difference and
FLIP maps and their colours (images), and the Jinja templates.
"""

from hzval.core.exports import exports

__getattr__, __dir__ = exports(
    __name__,
    ("images", "pages"),
)
