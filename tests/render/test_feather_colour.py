"""Acceptance: a flat feather patch renders to the colour the optics model predicts."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux

from pavonine.materials.parameters import LayerStack, OcellarClass, preset
from pavonine.render.api import render_stage
from pavonine.render.diagnostics import StageWarning

pytestmark = pytest.mark.render
THETA_I = 20.0  # sun 20° from the vane normal, in the plane of the barbule's long axis


def patch_stage(path, params):
    from render_helpers import feather_sheet

    from pavonine.schemas.authoring import create_feather_material

    stage = Usd.Stage.CreateNew(str(path))
    # u along +X: the barbule axis (angle map absent = 0); the legacy uv name, as older assets
    mesh = feather_sheet(
        stage,
        "/Patch",
        [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)],
        uv="pavonine:featherUV",
        uv_type=Sdf.ValueTypeNames.Float2Array,
    )
    material = create_feather_material(stage, "/Looks/Patch", params)
    from pxr import UsdShade

    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(material)
    cam = UsdGeom.Camera.Define(stage, "/Cam")
    cam.CreateFocalLengthAttr(1000.0)  # ~1.2° field: the view direction is the normal everywhere
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 0, 20))
    sun = UsdLux.DistantLight.Define(stage, "/Sun")
    sun.CreateAngleAttr(0.0)
    sun.CreateNormalizeAttr(True)
    sun.CreateIntensityAttr(math.pi)  # E = π: a white Lambertian would read 1
    sun.AddRotateYOp().Set(THETA_I)  # travels towards (−sin θ, 0, −cos θ): comes from +X
    stage.Save()
    return str(path)


def predicted_rgb(params) -> np.ndarray:
    """Model spectrum for this geometry through the same colour pipeline (CIE 1931, D65, Rec.709)."""
    from pavonine.materials.brdf import (
        MaterialConstants,
        RowTable,
        direction,
        feather_brdf,
        stack_in_nm,
    )
    from pavonine.materials.colour import reflectance_to_linear_srgb

    wavelengths = np.arange(360.0, 831.0, 1.0)
    long_stack, short_stack = params.stacks(0, 0.0)
    wi = direction(THETA_I, 0.0)
    wo = direction(0.0, 0.0)
    f = feather_brdf(
        MaterialConstants.from_parameters(params),
        RowTable.build(complex(params.melanin_index / params.medium_index)),
        tuple(wi),
        tuple(wo),
        wavelengths,
        stack_in_nm(long_stack),
        stack_in_nm(short_stack),
        1.0,
        np.zeros_like(wavelengths),
    )
    # radiance = f · E · cos θ_i with E = π (relative to a white diffuser's π·(1/π)·... = 1)
    return reflectance_to_linear_srgb(
        wavelengths, np.asarray(f) * math.pi * math.cos(math.radians(THETA_I))
    )


def one_class(interval_scale: float = 1.0):
    base = preset("paper-table1")
    cls = base.classes[1]

    def scaled(stacks):
        return tuple(LayerStack(s.interval * interval_scale, s.radius, s.count) for s in stacks)

    return base.with_(classes=(OcellarClass(long=scaled(cls.long), short=scaled(cls.short)),))


def rendered_rgb(tmp_path, params, name):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        result = render_stage(
            patch_stage(tmp_path / f"{name}.usda", params),
            spp=64,
            resolution=(16, 16),
            progress=False,
        )
    return result.rgb[4:12, 4:12].reshape(-1, 3).mean(axis=0)


def test_flat_patch_matches_the_optics_model_and_interval_shifts_hue(tmp_path):
    pytest.importorskip("pavonine.schemas.authoring")
    from pavonine.materials.colour import delta_e76

    base, wider = one_class(1.0), one_class(1.15)
    rendered_base, rendered_wider = (
        rendered_rgb(tmp_path, base, "base"),
        rendered_rgb(tmp_path, wider, "wider"),
    )
    model_base, model_wider = predicted_rgb(base), predicted_rgb(wider)
    assert float(delta_e76(rendered_base, model_base)) < 3.0
    assert float(delta_e76(rendered_wider, model_wider)) < 3.0
    # a 15 % wider layer interval moves the colour as the model says, by much more than the error
    assert float(delta_e76(model_base, model_wider)) > 10.0
    shift_model = model_wider - model_base
    shift_render = rendered_wider - rendered_base
    assert (
        np.dot(shift_model, shift_render)
        / (np.linalg.norm(shift_model) * np.linalg.norm(shift_render))
        > 0.9
    )


def test_scalar_variant_renders_the_feather_patch(tmp_path, scalar_centre):
    """The fallback without libLLVM renders the feather BSDF too (8×8, 2 spp: a loose check)."""
    params = one_class()
    centre = scalar_centre(patch_stage(tmp_path / "scalar.usda", params))
    assert centre == pytest.approx(predicted_rgb(params), abs=0.1)
