"""Studies whose numbers the docs quote.

- ``curvature_band``: curvature at a fixed local light elevation.
- ``seam_share``: the share of error near UV seams.
- ``bug_signatures``: the tangent-frame bugs' signatures (matched by :mod:`hzval.pipeline.bug_match`).

The models' study that runs them is :mod:`hzval.commands.models`.
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
