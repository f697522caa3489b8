"""Scores of a frame against the truth: mean |F - V|, leaks, false shadows, RMSE, PSNR, CIEDE2000
(compare), FLIP in Dr.Jit (flip, its colour steps flip_colour), what a frame has to shadow and
scores over light-facing pixels (facing), exposure found from brightness (brightness), and a run's
result read as typed records (results).
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
