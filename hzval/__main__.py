"""``python -m hzval``: the ``hzval`` command (:func:`hzval.cli.main`)."""

import sys

from hzval.cli import main

sys.exit(main())
