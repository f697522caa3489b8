"""``python -m hzval``: the ``hzval`` command (:func:`hzval.cli.main.main`)."""

import sys

from hzval.cli.main import main

sys.exit(main())
