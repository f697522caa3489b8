"""What a person reads: the sweep's HTML report, its plots and the figures of the other commands.

- ``pages``: the sweep's report; ``overview``: the suite's.
- ``plots``: the report's plots; ``figures``: the other commands' figures.
- ``columns``: the vocabulary both use (columns, technique views, colours).
- ``images``: the visibility-difference and FLIP maps; ``ranking``: the techniques ranked.
- ``templates/``: the Jinja templates.
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
