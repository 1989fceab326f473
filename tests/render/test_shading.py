"""Shading translators, each on a hand-written stage, measured in its render."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from pxr import Sdf, UsdGeom, UsdShade, UsdUtils
from render_helpers import (
    RES,
    bind,
    connect,
    halves,
    image,
    left_right,
    lum,
    new_stage,
    patch,
    preview,
    quad,
    render,
    set_input,
    sun,
    texture,
)

from pavonine.render.api import render_stage
from pavonine.render.diagnostics import StageWarning

pytestmark = pytest.mark.render
RED, BLUE = (0.8, 0.05, 0.05), (0.05, 0.05, 0.8)


def textured_quad(tmp_path, name, pixels, st_transform=None, **texture_inputs):
    """A sunlit quad whose diffuseColor reads an image (optionally through a UsdTransform2d)."""
    stage = new_stage(tmp_path / f"{name}.usda")
    sun(stage)
    mesh = quad(stage)
    material, shader = preview(stage, roughness=1.0)
    tex = texture(stage, "/Looks/M", image(tmp_path / f"{name}.exr", pixels), **texture_inputs)
    if st_transform is not None:
        reader = tex.GetInput("st").GetConnectedSource()[0]
        xform = UsdShade.Shader.Define(stage, "/Looks/M/Move")
        xform.CreateIdAttr("UsdTransform2d")
        for key, value in st_transform.items():
            set_input(xform, key, value)
        xform.CreateInput("in", Sdf.ValueTypeNames.Float2).ConnectToSource(reader, "result")
        tex.GetInput("st").ConnectToSource(xform.ConnectableAPI(), "result")
    connect(shader, "diffuseColor", tex, "rgb")
    bind(mesh, material)
    return stage


def test_transform2d_translation_and_rotation_move_the_texture(tmp_path):
    pixels = halves(RED, BLUE)
    plain = render(textured_quad(tmp_path, "plain", pixels, wrapS="repeat", wrapT="repeat"))
    left, right = left_right(plain.rgb)
    assert left[0] > 3 * left[2] and right[2] > 3 * right[0]
    shifted = textured_quad(
        tmp_path, "shift", pixels, {"translation": (0.5, 0.0)}, wrapS="repeat", wrapT="repeat"
    )
    left, right = left_right(render(shifted).rgb)
    assert left[2] > 3 * left[0] and right[0] > 3 * right[2]  # half a turn: the halves swap
    turned = textured_quad(
        tmp_path, "turn", pixels, {"rotation": 180.0}, wrapS="repeat", wrapT="repeat"
    )
    left, right = left_right(render(turned).rgb)
    assert left[2] > 3 * left[0] and right[0] > 3 * right[2]  # 180° about the origin


def test_wrap_black_and_scale_bias_and_fallback(tmp_path):
    stage = textured_quad(
        tmp_path, "black", halves(RED, RED), {"scale": (2.0, 1.0)}, wrapS="black", wrapT="black"
    )
    left, right = left_right(render(stage).rgb)
    assert lum(left) > 0.1 and lum(right) < 0.03  # u ∈ [1, 2] outside: black (+ specular)
    stage = textured_quad(
        tmp_path, "sb", halves(RED, RED), scale=(0.0, 0.0, 1.0, 1.0), bias=(0.0, 0.5, 0.0, 0.0)
    )
    left, _ = left_right(render(stage).rgb)
    assert left[1] > 5 * left[0]  # texel · (0, 0, 1) + (0, 0.5, 0): green, not red
    tex = stage.GetPrimAtPath("/Looks/M/Tex")
    tex.GetAttribute("inputs:file").Set(Sdf.AssetPath("missing.exr"))
    set_input(UsdShade.Shader(tex), "fallback", (0.0, 0.0, 0.9, 1.0))
    result = render(stage)
    left, _ = left_right(result.rgb)
    assert left[2] > 5 * left[0]
    assert any("missing.exr" in w and "not found" in w for w in result.warnings)


def test_texture_inside_usdz_package_is_read_through_the_resolver(tmp_path):
    stage = textured_quad(tmp_path, "pkg", halves(RED, BLUE))
    stage.GetPrimAtPath("/Looks/M/Tex").GetAttribute("inputs:file").Set(Sdf.AssetPath("pkg.exr"))
    stage.SetDefaultPrim(stage.GetPrimAtPath("/Quad"))
    stage.Save()
    package = tmp_path / "pkg.usdz"
    assert UsdUtils.CreateNewUsdzPackage(str(tmp_path / "pkg.usda"), str(package))
    (tmp_path / "pkg.exr").unlink()  # only the package holds the texture now
    import warnings

    from render_helpers import RES

    from pavonine.render.api import render_stage
    from pavonine.render.diagnostics import StageWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        result = render_stage(package, spp=16, resolution=RES, progress=False)
    left, right = left_right(result.rgb)
    assert left[0] > 3 * left[2] and right[2] > 3 * right[0]
    assert not any("not found" in w for w in result.warnings)


def test_udim_tiles_are_stitched(tmp_path):
    image(tmp_path / "tile.1001.exr", np.full((4, 4, 3), RED, np.float32))
    image(tmp_path / "tile.1002.exr", np.full((4, 4, 3), BLUE, np.float32))
    stage = textured_quad(tmp_path, "udim", halves(RED, RED))
    stage.GetPrimAtPath("/Looks/M/Tex").GetAttribute("inputs:file").Set(
        Sdf.AssetPath("tile.<UDIM>.exr")
    )
    st = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/Quad")).GetPrimvar("st")
    st.Set([(0, 0), (2, 0), (2, 1), (0, 1)])  # u from 0 to 2: tiles 1001 then 1002
    left, right = left_right(render(stage).rgb)
    assert left[0] > 3 * left[2] and right[2] > 3 * right[0]


def test_source_color_space_decodes_srgb(tmp_path):
    grey = np.full((4, 4, 3), 128, np.uint8)
    stage = textured_quad(tmp_path, "srgb", grey, sourceColorSpace="sRGB")
    stage.GetPrimAtPath("/Looks/M/Tex").GetAttribute("inputs:file").Set(
        image(tmp_path / "grey.png", grey)
    )
    decoded = lum(left_right(render(stage).rgb)[0])
    stage.GetPrimAtPath("/Looks/M/Tex").GetAttribute("inputs:sourceColorSpace").Set("raw")
    raw = lum(left_right(render(stage).rgb)[0])
    # 128/255 is 0.502 as data and 0.216 decoded (sRGB EOTF): the sun gives radiance = albedo
    assert raw == pytest.approx(0.502, rel=0.1) and decoded == pytest.approx(0.216, rel=0.1)


def test_normal_map_tilts_the_shading_towards_the_light(tmp_path):
    stage = new_stage(tmp_path / "normal.usda")
    sun(stage, tilt_deg=50.0)  # light arriving from +X
    mesh = quad(stage)
    material, shader = preview(stage, roughness=1.0, diffuseColor=(0.8, 0.8, 0.8))
    bind(mesh, material)
    flat = lum(patch(render(stage).rgb, slice(8, 24), slice(8, 24)))
    for nx, brighter in ((0.6, True), (-0.6, False)):
        n = np.array([nx, 0.0, 0.8])  # tangent space: +X along +u, the light's side
        pixels = np.full((4, 4, 3), (n + 1) / 2, np.float32)  # stored in [0, 1]
        tex = texture(stage, "/Looks/M", image(tmp_path / f"n{nx}.exr", pixels), name="N",
                      scale=(2.0, 2.0, 2.0, 1.0), bias=(-1.0, -1.0, -1.0, 0.0),
                      sourceColorSpace="raw")  # fmt: skip
        connect(shader, "normal", tex, "rgb", Sdf.ValueTypeNames.Normal3f)
        tilted = lum(patch(render(stage).rgb, slice(8, 24), slice(8, 24)))
        assert (tilted > flat) == brighter
        if brighter:  # Lambert: cos of the angle to the light, 50° flat, 50° − 36.9° tilted
            expected = np.cos(np.radians(50.0 - 36.87)) / np.cos(np.radians(50.0))
            assert tilted / flat == pytest.approx(expected, rel=0.12)
        else:  # 86.9° from the light: nearly dark
            assert tilted < 0.3 * flat


def test_emissive_material_glows_without_lights(tmp_path):
    stage = new_stage(tmp_path / "glow.usda")
    mesh = quad(stage, size=0.5)
    material, _ = preview(stage, diffuseColor=(0.0, 0.0, 0.0), emissiveColor=(2.0, 0.5, 0.25))
    bind(mesh, material)
    result = render(stage)
    centre = patch(result.rgb, slice(12, 20), slice(12, 20))
    assert centre == pytest.approx([2.0, 0.5, 0.25], rel=0.08)  # seen directly: its radiance
    assert result.rgb[0, 0].max() < 1e-6  # no default sun or sky was added


def test_textured_emission_above_one(tmp_path):
    stage = new_stage(tmp_path / "glowtex.usda")
    mesh = quad(stage)
    material, shader = preview(stage, diffuseColor=(0.0, 0.0, 0.0))
    tex = texture(stage, "/Looks/M", image(tmp_path / "e.exr", halves((4.0, 0, 0), (0, 0, 2.0))))
    connect(shader, "emissiveColor", tex, "rgb")
    bind(mesh, material)
    left, right = left_right(render(stage).rgb)
    assert left[0] == pytest.approx(4.0, rel=0.1) and right[2] == pytest.approx(2.0, rel=0.1)


def test_specular_workflow_and_clearcoat_change_the_highlight(tmp_path):
    stage = new_stage(tmp_path / "spec.usda")
    sun(stage, illuminance=20.0, tilt_deg=3.0)  # mirror direction close to the camera
    mesh = quad(stage, size=2.0)
    material, shader = preview(
        stage, diffuseColor=(0.05, 0.05, 0.05), roughness=0.2, useSpecularWorkflow=1
    )
    bind(mesh, material)
    middle = (slice(8, 24), slice(8, 24))
    black = lum(patch(render(stage).rgb, *middle))
    set_input(shader, "specularColor", (1.0, 1.0, 1.0))
    white = lum(patch(render(stage).rgb, *middle))
    assert white > 5 * black  # F0 = 1 vs F0 = 0
    set_input(shader, "specularColor", (0.0, 0.0, 0.0))
    set_input(shader, "clearcoat", 1.0)
    coated = lum(patch(render(stage).rgb, *middle))
    assert coated > 2 * black


def test_double_sided_mesh_with_opacity_is_seen_through_from_behind(tmp_path):
    stage = new_stage(tmp_path / "ds.usda")
    sun(stage)
    back = quad(stage, "/Back", size=1.0, z=-1.0)
    bind(back, preview(stage, "/Looks/Blue", diffuseColor=BLUE, roughness=1.0)[0])
    front = quad(stage, "/Front", size=1.0, double_sided=True)
    UsdGeom.Mesh(front).GetOrientationAttr().Set("leftHanded")  # its front faces away
    material, _ = preview(stage, "/Looks/Red", diffuseColor=RED, roughness=1.0, opacity=0.5,
                          opacityMode="presence")  # fmt: skip
    bind(front, material)
    result = render(stage)
    assert not any("rejected" in w for w in result.warnings)
    centre = patch(result.rgb, slice(12, 20), slice(12, 20))
    assert centre[0] > 0.15 and centre[2] > 0.15  # half red (its back, lit), half blue behind


def test_transparent_opacity_keeps_the_specular_reflection(tmp_path):
    stage = new_stage(tmp_path / "glass.usda")
    sun(stage, illuminance=20.0, tilt_deg=3.0).CreateAngleAttr(2.0)  # a disc: its mirror image
    mesh = quad(stage, size=2.0)
    material, shader = preview(stage, diffuseColor=(0.8, 0.8, 0.8), roughness=0.05, opacity=0.0)
    bind(mesh, material)
    middle = (slice(8, 24), slice(8, 24))
    transparent = render(stage, spp=32).rgb
    set_input(shader, "opacityMode", "presence")
    presence = render(stage, spp=32).rgb
    assert lum(patch(presence, *middle)) < 1e-3  # fully absent
    assert transparent.max() > 0.5  # the sun's reflection stays on a transparent surface


def test_primvar_reader_and_display_color_interpolations(tmp_path):
    stage = new_stage(tmp_path / "pv.usda")
    sun(stage)
    left = quad(stage, "/Left", size=0.45, x0=-0.95)
    right = quad(stage, "/Right", size=0.45, x0=0.05)
    colours = UsdGeom.PrimvarsAPI(left).CreatePrimvar(
        "displayColor", Sdf.ValueTypeNames.Color3fArray, UsdGeom.Tokens.vertex
    )
    colours.Set([RED, RED, BLUE, BLUE])  # red at the bottom, blue at the top
    UsdGeom.PrimvarsAPI(right).CreatePrimvar(
        "displayColor", Sdf.ValueTypeNames.Color3fArray, UsdGeom.Tokens.uniform
    ).Set([BLUE])
    rgb = render(stage).rgb
    bottom, top = patch(rgb, slice(19, 22), slice(6, 12)), patch(rgb, slice(10, 13), slice(6, 12))
    assert bottom[0] > 2 * bottom[2] and top[2] > 2 * top[0]  # no material: vertex displayColor
    assert patch(rgb, slice(12, 20), slice(20, 26))[2] > 0.3  # uniform displayColor
    # the same primvar through a UsdPrimvarReader_float3 into a UsdPreviewSurface
    material, shader = preview(stage, roughness=1.0)
    reader = UsdShade.Shader.Define(stage, "/Looks/M/Colour")
    reader.CreateIdAttr("UsdPrimvarReader_float3")
    reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("displayColor")
    connect(shader, "diffuseColor", reader, "result")
    bind(left, material)
    bind(right, material)
    result = render(stage)
    top = patch(result.rgb, slice(10, 13), slice(6, 12))
    assert top[2] > 2 * top[0] and patch(result.rgb, slice(12, 20), slice(20, 26))[2] > 0.3


def test_node_graph_interface_inputs_feed_the_surface(tmp_path):
    stage = new_stage(tmp_path / "graph.usda")
    sun(stage)
    mesh = quad(stage)
    material = UsdShade.Material.Define(stage, "/Looks/G")
    tint = material.CreateInput("tint", Sdf.ValueTypeNames.Color3f)
    tint.Set(RED)
    outer = UsdShade.NodeGraph.Define(stage, "/Looks/G/Outer")
    inner = UsdShade.NodeGraph.Define(stage, "/Looks/G/Outer/Inner")
    shader = UsdShade.Shader.Define(stage, "/Looks/G/Outer/Inner/Surface")
    shader.CreateIdAttr("UsdPreviewSurface")
    shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(1.0)
    inner_in = inner.CreateInput("colour", Sdf.ValueTypeNames.Color3f)
    outer_in = outer.CreateInput("colour", Sdf.ValueTypeNames.Color3f)
    shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).ConnectToSource(inner_in)
    inner_in.ConnectToSource(outer_in)
    outer_in.ConnectToSource(tint)
    inner.CreateOutput("surface", Sdf.ValueTypeNames.Token).ConnectToSource(
        shader.ConnectableAPI(), "surface"
    )
    outer.CreateOutput("surface", Sdf.ValueTypeNames.Token).ConnectToSource(
        inner.ConnectableAPI(), "surface"
    )
    material.CreateSurfaceOutput().ConnectToSource(outer.ConnectableAPI(), "surface")
    bind(mesh, material)
    centre = patch(render(stage).rgb, slice(12, 20), slice(12, 20))
    assert centre[0] > 5 * centre[2]  # the material's interface value, through two graphs
    tint.Set(BLUE)
    centre = patch(render(stage).rgb, slice(12, 20), slice(12, 20))
    assert centre[2] > 5 * centre[0]


def test_mitsuba_render_context_wins_over_the_preview_surface(tmp_path):
    stage = new_stage(tmp_path / "ctx.usda")
    sun(stage)
    mesh = quad(stage)
    material, _ = preview(stage, diffuseColor=RED, roughness=1.0)
    node = UsdShade.Shader.Define(stage, "/Looks/M/Mitsuba")
    node.CreateIdAttr("mitsuba_diffuse")
    node.CreateInput("reflectance", Sdf.ValueTypeNames.Color3f).Set(BLUE)
    material.CreateSurfaceOutput("mitsuba").ConnectToSource(node.ConnectableAPI(), "surface")
    bind(mesh, material)
    result = render(stage)
    centre = patch(result.rgb, slice(12, 20), slice(12, 20))
    assert centre[2] > 5 * centre[0]
    assert centre[2] == pytest.approx(BLUE[2], rel=0.1)  # Lambertian under E = π: its albedo


def test_displacement_and_occlusion_are_warned(tmp_path):
    stage = new_stage(tmp_path / "disp.usda")
    sun(stage)
    mesh = quad(stage)
    material, _ = preview(stage, displacement=0.2, occlusion=0.5)
    bind(mesh, material)
    messages = render(stage, spp=1, resolution=(8, 8)).warnings
    assert any("displacement is not applied" in w for w in messages)
    assert any("occlusion is ignored" in w for w in messages)


def test_wrongly_typed_inputs_are_warned_by_name_and_the_render_goes_on():
    stage_path = Path(__file__).parents[1] / "data" / "render" / "wrong_types.usda"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        result = render_stage(stage_path, spp=2, resolution=RES, progress=False)
    assert np.isfinite(result.rgb).all()
    for expected in (
        "/Mat/S: input 'diffuseColor' = 'blue' is not a color value",
        "/Mat/S: input 'roughness' = 'rough' is not a float value",
        "/Mat/S: input 'normal' = ",
        "/Mat/S: input 'opacityThreshold' = 'x' is not a float value",
        "/L: inputs:intensity = nan is not a finite number",
        "/L: inputs:color = 'red' is not a colour",
        "/L: inputs:shaping:cone:angle = 'wide' is not a finite number",
    ):
        assert any(w.startswith(expected) for w in result.warnings), expected


def test_mitsuba_bitmap_reads_files_mitsuba_cannot_through_openimageio(tmp_path):
    """Mitsuba has no TIFF (nor CMYK JPEG) reader; the file is read with OpenImageIO instead."""
    stage = new_stage(tmp_path / "tiff.usda")
    sun(stage)
    mesh = quad(stage)
    material = UsdShade.Material.Define(stage, "/Looks/T")
    diffuse = UsdShade.Shader.Define(stage, "/Looks/T/Diffuse")
    diffuse.CreateIdAttr("mitsuba_diffuse")
    bitmap = UsdShade.Shader.Define(stage, "/Looks/T/Bitmap")
    bitmap.CreateIdAttr("mitsuba_bitmap")
    tiff = image(tmp_path / "halves.tif", halves(RED, BLUE))
    bitmap.CreateInput("filename", Sdf.ValueTypeNames.Asset).Set(tiff)
    diffuse.CreateInput("reflectance", Sdf.ValueTypeNames.Color3f).ConnectToSource(
        bitmap.ConnectableAPI(), "out"
    )
    material.CreateSurfaceOutput("mitsuba").ConnectToSource(diffuse.ConnectableAPI(), "surface")
    bind(mesh, material)
    result = render(stage)
    assert result.warnings == []
    left, right = left_right(result.rgb)
    assert left[0] > 3 * left[2] and right[2] > 3 * right[0]
