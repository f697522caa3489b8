import os

import pytest

# Tests must not pick a GPU by accident, nor depend on the caller's choice.
os.environ.setdefault("HZVAL_VARIANT", "llvm_ad_rgb")


@pytest.fixture(scope="session")
def variant():
    """Select hzval's Mitsuba variant once for the whole session."""
    from hzval import backend

    return backend.variant()
