"""What a person reads: the sweep's HTML report (pages), its plots (plots), the vocabulary both use:
each metric's column, the technique views and the colours of the truth and each technique
(columns), the visibility-difference and FLIP maps and their colours (images), every technique
ranked and its error against light elevation (ranking), and the Jinja templates.
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
