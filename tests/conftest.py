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


@pytest.fixture(scope="session")
def eye_asset(tmp_path_factory):
    """A converted eye feather shared by the portable-asset tests (256-px maps, 12k/4k/1k
    triangles, 256² baked textures; the shipped feathers' freyer2020 preset). Tests that change it work on a copy."""
    from pavonine.pipeline.convert.batch import convert_recipe
    from pavonine.pipeline.maps.paint import MAP_NAMES, generate_maps, write_maps

    work = tmp_path_factory.mktemp("eye_asset")
    write_maps(generate_maps("eye", 256, seed=4), work / "m")
    maps = "\n".join(f'{name} = "m/{name}.png"' for name in MAP_NAMES)
    (work / "eye.toml").write_text(
        f'name = "eye_feather"\n[maps]\n{maps}\n[material]\npreset = "freyer2020"\n'
        "[geometry]\nlength_cm = 20\nrachis_length = 0.74\n"
        "[geometry.lod]\nhigh = 12000\nmedium = 4000\nlow = 1000\n[bake]\nresolution = 256\n"
    )
    result = convert_recipe(work / "eye.toml", work / "out")
    return result.root
