"""USD hygiene of converted assets and shipped scenes: texCoord2f feather coordinates, bindings
through MaterialBindingAPI, the low LOD as the proxy, per-purpose extentsHint, defaultPrim and
kind on scenes — and that the render delegate renders what this means."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from pavonine.apps.cli import cli

REPO = Path(__file__).resolve().parents[2]
SCENES = sorted((REPO / "assets" / "scenes").glob("*.usda"))
SHIPPED = sorted((REPO / "assets" / "feathers").glob("*/*.usd"))


def open_stage(path):
    from pxr import Usd

    import pavonine  # noqa: F401  (registers the schema)

    return Usd.Stage.Open(str(path))


def test_feather_coordinate_is_a_texcoord2f_primvar(eye_asset):
    from pxr import Sdf, UsdGeom

    stage = open_stage(eye_asset)
    for scope in ("Geom", "Proxy"):
        for mesh in ("Vane", "Rachis"):
            prim = stage.GetPrimAtPath(f"/eye_feather/{scope}/{mesh}")
            primvar = UsdGeom.PrimvarsAPI(prim).GetPrimvar("pavonine_featherUV")
            assert primvar.GetTypeName() == Sdf.ValueTypeNames.TexCoord2fArray
            assert primvar.GetTypeName().role == "TextureCoordinate"
            assert primvar.GetInterpolation() == UsdGeom.Tokens.vertex


def test_bindings_go_through_material_binding_api(eye_asset):
    from pxr import UsdShade

    stage = open_stage(eye_asset)
    for scope in ("Geom", "Proxy"):
        for mesh, material in (("Vane", "Feather"), ("Rachis", "Rachis")):
            prim = stage.GetPrimAtPath(f"/eye_feather/{scope}/{mesh}")
            assert prim.HasAPI(UsdShade.MaterialBindingAPI)
            api = UsdShade.MaterialBindingAPI(prim)
            assert api.GetDirectBinding().GetMaterialPath().name == material
    # The geometry layers carry no bindings: the material layer binds (and the proxy reuses them).
    geo = (eye_asset.parent / "eye_feather_geo_high.usdc").as_posix()
    from pxr import Sdf

    layer = Sdf.Layer.FindOrOpen(geo)
    vane = layer.GetPrimAtPath("/eye_feather/Geom/Vane")
    assert "material:binding" not in vane.relationships


def test_low_lod_is_the_proxy_and_the_render_lod_is_render(eye_asset):
    from pxr import UsdGeom

    stage = open_stage(eye_asset)
    stage.SetEditTarget(stage.GetSessionLayer())  # the shared asset's files stay as converted
    geom = UsdGeom.Imageable(stage.GetPrimAtPath("/eye_feather/Geom"))
    proxy = UsdGeom.Imageable(stage.GetPrimAtPath("/eye_feather/Proxy"))
    assert geom.ComputePurpose() == UsdGeom.Tokens.render
    assert proxy.ComputePurpose() == UsdGeom.Tokens.proxy
    assert geom.ComputeProxyPrim()[0].GetPath() == proxy.GetPath()

    def faces(scope: str) -> int:
        mesh = UsdGeom.Mesh(stage.GetPrimAtPath(f"/eye_feather/{scope}/Vane"))
        return len(mesh.GetFaceVertexCountsAttr().Get())

    stage.GetDefaultPrim().GetVariantSet("lod").SetVariantSelection("low")
    low = faces("Geom")
    stage.GetDefaultPrim().GetVariantSet("lod").SetVariantSelection("high")
    assert faces("Proxy") == low < faces("Geom")


def test_extents_hint_holds_each_purposes_bounds(eye_asset):
    from pxr import Usd, UsdGeom

    stage = open_stage(eye_asset)
    model = UsdGeom.ModelAPI(stage.GetDefaultPrim())
    hint = np.asarray(model.GetExtentsHintAttr().Get(), dtype=np.float64)
    purposes = UsdGeom.Imageable.GetOrderedPurposeTokens()  # default, render, proxy, guide
    assert len(hint) == 6  # USD drops the trailing empty box (guide)
    for i, purpose in enumerate(purposes[:3]):
        cache = UsdGeom.BBoxCache(Usd.TimeCode.Default(), [purpose], useExtentsHint=False)
        box = cache.ComputeUntransformedBound(stage.GetDefaultPrim()).ComputeAlignedRange()
        if box.IsEmpty():
            assert np.all(hint[2 * i] > hint[2 * i + 1])  # an empty box for unused purposes
        else:
            assert np.allclose(hint[2 * i : 2 * i + 2], [box.GetMin(), box.GetMax()], atol=1e-4)
    assert (
        not UsdGeom.BBoxCache(Usd.TimeCode.Default(), ["render"])
        .ComputeWorldBound(stage.GetDefaultPrim())
        .GetRange()
        .IsEmpty()
    )


def test_render_delegate_skips_the_proxy(eye_asset):
    from pavonine.render.delegate import StageDelegate, render_time
    from pavonine.render.diagnostics import Diagnostics

    stage = open_stage(eye_asset)
    scene = StageDelegate(stage, render_time(stage, None), Diagnostics()).sync()
    assert scene.mesh_count == 2 and scene.feather_materials == 1
    assert all("/Proxy/" not in name for name in scene.shapes)


@pytest.mark.parametrize(
    ("name", "type_name"),
    [("pavonine_featherUV", "TexCoord2fArray"), ("pavonine:featherUV", "Float2Array")],
)
def test_delegate_reads_the_feather_coordinate_and_its_legacy_float2_name(name, type_name):
    from pxr import Sdf, Usd, UsdGeom, UsdShade

    from pavonine.render import materials

    stage = Usd.Stage.CreateInMemory()
    mesh = UsdGeom.Mesh.Define(stage, "/Quad")
    UsdGeom.PrimvarsAPI(mesh).CreatePrimvar(
        name, getattr(Sdf.ValueTypeNames, type_name), UsdGeom.Tokens.vertex
    ).Set([(0, 0), (1, 0), (1, 1), (0, 1)])
    material = UsdShade.Material.Define(stage, "/Feather")
    spec = materials.MaterialSpec("/Feather", {}, materials.FEATHER_UV, {}, is_feather=True)
    del material
    assert spec.primvars_for(mesh.GetPrim())[0] == name


@pytest.mark.parametrize("scene", SCENES, ids=lambda p: p.stem)
def test_shipped_scenes_are_assemblies_with_a_default_prim_and_validate_clean(scene):
    from pxr import Kind, Usd

    stage = open_stage(scene)
    default = stage.GetDefaultPrim()
    assert default and Usd.ModelAPI(default).GetKind() == Kind.Tokens.assembly
    assert Usd.ModelAPI(default).IsModel()
    result = CliRunner().invoke(cli, ["validate", str(scene)])
    assert result.exit_code == 0 and result.output == "1 file, no findings\n", result.output


@pytest.mark.parametrize("asset", SHIPPED, ids=lambda p: p.stem)
def test_shipped_feathers_are_converted_baked_and_clean(asset):
    from pxr import UsdShade

    stage = open_stage(asset)
    material = UsdShade.Material(stage.GetPrimAtPath(f"/{asset.stem}/Materials/Feather"))
    assert material.GetPrim().GetCustomDataByKey("pavonine:bake")["resolution"] > 0
    assert (asset.parent / f"{asset.stem}.mtlx").is_file()
    result = CliRunner().invoke(cli, ["validate", str(asset)])
    assert result.exit_code == 0 and result.output == "1 file, no findings\n", result.output
