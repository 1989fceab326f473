"""Light translators beyond the basics: spot cones, focus, dome orientation, textured rect
lights, cylinder lights, and the UsdLux audit."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pxr import Gf, Sdf, UsdGeom, UsdLux
from render_helpers import bind, image, lum, new_stage, patch, preview, quad, render, sun

pytestmark = pytest.mark.render


def floor_with_point_light(tmp_path, name, **shaping):
    """A large white floor at z = 0 seen from above, a point light 2 units over its centre."""
    stage = new_stage(tmp_path / f"{name}.usda", camera_z=8.0)
    floor = quad(stage, "/Floor", size=3.0)
    bind(floor, preview(stage, diffuseColor=(0.8, 0.8, 0.8), roughness=1.0)[0])
    light = UsdLux.SphereLight.Define(stage, "/Lamp")
    light.CreateTreatAsPointAttr(True)
    light.CreateIntensityAttr(40.0)
    light.AddTranslateOp().Set(Gf.Vec3d(0, 0, 2))  # shining down −Z, onto the floor
    if shaping:
        UsdLux.ShapingAPI.Apply(light.GetPrim())
    for key, value in shaping.items():
        light.GetPrim().GetAttribute(f"inputs:shaping:{key}").Set(value)
    return stage


def radial_profile(rgb: np.ndarray) -> np.ndarray:
    """Mean luminance in rings around the image centre (ring i: radius i..i+1 pixels)."""
    h, w, _ = rgb.shape
    y, x = np.indices((h, w))
    r = np.hypot(x - w / 2 + 0.5, y - h / 2 + 0.5).astype(int)
    lum_image = rgb[..., :3] @ np.array([0.2126, 0.7152, 0.0722])
    return np.array([lum_image[r == i].mean() for i in range(min(h, w) // 2)])


def test_spot_cone_lights_inside_and_not_outside_unlike_a_point_light(tmp_path):
    point = radial_profile(render(floor_with_point_light(tmp_path, "point"), spp=32).rgb)
    spot = render(floor_with_point_light(tmp_path, "spot", **{"cone:angle": 30.0}), spp=32)
    profile = radial_profile(spot.rgb)
    # the camera (8 over the floor, 23.5° field) sees ±1.67: the cone of 30° from 2 units up
    # reaches 2·tan 30° = 1.15, i.e. ring 11 of 16
    edge = round(16 * math.tan(math.radians(30.0)) * 2.0 / (8.0 * math.tan(math.radians(11.7))))
    assert profile[: edge - 2] == pytest.approx(point[: edge - 2], rel=0.15)  # inside: as bright
    assert profile[edge + 2 :].max() < 0.02 * point[edge + 2 :].min()  # outside: dark
    assert point[edge + 2 :].min() > 0.05
    assert not any("shaping" in w for w in spot.warnings)


def test_cone_softness_and_focus_shape_the_falloff(tmp_path):
    hard = radial_profile(
        render(floor_with_point_light(tmp_path, "hard", **{"cone:angle": 40.0}), spp=32).rgb
    )
    soft = radial_profile(
        render(
            floor_with_point_light(tmp_path, "soft", **{"cone:angle": 40.0, "cone:softness": 1.0}),
            spp=32,
        ).rgb
    )
    assert soft[2] == pytest.approx(hard[2], rel=0.2)  # the centre is untouched
    middle = len(hard) // 2
    assert soft[middle] < 0.8 * hard[middle]  # a smooth fall towards the edge
    focused = radial_profile(
        render(
            floor_with_point_light(tmp_path, "focus", **{"cone:angle": 40.0, "focus": 20.0}), spp=32
        ).rgb
    )
    assert focused[middle] < 0.5 * hard[middle] and focused[0] == pytest.approx(hard[0], rel=0.2)


def test_missing_ies_file_and_shadow_switch_are_warned(tmp_path):
    stage = floor_with_point_light(tmp_path, "ies", **{"cone:angle": 30.0})
    lamp = stage.GetPrimAtPath("/Lamp")
    lamp.GetAttribute("inputs:shaping:ies:file").Set(Sdf.AssetPath("beam.ies"))
    UsdLux.ShadowAPI.Apply(lamp).CreateShadowEnableAttr(False)
    UsdLux.LightAPI(lamp).CreateDiffuseAttr(0.5)
    warnings = render(stage, spp=1, resolution=(8, 8)).warnings
    assert "/Lamp: inputs:shaping:ies:file 'beam.ies' not found; the light is not shaped by it" in (
        warnings
    )
    for name in ("inputs:shadow:enable", "inputs:diffuse"):
        assert any(w.startswith(f"/Lamp: {name} = ") for w in warnings), name


@pytest.mark.parametrize("kind", ["DistantLight", "DomeLight", "SphereLight", "RectLight"])
def test_a_180_degree_cone_is_no_shaping_and_no_warning(tmp_path, kind):
    """usd-wg McUsd: ``shaping:cone:angle = 180`` on a sun and a dome; a 180° cone cuts nothing."""
    stage = new_stage(tmp_path / f"{kind}.usda")
    quad(stage, "/Floor", size=3.0)
    light = getattr(UsdLux, kind).Define(stage, "/Light")
    light.CreateIntensityAttr(2.0)
    plain = render(stage, spp=4, resolution=(16, 16))
    shaping = UsdLux.ShapingAPI.Apply(light.GetPrim())
    shaping.CreateShapingConeAngleAttr(180.0)
    coned = render(stage, spp=4, resolution=(16, 16))
    assert coned.warnings == plain.warnings
    assert np.allclose(coned.rgb, plain.rgb, rtol=1e-4, atol=1e-4)  # same seed: the same image
    shaping.CreateShapingConeSoftnessAttr(0.6)  # now it cuts (softening from 72°), or is warned
    if kind in ("DistantLight", "DomeLight"):
        soft = render(stage, spp=4, resolution=(16, 16)).warnings
        assert any("/Light: inputs:shaping:cone:angle = 180" in w for w in soft), soft


def dome_stage(tmp_path, name, up, kind, pole=None):
    """Two tilted white cards facing ±Y, lit by a sky bright in the +Y half (latlong top half)."""
    sky = np.zeros((8, 16, 3), np.float32)
    sky[:4] = 1.0
    image(tmp_path / "sky.exr", sky)
    stage = new_stage(tmp_path / f"{name}.usda", up=up)
    for card, ny in (("Up", 1.0), ("Down", -1.0)):
        mesh = UsdGeom.Mesh.Define(stage, f"/{card}")
        y = 0.6 * ny
        back, front = (y + 0.25 * ny, -0.25), (y - 0.25 * ny, 0.25)
        mesh.CreatePointsAttr([(-0.5, *back), (0.5, *back), (0.5, *front), (-0.5, *front)])
        mesh.CreateFaceVertexCountsAttr([4])
        mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 3] if ny > 0 else [0, 3, 2, 1])
        mesh.CreateDoubleSidedAttr(True)
    dome = (UsdLux.DomeLight if kind == "DomeLight" else UsdLux.DomeLight_1).Define(stage, "/Sky")
    dome.CreateTextureFileAttr(Sdf.AssetPath("sky.exr"))
    if pole:
        dome.CreatePoleAxisAttr(pole)
    return stage


@pytest.mark.parametrize(
    ("up", "kind", "pole", "bright_up"),
    [
        ("Z", "DomeLight", None, True),  # plain DomeLight: +Y pole on any stage
        ("Y", "DomeLight_1", None, True),  # poleAxis scene on a Y-up stage: +Y
        ("Z", "DomeLight_1", None, False),  # poleAxis scene on a Z-up stage: +Z, not +Y
        ("Y", "DomeLight_1", "Z", False),
    ],
)
def test_dome_light_pole_axis(tmp_path, up, kind, pole, bright_up):
    rgb = render(dome_stage(tmp_path, f"{kind}{up}{pole}", up, kind, pole), spp=32).rgb
    upper, lower = (
        lum(patch(rgb, slice(6, 13), slice(12, 20))),
        lum(patch(rgb, slice(19, 26), slice(12, 20))),
    )
    if bright_up:
        assert upper > 3 * lower
    else:  # the bright half is +Z: the camera side, seen equally by both cards
        assert upper == pytest.approx(lower, rel=0.2)


def test_dome_light_colour_tints_its_texture_per_channel(tmp_path):
    stage = dome_stage(tmp_path, "tint", "Y", "DomeLight")
    UsdLux.DomeLight(stage.GetPrimAtPath("/Sky")).CreateColorAttr((1.0, 0.2, 0.2))
    upper = patch(render(stage, spp=32).rgb, slice(6, 13), slice(12, 20))
    assert upper[0] > 3 * upper[1]


def test_rect_light_texture_is_its_radiance_with_t_along_y(tmp_path):
    stage = new_stage(tmp_path / "rect.usda")
    rect = UsdLux.RectLight.Define(stage, "/Panel")
    rect.CreateWidthAttr(1.5)
    rect.CreateHeightAttr(1.5)
    rect.CreateIntensityAttr(2.0)
    top_red = np.zeros((8, 8, 3), np.float32)
    top_red[:4] = (1.0, 0.0, 0.0)  # the image's top rows
    top_red[4:] = (0.0, 0.0, 1.0)
    rect.CreateTextureFileAttr(Sdf.AssetPath(image(tmp_path / "panel.exr", top_red)))
    rect.AddRotateYOp().Set(180.0)  # emit along +Z, towards the camera
    rgb = render(stage).rgb
    top, bottom = patch(rgb, slice(10, 14), slice(12, 20)), patch(rgb, slice(18, 22), slice(12, 20))
    assert top[0] == pytest.approx(2.0, rel=0.1) and bottom[2] == pytest.approx(2.0, rel=0.1)


def test_cylinder_light_lights_the_floor_under_it(tmp_path):
    stage = new_stage(tmp_path / "tube.usda", camera_z=8.0)
    floor = quad(stage, "/Floor", size=3.0)
    bind(floor, preview(stage, diffuseColor=(0.8, 0.8, 0.8), roughness=1.0)[0])
    tube = UsdLux.CylinderLight.Define(stage, "/Tube")
    tube.CreateLengthAttr(2.0)
    tube.CreateRadiusAttr(0.05)
    tube.CreateIntensityAttr(30.0)
    tube.AddTranslateOp().Set(Gf.Vec3d(0, 1.0, 0.5))  # along X, over the upper part of the floor
    result = render(stage, spp=32)
    assert not result.warnings
    lit, far = (
        lum(patch(result.rgb, slice(6, 9), slice(10, 22))),
        lum(patch(result.rgb, slice(26, 29), slice(10, 22))),
    )
    assert lit > 3 * far > 0


def test_old_light_attribute_names_are_warned(tmp_path):
    stage = new_stage(tmp_path / "old.usda")
    light = sun(stage)
    light.GetPrim().CreateAttribute("intensity", Sdf.ValueTypeNames.Float).Set(5.0)
    quad(stage)
    warnings = render(stage, spp=1, resolution=(8, 8)).warnings
    assert any(
        w.startswith("/Sun: intensity is the old UsdLux name of inputs:intensity") for w in warnings
    )
