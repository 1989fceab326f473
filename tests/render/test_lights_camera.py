"""Each light kind and camera parameter: a tiny stage and a measurable property of its render."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdRender

from pavonine.render.api import render_stage
from pavonine.render.diagnostics import StageWarning

pytestmark = pytest.mark.render
RES = (32, 32)


def stage_with_plane(path, *, normal_z=True, size=1.0, x=0.0, camera=True, **camera_attrs):
    """A white Lambertian square (facing +Z) and a camera 5 units in front of it."""
    stage = Usd.Stage.CreateNew(str(path))
    mesh = UsdGeom.Mesh.Define(stage, "/Plane")
    s = size
    mesh.CreatePointsAttr([(x - s, -s, 0), (x + s, -s, 0), (x + s, s, 0), (x - s, s, 0)])
    mesh.CreateFaceVertexCountsAttr([4])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    mesh.CreateSubdivisionSchemeAttr("none")
    UsdGeom.PrimvarsAPI(mesh).CreatePrimvar(
        "displayColor", Sdf.ValueTypeNames.Color3fArray, "constant"
    ).Set([(1, 1, 1)])
    if camera:
        cam = UsdGeom.Camera.Define(stage, "/Cam")
        cam.AddTranslateOp().Set(Gf.Vec3d(0, 0, 5))
        for name, value in camera_attrs.items():
            cam.GetPrim().GetAttribute(name).Set(value)
    return stage


def render(stage, spp=16, **kwargs):
    stage.Save()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        return render_stage(
            stage.GetRootLayer().realPath,
            spp=spp,
            resolution=kwargs.pop("resolution", RES),
            progress=False,
            **kwargs,
        )


def centre(result, half=4):
    h, w, _ = result.rgb.shape
    return result.rgb[h // 2 - half : h // 2 + half, w // 2 - half : w // 2 + half].mean(
        axis=(0, 1)
    )


def side(result):
    """A patch of the plane left of centre: lit by lights between camera and plane, not hidden by them."""
    h, w, _ = result.rgb.shape
    return result.rgb[h // 2 - 4 : h // 2 + 4, w // 8 : w // 4 + 1].mean(axis=(0, 1))


def lum(rgb):
    return float(np.dot(rgb, [0.2126, 0.7152, 0.0722]))


def mask(result, threshold=0.05):
    return result.rgb.mean(axis=2) > threshold


def sun(stage, intensity=math.pi, angle=0.0, normalize=True, tilt_deg=0.0, path="/Sun"):
    light = UsdLux.DistantLight.Define(stage, path)
    light.CreateIntensityAttr(intensity)
    light.CreateAngleAttr(angle)
    light.CreateNormalizeAttr(normalize)
    if tilt_deg:
        light.AddRotateYOp().Set(tilt_deg)
    return light


# -- DistantLight -------------------------------------------------------------------------------


def test_distant_light_irradiance_and_cosine_law(tmp_path):
    stage = stage_with_plane(tmp_path / "sun.usda")
    light = sun(stage)
    facing = lum(centre(render(stage)))
    assert facing == pytest.approx(1.0, rel=0.08)  # white Lambertian, E = π → L = 1
    light.AddRotateYOp().Set(60.0)
    tilted = lum(centre(render(stage)))
    assert tilted / facing == pytest.approx(0.5, rel=0.08)  # cos 60°


def test_distant_light_intensity_and_exposure_scale_brightness(tmp_path):
    stage = stage_with_plane(tmp_path / "sun.usda")
    light = sun(stage, intensity=1.0)
    base = lum(centre(render(stage)))
    light.CreateIntensityAttr(2.0)
    assert lum(centre(render(stage))) / base == pytest.approx(2.0, rel=0.05)
    light.CreateExposureAttr(1.0)
    assert lum(centre(render(stage))) / base == pytest.approx(4.0, rel=0.05)


def test_sun_angle_normalized_keeps_illuminance_unnormalized_scales_with_solid_angle(tmp_path):
    stage = stage_with_plane(tmp_path / "sun.usda")
    light = sun(stage, angle=2.0, normalize=True)
    disc = lum(centre(render(stage, spp=32)))
    assert disc == pytest.approx(1.0, rel=0.1)
    light.CreateNormalizeAttr(False)
    light.CreateIntensityAttr(1000.0)
    small = lum(centre(render(stage, spp=32)))
    light.CreateAngleAttr(4.0)
    large = lum(centre(render(stage, spp=32)))
    ratio = (1 - math.cos(math.radians(2.0))) / (1 - math.cos(math.radians(1.0)))
    assert large / small == pytest.approx(ratio, rel=0.1)


def test_sun_highlight_follows_direction(tmp_path):
    """A glossy plane seen from the front: the highlight sits where the mirror direction points."""
    stage = stage_with_plane(tmp_path / "gloss.usda", size=3.0)
    from pxr import UsdShade

    material = UsdShade.Material.Define(stage, "/Looks/Gloss")
    shader = UsdShade.Shader.Define(stage, "/Looks/Gloss/Surface")
    shader.CreateIdAttr("UsdPreviewSurface")
    shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set((0.02, 0.02, 0.02))
    shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(0.15)
    shader.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(1.0)
    material.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
    UsdShade.MaterialBindingAPI.Apply(stage.GetPrimAtPath("/Plane")).Bind(material)
    light = sun(stage, intensity=10.0)
    rotate = light.AddRotateYOp()
    columns = []
    for angle in (-15.0, 15.0):  # light travelling towards -X+… vs +X
        rotate.Set(angle)
        image = render(stage).rgb.mean(axis=2)
        columns.append(float(np.argmax(image.mean(axis=0))))
    # rotating the sun about Y moves the highlight across the image, in opposite directions
    assert columns[0] < 14 and columns[1] > 17


# -- DomeLight ----------------------------------------------------------------------------------


def test_dome_light_colour_and_intensity(tmp_path):
    stage = stage_with_plane(tmp_path / "dome.usda")
    dome = UsdLux.DomeLight.Define(stage, "/Sky")
    dome.CreateColorAttr((1.0, 0.5, 0.25))
    dome.CreateIntensityAttr(1.0)
    rgb = centre(render(stage, spp=32))
    # one-sided Lambertian under a uniform sky of radiance L reflects L (albedo 1)
    assert rgb == pytest.approx([1.0, 0.5, 0.25], rel=0.12)


def test_dome_light_texture_is_up_oriented(tmp_path):
    import OpenImageIO as oiio

    sky = np.zeros((8, 16, 3), dtype=np.float32)
    sky[:4] = 1.0  # bright upper hemisphere (+Y in a Y-up stage), black ground
    out = oiio.ImageOutput.create(str(tmp_path / "sky.exr"))
    out.open(str(tmp_path / "sky.exr"), oiio.ImageSpec(16, 8, 3, oiio.FLOAT))
    out.write_image(sky)
    out.close()
    stage = Usd.Stage.CreateNew(str(tmp_path / "dometex.usda"))
    for name, ny in (("Up", 1.0), ("Down", -1.0)):
        mesh = UsdGeom.Mesh.Define(stage, f"/{name}")
        y = 0.6 * ny
        # tilted 45° so that the camera (at +Z) sees both; visible normal (0, ny, 1)/√2
        back, front = (y + 0.25 * ny, -0.25), (y - 0.25 * ny, 0.25)
        mesh.CreatePointsAttr([(-0.5, *back), (0.5, *back), (0.5, *front), (-0.5, *front)])
        mesh.CreateFaceVertexCountsAttr([4])
        mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 3] if ny > 0 else [0, 3, 2, 1])
        mesh.CreateSubdivisionSchemeAttr("none")
        mesh.CreateDoubleSidedAttr(True)
    cam = UsdGeom.Camera.Define(stage, "/Cam")
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 0, 5))
    dome = UsdLux.DomeLight.Define(stage, "/Sky")
    dome.CreateTextureFileAttr(Sdf.AssetPath("sky.exr"))
    image = render(stage, spp=32).rgb.mean(axis=2)
    upper, lower = image[6:13, 12:20].mean(), image[19:26, 12:20].mean()
    assert upper > 2.0 * lower


# -- SphereLight, RectLight, DiskLight --------------------------------------------------------------


def _area_light(stage, kind, **attrs):
    cls = {"sphere": UsdLux.SphereLight, "rect": UsdLux.RectLight, "disk": UsdLux.DiskLight}[kind]
    light = cls.Define(stage, f"/{kind}")
    light.AddTranslateOp().Set(Gf.Vec3d(0, 0, 2))
    for name, value in attrs.items():
        light.GetPrim().GetAttribute(f"inputs:{name}").Set(value)
    return light


@pytest.mark.parametrize("kind", ["sphere", "rect", "disk"])
def test_area_lights_scale_with_intensity_and_exposure(tmp_path, kind):
    stage = stage_with_plane(tmp_path / f"{kind}.usda")
    size = {
        "sphere": {"radius": 0.1},
        "rect": {"width": 0.2, "height": 0.2},
        "disk": {"radius": 0.1},
    }[kind]
    light = _area_light(stage, kind, intensity=20.0, **size)
    base = lum(side(render(stage, spp=32)))
    assert base > 0.01
    light.GetPrim().GetAttribute("inputs:exposure").Set(1.0)
    assert lum(side(render(stage, spp=32))) / base == pytest.approx(2.0, rel=0.1)


@pytest.mark.parametrize("kind", ["sphere", "rect", "disk"])
def test_area_light_normalize_keeps_power_when_resized(tmp_path, kind):
    stage = stage_with_plane(tmp_path / f"{kind}.usda")
    small = {
        "sphere": {"radius": 0.05},
        "rect": {"width": 0.1, "height": 0.1},
        "disk": {"radius": 0.05},
    }[kind]
    light = _area_light(stage, kind, intensity=20.0, **small)
    unnormalized_small = lum(side(render(stage, spp=32)))
    light.CreateNormalizeAttr(True)
    normalized_small = lum(side(render(stage, spp=32)))
    for name, value in small.items():
        light.GetPrim().GetAttribute(f"inputs:{name}").Set(2 * value)
    normalized_large = lum(side(render(stage, spp=32)))
    light.CreateNormalizeAttr(False)
    unnormalized_large = lum(side(render(stage, spp=32)))
    assert normalized_large / normalized_small == pytest.approx(1.0, rel=0.1)
    assert unnormalized_large / unnormalized_small == pytest.approx(4.0, rel=0.12)


def test_rect_light_emits_along_minus_z_only(tmp_path):
    stage = stage_with_plane(tmp_path / "rect.usda")
    light = _area_light(stage, "rect", intensity=50.0, width=0.3, height=0.3)
    toward = lum(side(render(stage)))
    light.AddRotateXOp().Set(180.0)  # now emitting away from the plane
    away = lum(side(render(stage)))
    assert toward > 0.05 and away < 0.02 * toward


def test_color_temperature_warms_the_light(tmp_path):
    stage = stage_with_plane(tmp_path / "warm.usda")
    light = sun(stage)
    light.CreateEnableColorTemperatureAttr(True)
    light.CreateColorTemperatureAttr(3000.0)
    r, g, b = centre(render(stage, spp=32))
    assert r > 1.3 * b and r > g > b


# -- Camera ---------------------------------------------------------------------------------------


def _width_px(result):
    return int(mask(result)[RES[1] // 2].sum())


def _centroid_x(result):
    cols = np.nonzero(mask(result).any(axis=0))[0]
    return cols.mean()


def test_focal_length_and_aperture_set_the_field_of_view(tmp_path):
    stage = stage_with_plane(tmp_path / "cam.usda", size=0.5, focalLength=50.0)
    sun(stage)
    base = _width_px(render(stage, spp=4))
    stage.GetPrimAtPath("/Cam").GetAttribute("focalLength").Set(100.0)
    assert _width_px(render(stage, spp=4)) == pytest.approx(2 * base, abs=1)
    stage.GetPrimAtPath("/Cam").GetAttribute("horizontalAperture").Set(2 * 20.955)
    assert _width_px(render(stage, spp=4)) == pytest.approx(base, abs=1)


def test_aperture_offset_shifts_the_view_window(tmp_path):
    stage = stage_with_plane(tmp_path / "offset.usda", size=0.3)
    sun(stage)
    base = _centroid_x(render(stage, spp=4))
    stage.GetPrimAtPath("/Cam").GetAttribute("horizontalApertureOffset").Set(20.955 / 4)
    shifted = _centroid_x(render(stage, spp=4))
    assert shifted == pytest.approx(base - RES[0] / 4, abs=1)  # window right by ¼ → object left


def test_clipping_range_hides_geometry_outside_it(tmp_path):
    stage = stage_with_plane(tmp_path / "clip.usda")
    sun(stage)
    assert mask(render(stage, spp=4)).any()
    stage.GetPrimAtPath("/Cam").GetAttribute("clippingRange").Set(Gf.Vec2f(6.0, 100.0))
    assert not mask(render(stage, spp=4)).any()


def test_render_settings_camera_resolution_and_pixel_aspect(tmp_path):
    stage = stage_with_plane(tmp_path / "settings.usda", size=0.5)
    sun(stage)
    wide = UsdGeom.Camera.Define(stage, "/Wide")
    wide.AddTranslateOp().Set(Gf.Vec3d(0, 0, 10))
    settings = UsdRender.Settings.Define(stage, "/Render/Settings")
    settings.CreateResolutionAttr(Gf.Vec2i(32, 16))
    settings.CreateCameraRel().SetTargets(["/Wide"])
    stage.Save()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        far = render_stage(str(tmp_path / "settings.usda"), spp=4, progress=False)
        near = render_stage(str(tmp_path / "settings.usda"), spp=4, camera="/Cam", progress=False)
    assert far.rgb.shape == (16, 32, 3) and far.metadata["camera"] == "/Wide"
    assert mask(near).sum() == pytest.approx(4 * mask(far).sum(), rel=0.25)
    settings.CreatePixelAspectRatioAttr(2.0)
    stretched = render(stage, spp=4, resolution=None)
    # pixels twice as wide → the square covers half as many columns, as many rows
    cols = lambda r: mask(r).any(axis=0).sum()  # noqa: E731
    rows = lambda r: mask(r).any(axis=1).sum()  # noqa: E731
    assert cols(stretched) == pytest.approx(cols(far) / 2, abs=1)
    assert rows(stretched) == pytest.approx(rows(far), abs=1)


def test_time_sampled_camera_moves(tmp_path):
    stage = stage_with_plane(tmp_path / "anim.usda", size=0.3)
    sun(stage)
    cam = UsdGeom.Xformable(stage.GetPrimAtPath("/Cam"))
    op = cam.GetOrderedXformOps()[0]
    op.Set(Gf.Vec3d(0, 0, 5), 1.0)
    op.Set(Gf.Vec3d(0.5, 0, 5), 2.0)
    a = _centroid_x(render(stage, spp=4, time=1.0))
    b = _centroid_x(render(stage, spp=4, time=2.0))
    assert b < a - 2  # camera moves right → object moves left
