"""Scores of a frame against the truth, from mean |F - V| to FLIP, and a run's result as records.

- ``compare``: mean |F - V|, leaks, false shadows, RMSE, PSNR and CIEDE2000.
- ``flip``: FLIP in Dr.Jit, with its colour steps in ``flip_colour``.
- ``facing``: what a frame has to shadow, and scores over the pixels facing the light.
- ``brightness``: an engine's exposure error found from its brightness.
- ``results``: ``metrics.json`` and ``suite.json`` read as typed records.
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
