"""Materials and instancing, seen in renders: preview surface colour, textures, subsets, instances."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade

from pavonine.render.api import render_stage
from pavonine.render.diagnostics import Diagnostics, StageWarning

pytestmark = pytest.mark.render


def base_stage(path):
    stage = Usd.Stage.CreateNew(str(path))
    cam = UsdGeom.Camera.Define(stage, "/Cam")
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 0, 5))
    sun = UsdLux.DistantLight.Define(stage, "/Sun")
    sun.CreateAngleAttr(0.0)
    sun.CreateNormalizeAttr(True)
    sun.CreateIntensityAttr(3.14159)
    return stage


def square(stage, path, x0, x1, y0, y1, st=True):
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreatePointsAttr([(x0, y0, 0), (x1, y0, 0), (x1, y1, 0), (x0, y1, 0)])
    mesh.CreateFaceVertexCountsAttr([4])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    mesh.CreateSubdivisionSchemeAttr("none")
    if st:
        UsdGeom.PrimvarsAPI(mesh).CreatePrimvar(
            "st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying
        ).Set([(0, 0), (1, 0), (1, 1), (0, 1)])
    return mesh


def preview(stage, path, color=None, texture=None):
    material = UsdShade.Material.Define(stage, path)
    shader = UsdShade.Shader.Define(stage, f"{path}/Surface")
    shader.CreateIdAttr("UsdPreviewSurface")
    shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(1.0)
    diffuse = shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f)
    if texture:
        tex = UsdShade.Shader.Define(stage, f"{path}/Albedo")
        tex.CreateIdAttr("UsdUVTexture")
        tex.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(texture)
        diffuse.ConnectToSource(tex.ConnectableAPI(), "rgb")
    else:
        diffuse.Set(color)
    material.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
    return material


def render(stage, **kwargs):
    stage.Save()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        return render_stage(
            stage.GetRootLayer().realPath, spp=16, resolution=(32, 32), progress=False, **kwargs
        ).rgb


def test_preview_surface_subsets_give_each_half_its_colour(tmp_path):
    stage = base_stage(tmp_path / "subsets.usda")
    mesh = UsdGeom.Mesh.Define(stage, "/Mesh")
    mesh.CreatePointsAttr([(-1, -1, 0), (0, -1, 0), (1, -1, 0), (-1, 1, 0), (0, 1, 0), (1, 1, 0)])
    mesh.CreateFaceVertexCountsAttr([4, 4])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 4, 3, 1, 2, 5, 4])
    mesh.CreateSubdivisionSchemeAttr("none")
    red, green = (
        preview(stage, "/Looks/Red", (0.8, 0.05, 0.05)),
        preview(stage, "/Looks/Green", (0.05, 0.8, 0.05)),
    )
    left = UsdGeom.Subset.CreateGeomSubset(mesh, "left", "face", [0], "materialBind")
    right = UsdGeom.Subset.CreateGeomSubset(mesh, "right", "face", [1], "materialBind")
    UsdShade.MaterialBindingAPI.Apply(left.GetPrim()).Bind(red)
    UsdShade.MaterialBindingAPI.Apply(right.GetPrim()).Bind(green)
    rgb = render(stage)
    lhs, rhs = rgb[12:20, 9:14].reshape(-1, 3).mean(0), rgb[12:20, 18:23].reshape(-1, 3).mean(0)
    assert lhs[0] > 4 * lhs[1] and rhs[1] > 4 * rhs[0]


def test_texture_is_upright(tmp_path):
    import OpenImageIO as oiio

    image = np.zeros((8, 8, 3), dtype=np.float32)
    image[:4, :, 0] = 1.0  # top rows red
    image[4:, :, 2] = 1.0  # bottom rows blue
    out = oiio.ImageOutput.create(str(tmp_path / "tex.exr"))
    out.open(str(tmp_path / "tex.exr"), oiio.ImageSpec(8, 8, 3, oiio.FLOAT))
    out.write_image(image)
    out.close()
    stage = base_stage(tmp_path / "tex.usda")
    mesh = square(stage, "/Quad", -1, 1, -1, 1)
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(
        preview(stage, "/Looks/Tex", texture="tex.exr")
    )
    rgb = render(stage)
    top, bottom = rgb[9:14, 12:20].reshape(-1, 3).mean(0), rgb[18:23, 12:20].reshape(-1, 3).mean(0)
    assert top[0] > 3 * top[2] and bottom[2] > 3 * bottom[0]


def test_point_instancer_draws_every_instance(tmp_path):
    stage = base_stage(tmp_path / "instancer.usda")
    instancer = UsdGeom.PointInstancer.Define(stage, "/Tail")
    square(stage, "/Tail/Protos/Feather", -0.2, 0.2, -0.2, 0.2, st=False)
    instancer.CreatePrototypesRel().SetTargets(["/Tail/Protos/Feather"])
    instancer.CreateProtoIndicesAttr([0, 0, 0])
    instancer.CreatePositionsAttr([(-1.2, 0, 0), (0, 0, 0), (1.2, 0, 0)])
    row = render(stage).mean(axis=2)[16] > 0.1
    runs = np.count_nonzero(np.diff(row.astype(int)) == 1) + int(row[0])
    assert runs == 3
    instancer.CreateInvisibleIdsAttr([1])
    instancer.CreateIdsAttr([0, 1, 2])
    row = render(stage).mean(axis=2)[16] > 0.1
    assert np.count_nonzero(np.diff(row.astype(int)) == 1) + int(row[0]) == 2


def test_scalar_variant_renders_a_preview_surface_quad(tmp_path, scalar_centre):
    """The fallback without libLLVM: a red quad under a sun of E = π reads its diffuse colour."""
    stage = base_stage(tmp_path / "scalar.usda")
    mesh = square(stage, "/Quad", -1, 1, -1, 1)
    material = preview(stage, "/Looks/Red", color=(0.8, 0.2, 0.1))
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(material)
    stage.Save()
    centre = scalar_centre(stage.GetRootLayer().realPath)
    assert centre == pytest.approx([0.8, 0.2, 0.1], abs=0.1)


def rgba_texture(path, rgba: np.ndarray) -> str:
    import OpenImageIO as oiio

    spec = oiio.ImageSpec(rgba.shape[1], rgba.shape[0], 4, oiio.UINT8)
    spec.attribute("oiio:UnassociatedAlpha", 1)  # store the alpha channel as it is
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), spec) and out.write_image(rgba)
    out.close()
    return str(path)


def channel_material(stage, path, texture, wiring, **texture_inputs):
    """A preview surface whose inputs read texture channels: ``wiring`` = {input: output}."""
    material = UsdShade.Material.Define(stage, path)
    shader = UsdShade.Shader.Define(stage, f"{path}/Surface")
    shader.CreateIdAttr("UsdPreviewSurface")
    shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set((0.8, 0.8, 0.8))
    tex = UsdShade.Shader.Define(stage, f"{path}/Maps")
    tex.CreateIdAttr("UsdUVTexture")
    tex.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(texture)
    reader = UsdShade.Shader.Define(stage, f"{path}/St")
    reader.CreateIdAttr("UsdPrimvarReader_float2")
    reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("st")
    tex.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(
        reader.ConnectableAPI(), "result"
    )
    for name, (kind, value) in texture_inputs.items():
        tex.CreateInput(name, kind).Set(value)
    for usd_input, output in wiring.items():
        shader.CreateInput(usd_input, Sdf.ValueTypeNames.Float).ConnectToSource(
            tex.ConnectableAPI(), output
        )
    material.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
    return material, shader


def translated(material):
    from pavonine.render.materials import translate_material

    diag = Diagnostics()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        spec = translate_material(material, Usd.TimeCode.Default(), diag)
    return spec, diag


def test_texture_channels_scale_and_bias_reach_their_inputs(tmp_path):
    rgba = np.zeros((4, 4, 4), np.uint8)
    rgba[..., 0], rgba[..., 1], rgba[..., 2] = 255, 51, 0  # r = 1, g = 0.2, b = 0
    rgba[:, :2, 3], rgba[:, 2:, 3] = 0, 255  # alpha: left half 0, right half 1
    texture = rgba_texture(tmp_path / "maps.png", rgba)
    stage = Usd.Stage.CreateNew(str(tmp_path / "channels.usda"))
    material, _ = channel_material(
        stage, "/Looks/M", texture, {"metallic": "r", "roughness": "g", "opacity": "a"},
        scale=(Sdf.ValueTypeNames.Float4, (1.0, 0.5, 1.0, 1.0)),
        bias=(Sdf.ValueTypeNames.Float4, (0.0, 0.1, 0.0, 0.0)),
        sourceColorSpace=(Sdf.ValueTypeNames.Token, "raw"),
    )  # fmt: skip
    spec, diag = translated(material)
    assert not diag.messages

    def values(texture_dict):
        assert texture_dict["type"] == "bitmap" and texture_dict["raw"]
        return np.atleast_3d(np.array(texture_dict["bitmap"]))[..., 0]

    np.testing.assert_allclose(values(spec.bsdf["metallic"]), 1.0)
    np.testing.assert_allclose(values(spec.bsdf["roughness"]), 0.2 * 0.5 + 0.1, atol=1e-6)
    np.testing.assert_array_equal(values(spec.opacity)[:, :2], 0.0)
    np.testing.assert_array_equal(values(spec.opacity)[:, 2:], 1.0)
    # sourceColorSpace auto: an 8-bit RGBA file is sRGB-encoded (UsdUVTexture spec); alpha is not
    stage.GetPrimAtPath("/Looks/M/Maps").GetAttribute("inputs:sourceColorSpace").Set("auto")
    spec, _ = translated(UsdShade.Material(stage.GetPrimAtPath("/Looks/M")))
    decoded = ((0.2 + 0.055) / 1.055) ** 2.4  # sRGB EOTF of 51/255
    np.testing.assert_allclose(values(spec.bsdf["roughness"]), decoded * 0.5 + 0.1, atol=1e-4)
    np.testing.assert_array_equal(values(spec.opacity)[:, 2:], 1.0)


def test_opacity_threshold_and_unequal_wrap_modes(tmp_path):
    rgba = np.full((2, 2, 4), 255, np.uint8)
    rgba[0, :, 3] = 102  # alpha 0.4 on the top row
    texture = rgba_texture(tmp_path / "cut.png", rgba)
    stage = Usd.Stage.CreateNew(str(tmp_path / "cut.usda"))
    material, shader = channel_material(
        stage, "/Looks/Cut", texture, {"opacity": "a"},
        wrapS=(Sdf.ValueTypeNames.Token, "clamp"), wrapT=(Sdf.ValueTypeNames.Token, "repeat"),
    )  # fmt: skip
    shader.CreateInput("opacityThreshold", Sdf.ValueTypeNames.Float).Set(0.5)
    spec, diag = translated(material)
    assert spec.opacity_mode == "presence"  # a threshold makes a cut-out whatever the mode
    opacity = np.atleast_3d(np.array(spec.opacity["bitmap"]))[..., 0]
    np.testing.assert_array_equal(opacity, [[0.0, 0.0], [1.0, 1.0]])
    assert any(
        m.startswith("/Looks/Cut/Maps: wrapS 'clamp' / wrapT 'repeat'") for m in diag.messages
    )


def test_alpha_channel_cuts_the_quad_out(tmp_path):
    rgba = np.full((4, 4, 4), 255, np.uint8)
    rgba[:, :2, 3] = 0  # left half transparent
    texture = rgba_texture(tmp_path / "alpha.png", rgba)
    stage = base_stage(tmp_path / "alpha.usda")
    mesh = square(stage, "/Quad", -1, 1, -1, 1)
    material, _ = channel_material(stage, "/Looks/A", texture, {"opacity": "a"})
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(material)
    rgb = render(stage)
    # texels 0-1 (u < 0.5) are transparent; bilinear filtering blends over u 0.375-0.625
    left, right = rgb[12:20, 6:10].mean(), rgb[12:20, 22:26].mean()
    assert left < 0.02 and right > 0.3
