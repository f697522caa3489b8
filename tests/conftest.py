import os

import pytest

# Tests must not pick a GPU by accident, nor depend on the caller's choice.
os.environ.setdefault("HZVAL_VARIANT", "llvm_ad_rgb")

# Dr.Jit reads DRJIT_LIBLLVM_PATH when it is first imported, which the test modules do: point it at a
# working LLVM first, as hzval.cli.main.main does (hzval.init)
from hzval.core import backend as _backend  # noqa: E402

_backend.prefer_working_llvm()


@pytest.fixture(scope="session")
def variant():
    """Select hzval's Mitsuba variant once for the whole session."""
    from hzval.core import backend

    return backend.variant()
