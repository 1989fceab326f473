"""MaterialX surfaces (Standard Surface, OpenPBR) and image nodes, approximated by ``principled``."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from pxr import Sdf, UsdShade
from render_helpers import RES, bind, halves, image, left_right, lum, new_stage, patch, quad, sun
from render_helpers import render as render_quietly

pytestmark = pytest.mark.render
RED, BLUE = (0.8, 0.05, 0.05), (0.05, 0.05, 0.8)
MIDDLE = (slice(12, 20), slice(12, 20))


def mtlx_material(stage, node_id, path="/Looks/X", **inputs):
    """A material whose ``mtlx`` surface is the MaterialX node ``node_id`` holding ``inputs``."""
    material = UsdShade.Material.Define(stage, path)
    shader = UsdShade.Shader.Define(stage, f"{path}/Surface")
    shader.CreateIdAttr(node_id)
    for name, value in inputs.items():
        kind = Sdf.ValueTypeNames.Float
        if isinstance(value, tuple):
            kind = Sdf.ValueTypeNames.Color3f
        shader.CreateInput(name, kind).Set(value)
    material.CreateSurfaceOutput("mtlx").ConnectToSource(shader.ConnectableAPI(), "surface")
    return material, shader


def fed_by(stage, shader, name: str, node_id: str, kind) -> UsdShade.Shader:
    """A node ``node_id`` beside ``shader`` whose ``out`` feeds its input ``name``."""
    node = UsdShade.Shader.Define(stage, shader.GetPath().GetParentPath().AppendChild("Fed"))
    node.CreateIdAttr(node_id)
    shader.CreateInput(name, kind).ConnectToSource(node.ConnectableAPI(), "out")
    return node


def tiled_image(stage, parent, file, **inputs):
    node = UsdShade.Shader.Define(stage, f"{parent}/Image")
    node.CreateIdAttr("ND_tiledimage_color3")
    node.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(file)
    for name, value in inputs.items():
        node.CreateInput(name, Sdf.ValueTypeNames.Float2).Set(value)
    return node


def lit_quad(tmp_path, name):
    stage = new_stage(tmp_path / f"{name}.usda")
    sun(stage)
    return stage, quad(stage)


def test_standard_surface_reads_a_tiled_image_into_its_base_colour(tmp_path):
    stage, mesh = lit_quad(tmp_path, "tiled")
    material, shader = mtlx_material(
        stage, "ND_standard_surface_surfaceshader", specular_roughness=1.0, specular=0.0
    )
    node = tiled_image(stage, "/Looks/X", image(tmp_path / "halves.exr", halves(RED, BLUE)))
    shader.CreateInput("base_color", Sdf.ValueTypeNames.Color3f).ConnectToSource(
        node.ConnectableAPI(), "out"
    )
    bind(mesh, material)
    result = render_quietly(stage)
    assert result.warnings == []
    left, right = left_right(result.rgb)
    assert left[0] > 3 * left[2] and right[2] > 3 * right[0]
    node.CreateInput("uvtiling", Sdf.ValueTypeNames.Float2).Set((2.0, 1.0))  # twice across
    left, right = left_right(render_quietly(stage).rgb)
    assert left[2] > 3 * left[0] and right[0] > 3 * right[2]  # u 0.36 → 0.72, u 0.64 → 0.28


def test_standard_surface_coat_colour_tints_a_white_metal(tmp_path):
    stage, mesh = lit_quad(tmp_path, "brass")
    material, shader = mtlx_material(
        stage,
        "ND_standard_surface_surfaceshader",
        base_color=(1.0, 1.0, 1.0),
        metalness=1.0,
        specular_roughness=0.5,
        coat=1.0,
        coat_roughness=0.5,
        coat_color=(0.9, 0.6, 0.2),
    )
    bind(mesh, material)
    result = render_quietly(stage)
    tinted = patch(result.rgb, *MIDDLE)
    assert result.warnings == [] and tinted[0] > 2.5 * tinted[2]
    shader.GetInput("coat").Set(0.0)  # no coat: the white metal is grey
    plain = patch(render_quietly(stage).rgb, *MIDDLE)
    assert plain[0] == pytest.approx(plain[2], rel=0.1) and lum(plain) > lum(tinted)


def test_open_pbr_opacity_and_emission(tmp_path):
    stage, mesh = lit_quad(tmp_path, "openpbr")
    material, shader = mtlx_material(
        stage, "ND_open_pbr_surface_surfaceshader", base_color=(0.8, 0.8, 0.8)
    )
    bind(mesh, material)
    assert lum(patch(render_quietly(stage).rgb, *MIDDLE)) > 0.3
    shader.CreateInput("geometry_opacity", Sdf.ValueTypeNames.Float).Set(0.0)
    assert lum(patch(render_quietly(stage).rgb, *MIDDLE)) < 1e-3  # fully cut out
    dark = new_stage(tmp_path / "glow.usda")  # no lights: only the emission is seen
    glowing = quad(dark)
    material, _ = mtlx_material(
        dark,
        "ND_open_pbr_surface_surfaceshader",
        emission_luminance=2.0,
        emission_color=(1.0, 0.5, 0.25),
    )
    bind(glowing, material)
    glow = patch(render_quietly(dark).rgb, *MIDDLE)
    np.testing.assert_allclose(glow, [2.0, 1.0, 0.5], rtol=0.1)


def test_untranslated_materialx_inputs_are_warned_by_name(tmp_path):
    stage, mesh = lit_quad(tmp_path, "warned")
    material, _ = mtlx_material(
        stage,
        "ND_standard_surface_surfaceshader",
        subsurface=0.5,
        thin_film_thickness=300.0,
        coat_IOR=1.5,  # its default: not warned
        wobble=1.0,
    )
    bind(mesh, material)
    warnings = render_quietly(stage, resolution=RES).warnings
    surface = "/Looks/X/Surface"
    assert any(w.startswith(f"{surface}: subsurface is not translated") for w in warnings)
    assert any(w.startswith(f"{surface}: thin_film_thickness is not translated") for w in warnings)
    assert not any("coat_IOR" in w for w in warnings)
    assert (
        f"{surface}: input 'wobble' is not an input of ND_standard_surface_surfaceshader; ignored"
        in warnings
    )


def test_other_materialx_nodes_and_surfaces_are_warned(tmp_path):
    from pxr import Usd

    from pavonine.render.diagnostics import Diagnostics
    from pavonine.render.materials import translate_material

    stage = new_stage(tmp_path / "others.usda")
    gltf, _ = mtlx_material(stage, "ND_gltf_pbr_surfaceshader", "/Looks/Gltf")
    material, shader = mtlx_material(stage, "ND_standard_surface_surfaceshader")
    fed_by(stage, shader, "base_color", "ND_multiply_color3", Sdf.ValueTypeNames.Color3f)
    diag = Diagnostics()
    with pytest.warns(UserWarning):
        grey = translate_material(gltf, Usd.TimeCode.Default(), diag)
        spec = translate_material(material, Usd.TimeCode.Default(), diag)
    assert grey.key == "__default_grey"
    assert (
        "/Looks/Gltf: surface shader 'ND_gltf_pbr_surfaceshader' is not supported; "
        "rendering grey diffuse" in diag.messages
    )
    assert any(
        m.startswith("/Looks/X/Fed: shader 'ND_multiply_color3' feeding") for m in diag.messages
    )
    assert spec.bsdf["base_color"] == {"type": "rgb", "value": pytest.approx([0.8, 0.8, 0.8])}


def test_a_connected_normal_without_a_default_is_warned_not_dropped(tmp_path):
    """``normal`` has no default value (its nodedef reads the geometric normal): connected, it
    is named in a warning (MaterialX's brick and chess-set examples connect it)."""
    from pavonine.render.diagnostics import Diagnostics, StageWarning
    from pavonine.render.shading import translate_material

    stage = new_stage(tmp_path / "normal.usda")
    material, shader = mtlx_material(stage, "ND_standard_surface_surfaceshader")
    fed_by(stage, shader, "normal", "ND_normalmap_float", Sdf.ValueTypeNames.Float3)
    diag = Diagnostics()
    with pytest.warns(StageWarning, match="normal is not translated"):
        translate_material(material, stage.GetStartTimeCode(), diag)
    assert any("normal is not translated" in w for w in diag.messages), diag.messages


@pytest.mark.parametrize("order", [0, 1])
def test_place2d_matrix_follows_the_materialx_graph(tmp_path, order):
    """``ND_place2d_vector2`` against its node graph (stdlib_ng.mtlx) evaluated step by step."""
    from pavonine.render.diagnostics import Diagnostics
    from pavonine.render.shading.materialx import place2d
    from pavonine.render.shading.network import Network

    stage = new_stage(tmp_path / "place2d.usda")
    node = UsdShade.Shader.Define(stage, "/Place")
    node.CreateIdAttr("ND_place2d_vector2")
    values = {"pivot": (0.5, 0.25), "scale": (2.0, 0.5), "offset": (0.1, -0.3)}
    for name, value in values.items():
        node.CreateInput(name, Sdf.ValueTypeNames.Float2).Set(value)
    node.CreateInput("rotate", Sdf.ValueTypeNames.Float).Set(30.0)
    node.CreateInput("operationorder", Sdf.ValueTypeNames.Int).Set(order)
    matrix = place2d(node, Network("/M", stage.GetStartTimeCode(), Diagnostics()))

    def rotate2d(v, degrees):  # mx_rotate_vector2
        a = np.radians(degrees)
        return np.array([np.cos(a) * v[0] + np.sin(a) * v[1], -np.sin(a) * v[0] + np.cos(a) * v[1]])

    pivot, scale, offset = (np.array(values[k]) for k in ("pivot", "scale", "offset"))
    for t in (np.array([0.0, 0.0]), np.array([0.7, 0.9])):
        if order == 0:
            expected = rotate2d((t - pivot) / scale, 30.0) - offset + pivot
        else:
            expected = rotate2d(t - pivot - offset, 30.0) / scale + pivot
        assert (matrix @ [*t, 1.0])[:2] == pytest.approx(expected)


PLASTIC_MTLX = """<?xml version="1.0"?>
<materialx version="1.38" colorspace="lin_rec709" fileprefix="./textures/">
  <UsdPreviewSurface name="SR_blue" type="surfaceshader">
    <input name="diffuseColor" type="color3" value="0.05, 0.05, 0.8" />
    <input name="roughness" type="float" value="1.0" />
  </UsdPreviewSurface>
  <surfacematerial name="Blue" type="material">
    <input name="surfaceshader" type="surfaceshader" nodename="SR_blue" />
  </surfacematerial>
  <nodegraph name="NG">
    <image name="picture" type="color3">
      <input name="file" type="filename" value="./textures/halves.exr" />
    </image>
    <output name="out" type="color3" nodename="picture" />
  </nodegraph>
  <standard_surface name="SR_pictured" type="surfaceshader">
    <input name="base_color" type="color3" nodegraph="NG" output="out" />
  </standard_surface>
  <surfacematerial name="Pictured" type="material">
    <input name="surfaceshader" type="surfaceshader" nodename="SR_pictured" />
  </surfacematerial>
</materialx>
"""


def test_a_referenced_mtlx_document_is_read_as_usdmtlx_would(tmp_path):
    """usd-core cannot open ``references = @look.mtlx@</MaterialX>`` (no usdMtlx): the renderer
    translates the document itself into usdMtlx's ``/MaterialX/Materials/<name>``, so the quad is
    blue, not the fallback grey (usd-wg ``MaterialXTest/basic.usda``), and says how in the
    composition error's warning; its file names resolve as usdMtlx 22.08 read that suite
    (``fileprefix`` and a name that already holds it)."""
    from pavonine.render.delegate import open_stage
    from pavonine.render.diagnostics import Diagnostics, StageWarning
    from pavonine.render.shading.mtlx_documents import ROOT

    (tmp_path / "textures").mkdir()
    image(tmp_path / "textures" / "halves.exr", halves(RED, BLUE))
    (tmp_path / "look.mtlx").write_text(PLASTIC_MTLX)
    stage, mesh = lit_quad(tmp_path, "referenced")
    scope = stage.DefinePrim("/MaterialX", "Scope")
    scope.GetReferences().AddReference("./look.mtlx", "/MaterialX")
    material = UsdShade.Material(stage.GetPrimAtPath(f"{ROOT}/Blue"))
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).GetDirectBindingRel().SetTargets(
        [Sdf.Path(f"{ROOT}/Blue")]
    )
    stage.Save()
    assert not material  # usd-core alone composes nothing there
    result = render_quietly(stage)
    colour = patch(result.rgb, *MIDDLE)
    assert colour[2] > 4 * colour[0], colour
    (warning,) = [w for w in result.warnings if "composition error" in w]
    assert "look.mtlx" in warning and "read with the MaterialX package" in warning
    assert not [w for w in result.warnings if "not supported" in w or "not found" in w]

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        opened = open_stage(stage.GetRootLayer().realPath, Diagnostics())
    pictured = opened.GetPrimAtPath(f"{ROOT}/Pictured")
    assert pictured.IsA(UsdShade.Material)
    picture = opened.GetPrimAtPath(f"{ROOT}/Pictured/NG/picture")
    file = UsdShade.Shader(picture).GetInput("file").Get()
    assert picture and file.path == str(tmp_path / "textures" / "halves.exr")
    assert not opened.GetRootLayer().dirty and opened.GetSessionLayer().GetPrimAtPath("/MaterialX")
