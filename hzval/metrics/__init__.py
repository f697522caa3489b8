"""Scores of a frame against the truth: mean |F - V|, leaks, false shadows, RMSE, PSNR, CIEDE2000
(compare), FLIP in Dr.Jit (flip), what a frame has to shadow and scores over light-facing pixels
(facing), and exposure found from brightness (brightness).
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
