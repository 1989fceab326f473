"""Small hand-written test stages for the shading, light and output translators."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdRender, UsdShade

from pavonine.render.api import RenderResult, render_stage
from pavonine.render.diagnostics import StageWarning

RES = (32, 32)
TYPES = {
    float: Sdf.ValueTypeNames.Float,
    int: Sdf.ValueTypeNames.Int,
    str: Sdf.ValueTypeNames.Token,
    bool: Sdf.ValueTypeNames.Bool,
}
COLOR_INPUTS = ("diffuseColor", "emissiveColor", "specularColor")


def new_stage(path: Path, up: str = "Y", camera_z: float = 5.0) -> Usd.Stage:
    """A stage with a camera on +Z (at ``camera_z``) looking down −Z."""
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, up)
    cam = UsdGeom.Camera.Define(stage, "/Cam")
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 0, camera_z))
    return stage


def quad(stage, path="/Quad", size=1.0, x0=None, st=True, double_sided=False, z=0.0):
    """A square facing +Z, st (0,0) at its bottom-left corner."""
    s = size
    left = -s if x0 is None else x0
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreatePointsAttr(
        [(left, -s, z), (left + 2 * s, -s, z), (left + 2 * s, s, z), (left, s, z)]
    )
    mesh.CreateFaceVertexCountsAttr([4])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    mesh.CreateSubdivisionSchemeAttr("none")
    mesh.CreateDoubleSidedAttr(double_sided)
    if st:
        UsdGeom.PrimvarsAPI(mesh).CreatePrimvar(
            "st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.vertex
        ).Set([(0, 0), (1, 0), (1, 1), (0, 1)])
    return mesh


def feather_sheet(
    stage, path, corners, uv="pavonine_featherUV", uv_type=Sdf.ValueTypeNames.TexCoord2fArray
) -> UsdGeom.Mesh:
    """A flat quad facing +Z over ``corners`` (counter-clockwise from its bottom left) whose
    feather coordinate ``uv`` runs from (0, 0) to (1, 1): u along its first edge."""
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreatePointsAttr(corners)
    mesh.CreateFaceVertexCountsAttr([4])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    mesh.CreateNormalsAttr([(0, 0, 1)] * 4)
    mesh.SetNormalsInterpolation("vertex")
    mesh.CreateSubdivisionSchemeAttr("none")
    UsdGeom.PrimvarsAPI(mesh).CreatePrimvar(uv, uv_type, "vertex").Set(
        [(0, 0), (1, 0), (1, 1), (0, 1)]
    )
    return mesh


def render_product(
    stage: Usd.Stage,
    var_types: dict[str, str | None],
    *,
    path: str = "/Render/Product",
    camera: str | None = None,
    resolution: tuple[int, int] | None = None,
) -> UsdRender.Product:
    """Author a RenderProduct at ``path`` whose ordered RenderVars are ``var_types``' names (each
    its own source name, with its data type unless ``None``), the one product of the stage's
    ``/Render/Settings``."""
    product = UsdRender.Product.Define(stage, path)
    if camera is not None:
        product.CreateCameraRel().SetTargets([camera])
    if resolution is not None:
        product.CreateResolutionAttr(Gf.Vec2i(*resolution))
    targets = []
    for name, data_type in var_types.items():
        var = UsdRender.Var.Define(stage, f"/Render/Vars/{name}")
        var.CreateSourceNameAttr(name)
        if data_type is not None:
            var.CreateDataTypeAttr(data_type)
        targets.append(var.GetPath())
    product.CreateOrderedVarsRel().SetTargets(targets)
    settings = UsdRender.Settings(stage.GetPrimAtPath("/Render/Settings"))
    settings.CreateProductsRel().SetTargets([product.GetPath()])
    return product


def set_input(shader: UsdShade.Shader, name: str, value) -> UsdShade.Input:
    if isinstance(value, (tuple, list)):
        kind = Sdf.ValueTypeNames.Color3f if name in COLOR_INPUTS else Sdf.ValueTypeNames.Float3
        if name == "normal":
            kind = Sdf.ValueTypeNames.Normal3f
        if len(value) == 2:
            kind = Sdf.ValueTypeNames.Float2
        if len(value) == 4:
            kind = Sdf.ValueTypeNames.Float4
    elif isinstance(value, Sdf.AssetPath):
        kind = Sdf.ValueTypeNames.Asset
    else:
        kind = TYPES[type(value)]
    shader_input = shader.CreateInput(name, kind)
    shader_input.Set(value)
    return shader_input


def preview(stage, path="/Looks/M", **inputs) -> tuple[UsdShade.Material, UsdShade.Shader]:
    """A material with a UsdPreviewSurface holding ``inputs``."""
    material = UsdShade.Material.Define(stage, path)
    shader = UsdShade.Shader.Define(stage, f"{path}/Surface")
    shader.CreateIdAttr("UsdPreviewSurface")
    for name, value in inputs.items():
        set_input(shader, name, value)
    material.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
    return material, shader


def texture(stage, parent: str, file: str, name="Tex", varname="st", **inputs) -> UsdShade.Shader:
    """A UsdUVTexture reading ``file`` at the primvar ``varname`` (through a primvar reader)."""
    tex = UsdShade.Shader.Define(stage, f"{parent}/{name}")
    tex.CreateIdAttr("UsdUVTexture")
    tex.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(file)
    for key, value in inputs.items():
        set_input(tex, key, value)
    if varname:
        reader = UsdShade.Shader.Define(stage, f"{parent}/{name}Reader")
        reader.CreateIdAttr("UsdPrimvarReader_float2")
        reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set(varname)
        tex.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(
            reader.ConnectableAPI(), "result"
        )
    return tex


def connect(shader: UsdShade.Shader, name: str, source: UsdShade.Shader, output: str, kind=None):
    kind = kind or (Sdf.ValueTypeNames.Color3f if output == "rgb" else Sdf.ValueTypeNames.Float)
    shader.CreateInput(name, kind).ConnectToSource(source.ConnectableAPI(), output)


def bind(prim_or_schema, material: UsdShade.Material) -> None:
    prim = prim_or_schema.GetPrim() if hasattr(prim_or_schema, "GetPrim") else prim_or_schema
    UsdShade.MaterialBindingAPI.Apply(prim).Bind(material)


def sun(stage, path="/Sun", illuminance=math.pi, tilt_deg=0.0) -> UsdLux.DistantLight:
    light = UsdLux.DistantLight.Define(stage, path)
    light.CreateIntensityAttr(illuminance)
    light.CreateAngleAttr(0.0)
    light.CreateNormalizeAttr(True)
    if tilt_deg:
        light.AddRotateYOp().Set(tilt_deg)
    return light


def image(path: Path, pixels: np.ndarray) -> str:
    """Write H×W×C ``pixels`` (uint8 → PNG, float → EXR) and return the path."""
    import OpenImageIO as oiio

    pixels = np.ascontiguousarray(pixels)
    fmt = oiio.UINT8 if pixels.dtype == np.uint8 else oiio.FLOAT
    spec = oiio.ImageSpec(pixels.shape[1], pixels.shape[0], pixels.shape[2], fmt)
    spec.attribute("oiio:UnassociatedAlpha", 1)
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), spec) and out.write_image(pixels)
    out.close()
    return str(path)


def halves(left, right, size=8, dtype=np.float32) -> np.ndarray:
    """A size×size RGB image: ``left`` colour on the left half, ``right`` on the right."""
    pixels = np.zeros((size, size, 3), dtype=dtype)
    pixels[:, : size // 2] = left
    pixels[:, size // 2 :] = right
    return pixels


def render(stage, spp=16, resolution=RES, **kwargs) -> RenderResult:
    """Save ``stage``'s layers and render it quietly (warnings are kept in the result). Not
    ``Usd.Stage.Save``: it writes every dirty layer the stage uses, a shipped one among them."""
    shipped = str(Path(__file__).resolve().parents[1] / "assets")
    for layer in stage.GetUsedLayers():
        if layer.dirty and not layer.anonymous and not layer.realPath.startswith(shipped):
            layer.Save()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        return render_stage(
            stage.GetRootLayer().realPath, spp=spp, resolution=resolution, progress=False, **kwargs
        )


def patch(rgb: np.ndarray, rows: slice, cols: slice) -> np.ndarray:
    """Mean colour of an image region."""
    return rgb[rows, cols].reshape(-1, rgb.shape[2]).mean(axis=0)


def left_right(rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean colours of the left and right thirds of the middle band of a 32×32 render."""
    return patch(rgb, slice(12, 20), slice(9, 14)), patch(rgb, slice(12, 20), slice(18, 23))


def lum(rgb) -> float:
    return float(np.dot(np.asarray(rgb)[:3], [0.2126, 0.7152, 0.0722]))
