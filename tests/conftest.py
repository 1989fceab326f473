"""Shared pytest fixtures."""

import pytest


@pytest.fixture
def restore_variant():
    """Give the test the current Mitsuba variant and select it again afterwards (tests that switch
    to the scalar fallback must not leave the rest of the session in it)."""
    from pavonine.backend import select_variant

    previous = select_variant().variant
    yield previous
    select_variant(previous)
