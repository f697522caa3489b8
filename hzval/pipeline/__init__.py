"""The sweep: the truth and every technique for every light of a scene, compared, written and reported.

- ``sweep``: the run, from the scene to the report; ``renders``: each light's frames, scored.
- ``writing``: what a frame writes; ``records``: what a sweep records besides its images.
- ``bug_match``: which tangent-frame bug an engine's factors look like.
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
