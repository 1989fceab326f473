"""hdmitsuba's sensor settings (``mitsuba:sensor:type``, ``mitsuba:sensor``, the film's pixel
filter): an irradiance meter attached to a mesh measures the irradiance it receives."""

from __future__ import annotations

import math

import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux
from render_helpers import render

pytestmark = pytest.mark.render


def metered_stage(tmp_path, sensor_type="irradiancemeter", attach=True, dome=2.0):
    """A cube under a constant dome of radiance ``dome``, a camera that is (or not) a meter."""
    stage = Usd.Stage.CreateNew(str(tmp_path / "meter.usda"))
    UsdGeom.SetStageUpAxis(stage, "Z")
    camera = UsdGeom.Camera.Define(stage, "/Camera")
    camera.AddTranslateOp().Set(Gf.Vec3d(0, 0, 8))
    attr = camera.GetPrim().CreateAttribute("mitsuba:sensor:type", Sdf.ValueTypeNames.String)
    attr.Set(sensor_type)
    camera.GetPrim().CreateAttribute(
        "mitsuba:sensor:film:pixel_filter:type", Sdf.ValueTypeNames.String
    ).Set("box")
    cube = UsdGeom.Mesh.Define(stage, "/Cube")
    points = [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
    cube.CreatePointsAttr(points)
    cube.CreateFaceVertexCountsAttr([4] * 6)
    cube.CreateFaceVertexIndicesAttr(
        [0, 1, 3, 2, 4, 6, 7, 5, 0, 4, 5, 1, 2, 3, 7, 6, 0, 2, 6, 4, 1, 5, 7, 3]
    )
    cube.CreateSubdivisionSchemeAttr("none")
    if attach:
        cube.GetPrim().CreateAttribute("mitsuba:sensor", Sdf.ValueTypeNames.String).Set("/Camera")
    UsdLux.DomeLight.Define(stage, "/Sky").CreateIntensityAttr(dome)
    return stage


def test_irradiance_meter_on_a_convex_mesh_reads_pi_times_the_sky(tmp_path):
    """Every face of a convex mesh sees a whole hemisphere of radiance L: E = π L (W m⁻²); each
    pixel is one estimate (noisy only through the wavelengths each sample draws)."""
    result = render(metered_stage(tmp_path, dome=2.0), spp=16, resolution=(8, 6))
    assert result.rgb.shape == (6, 8, 3)  # the film is the image, each pixel one estimate
    grey = result.rgb.mean(axis=2)
    assert grey.mean() == pytest.approx(2.0 * math.pi, rel=0.01)
    assert grey.std() < 0.1 * grey.mean()  # flat: no pixel sees anything the others do not
    assert not [w for w in result.warnings if "mitsuba:sensor" in w], result.warnings


def test_a_perspective_sensor_type_is_the_camera_itself(tmp_path):
    meter = render(metered_stage(tmp_path), spp=8, resolution=(16, 16))
    camera = render(metered_stage(tmp_path, "perspective"), spp=8, resolution=(16, 16))
    assert not [w for w in camera.warnings if "mitsuba:sensor" in w], camera.warnings
    assert meter.rgb.mean() == pytest.approx(2.0 * math.pi, rel=0.05)  # irradiance, W m⁻²
    assert camera.rgb[0, 0].mean() == pytest.approx(2.0, rel=0.1)  # the sky's radiance, seen
    assert camera.rgb[8, 8].mean() < 1.5  # the cube, seen from above


def test_unknown_sensor_settings_and_a_meter_without_mesh_are_warned(tmp_path):
    odd = render(metered_stage(tmp_path, "radiancemeter"), spp=1, resolution=(8, 8))
    assert any(
        w.startswith("/Camera: mitsuba:sensor:type = 'radiancemeter' (hdmitsuba's setting) is not")
        for w in odd.warnings
    ), odd.warnings
    lone = render(metered_stage(tmp_path, attach=False), spp=1, resolution=(8, 8))
    assert any("needs exactly one rendered mesh" in w for w in lone.warnings), lone.warnings
    assert lone.rgb[0, 0].mean() == pytest.approx(2.0, rel=0.2)  # through the camera's lens
