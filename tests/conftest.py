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


@pytest.fixture
def scalar_centre(restore_variant):
    """Render a stage in the scalar fallback variant (8×8, 2 spp); return its centre's mean colour."""
    import warnings

    from pavonine.render.api import render_stage
    from pavonine.render.diagnostics import StageWarning

    def render(stage_path):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", StageWarning)
            result = render_stage(
                stage_path, spp=2, resolution=(8, 8), variant="scalar_spectral", progress=False
            )
        assert result.metadata["variant"] == "scalar_spectral"
        return result.rgb[2:6, 2:6].reshape(-1, 3).mean(axis=0)

    return render
