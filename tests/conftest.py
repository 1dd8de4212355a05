"""Fixtures shared by the whole suite (helpers and strategies: tests/support/helpers.py)."""

import pytest

from support import helpers


@pytest.fixture
def harmony() -> dict:
    """A fresh copy of the Harmony-like config as a dict."""
    return helpers.harmony_dict()
