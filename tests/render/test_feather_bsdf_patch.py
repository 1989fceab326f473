"""A flat patch of one class renders to the colour the optics model predicts (issue 5 acceptance)."""

import math

import numpy as np
import pytest

pytest.importorskip("mitsuba")  # conftest says why when it cannot load
from pavonine.base.backend import select_variant
from pavonine.materials import colour, optics
from pavonine.materials.brdf import direction
from pavonine.materials.parameters import FeatherParameters, preset
from pavonine.render.feather_bsdf import feather_bsdf_dict, register

pytestmark = pytest.mark.render

select_variant()
import mitsuba as mi

register()

INCIDENCE, OBSERVE = (20.0, 90.0), (30.0, 270.0)  # (θ, φ) in degrees; φ from the barbule axis


def _render_patch(bsdf: dict, spp: int = 256) -> np.ndarray:
    wi, wo = direction(*INCIDENCE), direction(*OBSERVE)
    scene = mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": "direct"},
            "patch": {"type": "rectangle", "bsdf": bsdf},
            "sun": {"type": "directional", "direction": (-wi).tolist(), "irradiance": 1.0},
            "sensor": {
                "type": "orthographic",
                "to_world": mi.ScalarTransform4f().look_at(
                    origin=(3 * wo).tolist(),
                    target=[0, 0, 0],
                    up=[0, 0, 1] if abs(wo[2]) < 0.99 else [0, 1, 0],
                )
                @ mi.ScalarTransform4f().scale([0.3, 0.3, 1]),
                "film": {
                    "type": "hdrfilm",
                    "width": 8,
                    "height": 8,
                    "pixel_format": "rgb",
                    "rfilter": {"type": "box"},
                },
                "sampler": {"type": "independent", "sample_count": spp},
            },
        }
    )
    image = np.array(mi.render(scene, seed=1))
    return image.reshape(-1, 3).mean(axis=0)


def _class_dict(params: FeatherParameters, ocellar_class: int) -> dict:
    d = feather_bsdf_dict(params)
    d["ocellar"] = {"type": "uniform", "value": 1.0 - ocellar_class / (len(params.classes) - 1)}
    d["gradation"] = {"type": "uniform", "value": 0.5}
    return d


def _predicted(params: FeatherParameters, ocellar_class: int) -> np.ndarray:
    """Model colour of the patch relative to a white Lambertian patch under the same light."""
    wavelengths = optics.COLOUR_WAVELENGTHS_NM
    f = optics.model_for(params).brdf(
        direction(*INCIDENCE), direction(*OBSERVE), wavelengths, ocellar_class, 0.5
    )
    return colour.reflectance_to_linear_srgb(wavelengths, math.pi * f)


@pytest.fixture(scope="module")
def white():
    rgb = _render_patch({"type": "diffuse", "reflectance": 1.0})
    np.testing.assert_allclose(rgb, rgb.mean(), rtol=0.01)  # D65 light on white: neutral
    return rgb


@pytest.mark.parametrize("ocellar_class", [0, 2, 3, 5])
def test_patch_renders_the_models_colour(white, ocellar_class):
    params = preset("paper-table1")
    rendered = _render_patch(_class_dict(params, ocellar_class)) / white
    expected = _predicted(params, ocellar_class)
    assert colour.delta_e76(rendered, expected) < 2.0, (rendered, expected)


def test_layer_interval_shift_moves_rendered_hue_like_the_model(white):
    base = preset("blue")
    stretched = FeatherParameters.from_class_arrays(
        {k: v * (1.12 if k.endswith("interval") else 1.0) for k, v in base.class_arrays().items()}
    )
    hues = {}
    for name, params in (("base", base), ("stretched", stretched)):
        rendered = _render_patch(feather_bsdf_dict(params)) / white
        expected = _predicted(params, 0)
        assert colour.delta_e76(rendered, expected) < 2.0
        lab = colour.xyz_to_lab(colour.linear_srgb_to_xyz(rendered))
        hues[name] = math.degrees(math.atan2(lab[2], lab[1]))
    # A longer interval moves the Bragg peak to longer wavelengths: blue-green → green/yellow,
    # i.e. the CIELAB hue angle decreases from ~200° towards 100°.
    assert hues["stretched"] < hues["base"] - 10
