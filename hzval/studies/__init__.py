"""Studies whose numbers the docs quote: curvature at fixed light elevation (curvature_band), the
share of error at seams (seam_share) and the tangent-frame bugs' signatures (bug_signatures; the
matching is hzval.pipeline.bug_match, the models' study hzval.commands.models).
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
