"""Studies whose numbers the docs quote: what models cost (models), curvature at fixed light elevation
(curvature_band), the share of error at seams (seam_share), and the tangent-frame bugs' signatures
and their signatures (bug_signatures; the matching is hzval.pipeline.bug_match).
"""

from hzval.core.exports import exports

__getattr__, __dir__ = exports(
    __name__,
    ("bug_signatures", "curvature_band", "seam_share"),
)
