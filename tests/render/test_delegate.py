"""Stage translation (no rendering): meshes, subsets, primvars, instancing, settings, bad data."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade

from pavonine.base.backend import select_variant
from pavonine.base.errors import InputError
from pavonine.render.delegate import StageDelegate, open_stage, render_time
from pavonine.render.diagnostics import Diagnostics, StageWarning
from pavonine.render.settings import read_render_settings


@pytest.fixture(scope="module", autouse=True)
def _variant():
    select_variant()


def quad(stage, path, size=1.0, z=0.0):
    mesh = UsdGeom.Mesh.Define(stage, path)
    s = size
    mesh.CreatePointsAttr([(-s, -s, z), (s, -s, z), (s, s, z), (-s, s, z)])
    mesh.CreateFaceVertexCountsAttr([4])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    mesh.CreateSubdivisionSchemeAttr("none")
    return mesh


def sync(stage):
    diag = Diagnostics()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        scene = StageDelegate(stage, render_time(stage, None), diag).sync()
    return scene, diag


def mesh_params(shape):
    import mitsuba as mi

    params = mi.traverse(shape)
    return {k: np.array(params[k]) for k in params.keys() if k.startswith(("vertex_", "faces"))}


def test_quad_triangulates_and_bakes_world_transform():
    stage = Usd.Stage.CreateInMemory()
    xf = UsdGeom.Xform.Define(stage, "/World")
    xf.AddTranslateOp().Set(Gf.Vec3d(10, 0, 0))
    quad(stage, "/World/Quad")
    scene, diag = sync(stage)
    assert diag.messages == []
    (shape,) = scene.shapes.values()
    p = mesh_params(shape)
    assert p["faces"].size == 6
    positions = p["vertex_positions"].reshape(-1, 3)
    assert np.allclose(positions[:, 0].min(), 9.0) and np.allclose(positions[:, 0].max(), 11.0)
    assert np.allclose(scene.bounds[0], [9, -1, 0]) and np.allclose(scene.bounds[1], [11, 1, 0])


def test_time_sampled_xform_follows_time_code():
    stage = Usd.Stage.CreateInMemory()
    xf = UsdGeom.Xform.Define(stage, "/World")
    op = xf.AddTranslateOp()
    op.Set(Gf.Vec3d(0, 0, 0), 1.0)
    op.Set(Gf.Vec3d(4, 0, 0), 2.0)
    quad(stage, "/World/Quad")
    centres = []
    for t in (1.0, 1.5, 2.0):
        scene = StageDelegate(stage, Usd.TimeCode(t), Diagnostics()).sync()
        centres.append((scene.bounds[0][0] + scene.bounds[1][0]) / 2)
    assert centres == pytest.approx([0.0, 2.0, 4.0])


def test_face_varying_uvs_unweld_and_flip_v():
    stage = Usd.Stage.CreateInMemory()
    mesh = quad(stage, "/Quad")
    st = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar(
        "st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying
    )
    st.Set([(0, 0), (1, 0), (1, 1), (0, 1)])
    scene, _ = sync(stage)
    p = mesh_params(next(iter(scene.shapes.values())))
    uv = p["vertex_texcoords"].reshape(-1, 2)
    pos = p["vertex_positions"].reshape(-1, 3)
    # the corner at (-1, 1) (top left) has st (0, 1) → Mitsuba uv (0, 0)
    top_left = np.argmin(pos[:, 0] - pos[:, 1])
    assert np.allclose(uv[top_left], [0.0, 0.0])


def test_geom_subsets_split_by_material():
    stage = Usd.Stage.CreateInMemory()
    mesh = UsdGeom.Mesh.Define(stage, "/Mesh")
    mesh.CreatePointsAttr([(0, 0, 0), (1, 0, 0), (2, 0, 0), (0, 1, 0), (1, 1, 0), (2, 1, 0)])
    mesh.CreateFaceVertexCountsAttr([4, 4])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 4, 3, 1, 2, 5, 4])
    red = UsdShade.Material.Define(stage, "/Looks/Red")
    subset = UsdGeom.Subset.CreateGeomSubset(mesh, "left", UsdGeom.Tokens.face, [0], "materialBind")
    UsdShade.MaterialBindingAPI.Apply(subset.GetPrim()).Bind(red)
    scene, diag = sync(stage)
    assert len(scene.shapes) == 2
    assert any("no surface shader" in m for m in diag.messages)


def test_nan_points_drop_faces_with_a_warning_naming_the_prim():
    stage = Usd.Stage.CreateInMemory()
    mesh = UsdGeom.Mesh.Define(stage, "/Broken")
    mesh.CreatePointsAttr([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (float("nan"), 2, 0)])
    mesh.CreateFaceVertexCountsAttr([3, 3, 3])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 0, 2, 3, 2, 3, 4])
    mesh.CreateSubdivisionSchemeAttr("none")
    with pytest.warns(StageWarning, match="/Broken: 1 of 5 points are NaN"):
        scene = StageDelegate(stage, Usd.TimeCode.Default(), Diagnostics()).sync()
    assert mesh_params(next(iter(scene.shapes.values())))["faces"].size == 6


def test_empty_mesh_is_skipped_with_a_warning():
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.Mesh.Define(stage, "/Empty")
    with pytest.warns(StageWarning, match="/Empty: empty mesh"):
        scene = StageDelegate(stage, Usd.TimeCode.Default(), Diagnostics()).sync()
    assert scene.shapes == {} and scene.bounds is None


def test_unsupported_prim_warns_once():
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.NurbsPatch.Define(stage, "/Box")
    diag = Diagnostics()
    with pytest.warns(StageWarning, match="/Box: NurbsPatch prims are not supported"):
        StageDelegate(stage, Usd.TimeCode.Default(), diag).sync()
    assert len(diag.messages) == 1


def test_point_instancer_shares_one_prototype():
    stage = Usd.Stage.CreateInMemory()
    instancer = UsdGeom.PointInstancer.Define(stage, "/Tail")
    quad(stage, "/Tail/Protos/Feather")
    instancer.CreatePrototypesRel().SetTargets(["/Tail/Protos/Feather"])
    instancer.CreateProtoIndicesAttr([0] * 50)
    instancer.CreatePositionsAttr([(3.0 * i, 0, 0) for i in range(50)])
    scene, _ = sync(stage)
    groups = [v for v in scene.shapes.values() if isinstance(v, dict) and v["type"] == "shapegroup"]
    assert len(groups) == 1 and scene.mesh_count == 1 and scene.instance_count == 50
    assert scene.bounds[1][0] == pytest.approx(3.0 * 49 + 1.0)


def test_native_instances_share_one_prototype(tmp_path):
    asset = Usd.Stage.CreateNew(str(tmp_path / "asset.usda"))
    quad(asset, "/Feather/Geo")
    asset.SetDefaultPrim(asset.GetPrimAtPath("/Feather"))
    asset.Save()
    stage = Usd.Stage.CreateInMemory()
    for i in range(4):
        prim = stage.DefinePrim(f"/F{i}", "Xform")
        prim.GetReferences().AddReference(str(tmp_path / "asset.usda"))
        prim.SetInstanceable(True)
        UsdGeom.Xformable(prim).AddTranslateOp().Set(Gf.Vec3d(0, 5.0 * i, 0))
    scene, _ = sync(stage)
    assert scene.mesh_count == 1 and scene.instance_count == 4
    assert scene.bounds[1][1] == pytest.approx(16.0)


def test_feather_material_uses_feather_uv_and_barb_tangent():
    stage = Usd.Stage.CreateInMemory()
    mesh = quad(stage, "/Feather")
    pv = UsdGeom.PrimvarsAPI(mesh)
    pv.CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, "vertex").Set([(0, 0)] * 4)
    pv.CreatePrimvar("pavonine:featherUV", Sdf.ValueTypeNames.Float2Array, "vertex").Set(
        [(0, 0), (1, 0), (1, 1), (0, 1)]
    )
    pv.CreatePrimvar("pavonine:barbTangent", Sdf.ValueTypeNames.Vector3fArray, "vertex").Set(
        [(0, 1, 0)] * 4
    )
    material = UsdShade.Material.Define(stage, "/Looks/Feather")
    material.GetPrim().AddAppliedSchema("PavonineFeatherAPI")
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(material)
    scene, _ = sync(stage)
    shape = next(iter(scene.shapes.values()))
    uv = mesh_params(shape)["vertex_texcoords"].reshape(-1, 2)
    assert np.ptp(uv[:, 0]) == pytest.approx(1.0)  # featherUV, not the constant st
    assert shape.has_attribute("vertex_barb_tangent")
    assert scene.feather_materials == 1


def test_broken_layer_is_one_line_input_error(tmp_path):
    bad = tmp_path / "broken.usda"
    bad.write_text('#usda 1.0\ndef Mesh "M" {\n  point3f[] points = [(0, 0\n}\n')
    with pytest.raises(InputError) as info:
        open_stage(bad, Diagnostics())
    assert str(bad) in str(info.value) and "\n" not in str(info.value)
    with pytest.raises(InputError, match="no such file"):
        open_stage(tmp_path / "missing.usda", Diagnostics())


def test_render_settings_and_product_override():
    stage = Usd.Stage.CreateInMemory()
    from pxr import UsdRender

    settings = UsdRender.Settings.Define(stage, "/Render/Settings")
    settings.CreateResolutionAttr(Gf.Vec2i(64, 32))
    product = UsdRender.Product.Define(stage, "/Render/Product")
    product.CreateResolutionAttr(Gf.Vec2i(48, 24))
    product.CreatePixelAspectRatioAttr(2.0)
    product.CreateCameraRel().SetTargets(["/Cam"])
    settings.CreateProductsRel().SetTargets(["/Render/Product"])
    spec = read_render_settings(stage, Diagnostics())
    assert spec.resolution == (48, 24) and spec.pixel_aspect == 2.0 and spec.camera == "/Cam"


def test_scene_ids_are_unique_and_prefixed_by_kind():
    from pavonine.render.scene_ids import scene_objects

    shapes = {"/a/b#0": "ab", "/a__b#0": "a__b", "shapegroup_0": "group", "instance_0": "inst"}
    emitters = {"/shapegroup_0": "light at /shapegroup_0", "/a/b#0": "light", "default_sky": "sky"}
    objects = scene_objects(shapes, emitters)
    assert sorted(objects.values()) == sorted([*shapes.values(), *emitters.values()])
    assert objects["shapegroup_0"] == "group" and objects["default_sky"] == "sky"
    assert {k for k, v in objects.items() if v in ("ab", "a__b")} == {
        "mesh_a__b_0",
        "mesh_a__b_0_1",
    }
    assert all("." not in k and "/" not in k for k in objects)


def test_prims_whose_ids_used_to_collide_all_render():
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.Xform.Define(stage, "/a")
    quad(stage, "/a/b", z=0.0)
    quad(stage, "/a__b", z=1.0)
    scene, _ = sync(stage)
    from pavonine.render.scene_ids import scene_objects

    assert len(scene_objects(scene.shapes, scene.emitters)) == 2


def test_first_line_is_the_first_informative_line():
    from pavonine.render.diagnostics import first_line

    assert first_line(ValueError("Error in 'Open'\nthe real reason\nmore")) == "the real reason"
    assert first_line(RuntimeError("[parser.cpp:444] bad node\n  - detail")) == "bad node"
    assert first_line(RuntimeError("")) == "RuntimeError"


def test_one_zero_normal_keeps_the_others_with_a_warning():
    stage = Usd.Stage.CreateInMemory()
    mesh = quad(stage, "/Bent")
    normals = [(0.6, 0, 0.8), (0, 0, 1), (0, 0, 0), (0, 0.6, 0.8)]
    mesh.CreateNormalsAttr(normals)
    mesh.SetNormalsInterpolation("vertex")
    scene, diag = sync(stage)
    n = mesh_params(next(iter(scene.shapes.values())))["vertex_normals"].reshape(-1, 3)
    p = mesh_params(next(iter(scene.shapes.values())))["vertex_positions"].reshape(-1, 3)
    for point, normal in zip(p, n, strict=True):
        i = [(-1, -1), (1, -1), (1, 1), (-1, 1)].index((round(point[0]), round(point[1])))
        expected = (0, 0, 1) if i == 2 else normals[i]  # the zero one: the face normal
        assert normal == pytest.approx(expected, abs=1e-6)
    assert any(m.startswith("/Bent: 1 of 4 normals are zero") for m in diag.messages)


def test_mesh_light_is_an_area_emitter_and_replaces_the_default_lights(tmp_path):
    from pxr import UsdLux

    from pavonine.render.api import render_stage

    stage = Usd.Stage.CreateNew(str(tmp_path / "glow.usda"))
    glow = quad(stage, "/Glow", size=0.4)
    UsdLux.MeshLightAPI.Apply(glow.GetPrim())
    light = UsdLux.LightAPI(glow.GetPrim())
    light.CreateIntensityAttr(2.0)
    light.CreateColorAttr(Gf.Vec3f(1.0, 0.2, 0.2))
    cam = UsdGeom.Camera.Define(stage, "/Cam")
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 0, 5))
    stage.Save()
    scene, diag = sync(stage)
    assert scene.mesh_lights == 1 and not diag.messages
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        result = render_stage(str(tmp_path / "glow.usda"), spp=2, resolution=(8, 8), progress=False)
    centre = result.rgb[3:5, 3:5].reshape(-1, 3).mean(axis=0)
    # seen directly: the emitted radiance L = intensity · colour (no sun, no sky added)
    assert centre == pytest.approx([2.0, 0.4, 0.4], rel=0.1)
    assert result.rgb[0, 0].max() < 1e-6
