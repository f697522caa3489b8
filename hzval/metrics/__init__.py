"""Scores of a frame against the truth: mean |F - V|, leaks, false shadows, RMSE, PSNR, CIEDE2000
(compare), FLIP in Dr.Jit (flip), what a frame has to shadow and scores over light-facing pixels
(facing), and exposure found from brightness (brightness).
"""

from hzval.core.exports import exports

__getattr__, __dir__ = exports(
    __name__,
    ("brightness", "compare", "facing", "flip", "flip_colour"),
)
