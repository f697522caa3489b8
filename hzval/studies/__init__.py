"""Studies whose numbers the docs quote: what models cost (models), curvature at fixed light elevation
(curvature_band), the share of error at seams (seam_share), and the tangent-frame bugs' signatures
and their matching (bug_signatures, bug_match).
"""

from hzval.core.exports import exports

__getattr__, __dir__ = exports(
    __name__,
    ("bug_match", "bug_signatures", "curvature_band", "models", "seam_share"),
)
