"""Materials and instancing, seen in renders: preview surface colour, textures, subsets, instances."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade

from pavonine.render.api import render_stage
from pavonine.render.diagnostics import StageWarning

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
