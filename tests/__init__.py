"""hzval's tests, laid out as the package is.

- ``tests/<subpackage>/test_<module>.py``: the unit tests of ``hzval/<subpackage>/<module>.py``;
  a module with more than one aspect to test has further files ``test_<module>_<aspect>.py``.
- ``tests/integration/``: end-to-end runs of the CLI (``hzval ...`` as a user types it).
- ``tests/oracles/``: independent references the tests compare against (no test imports from
  ``benchmarks/`` or ``studies/``), with their own tests.
- ``tests/hard/``: the hard-cases suite (extreme lights, geometry, sizes, precision, bad input).
- ``tests/test_structure.py``: the package's shape (layers, cycles, names).

Every folder is a package, so same-named files (``tests/bake/test_horizon.py`` and
``tests/techniques/test_horizon.py``) do not clash; test modules import shared helpers by their
full name (``from tests.helpers import make_scene``).
"""
