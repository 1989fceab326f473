"""RenderProducts and RenderVars: every product rendered, AOVs as layers of a multi-layer EXR."""

from __future__ import annotations

import numpy as np
import OpenImageIO as oiio
import pytest
from click.testing import CliRunner
from pxr import Gf, Sdf, UsdGeom, UsdRender
from render_helpers import bind, new_stage, patch, preview, quad, render, sun

from pavonine.apps.cli import cli

pytestmark = pytest.mark.render
ALBEDO = (0.6, 0.3, 0.1)
VARS = {  # RenderVar name: (sourceName, dataType)
    "color": ("color", "color3f"),
    "albedo": ("albedo", "color3f"),
    "normal": ("N", "normal3f"),
    "depth": ("depth", "float"),
    "P": ("P", "point3f"),
    "primId": ("primId", "int"),
    "instanceId": ("instanceId", "int"),
}


def aov_stage(tmp_path, products=(("Main", (24, 24), tuple(VARS)),)):
    """A plane of known albedo 5 units in front of the camera, with render products."""
    stage = new_stage(tmp_path / "aovs.usda")
    sun(stage)
    mesh = quad(stage, size=0.5)
    bind(mesh, preview(stage, diffuseColor=ALBEDO, roughness=1.0)[0])
    far = UsdGeom.Camera.Define(stage, "/Far")
    far.AddTranslateOp().Set(Gf.Vec3d(0, 0, 10))
    settings = UsdRender.Settings.Define(stage, "/Render/Settings")
    for name, (source, data_type) in VARS.items():
        var = UsdRender.Var.Define(stage, f"/Render/Vars/{name}")
        var.CreateSourceNameAttr(source)
        var.CreateDataTypeAttr(data_type)
    targets = []
    for name, resolution, var_names in products:
        product = UsdRender.Product.Define(stage, f"/Render/{name}")
        product.CreateResolutionAttr(Gf.Vec2i(*resolution))
        product.CreateProductNameAttr(f"{name.lower()}.exr")
        product.CreateCameraRel().SetTargets(["/Far" if name == "Wide" else "/Cam"])
        product.CreateOrderedVarsRel().SetTargets([f"/Render/Vars/{v}" for v in var_names])
        targets.append(product.GetPath())
    settings.CreateProductsRel().SetTargets(targets)
    stage.GetRootLayer().pseudoRoot.SetInfo("renderSettingsPrimPath", "/Render/Settings")
    return stage


def test_render_vars_become_aov_layers_with_sensible_values(tmp_path):
    result = render(aov_stage(tmp_path), spp=64, resolution=None)
    channels = [c for layer in result.layers for c in layer.channels]
    assert channels == [
        "R", "G", "B", "albedo.R", "albedo.G", "albedo.B", "normal.X", "normal.Y", "normal.Z",
        "depth.Z", "P.X", "P.Y", "P.Z", "primId.id",
    ]  # fmt: skip
    assert any("/Render/Vars/instanceId" in w and "instanceId" in w for w in result.warnings)
    centre = (slice(9, 15), slice(9, 15))
    images = result.images
    assert patch(images["albedo"], *centre) == pytest.approx(ALBEDO, abs=0.06)
    assert patch(images["normal"], *centre) == pytest.approx([0, 0, 1], abs=1e-3)
    assert patch(images["depth"], *centre)[0] == pytest.approx(5.0, rel=0.01)
    assert np.abs(patch(images["P"], *centre)).max() < 0.1  # the plane's centre is the origin
    assert images["depth"][0, 0, 0] == 0.0  # nothing behind the plane's corner
    ids = images["primId"][..., 0]
    assert ids[12, 12] == ids[10, 14] and ids[0, 0] == 0.0  # one shape, an integer id
    assert patch(images["color"], *centre) == pytest.approx(ALBEDO, abs=0.06)  # E = π: L = albedo


def test_every_product_is_written_with_its_camera_resolution_and_channels(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # products without -o go to their productName, here
    stage = aov_stage(
        tmp_path,
        products=(("Main", (24, 24), ("color",)), ("Wide", (32, 16), ("albedo", "depth"))),
    )
    stage.Save()
    out = tmp_path / "out" / "beauty.exr"
    result = CliRunner().invoke(
        cli, ["render", str(tmp_path / "aovs.usda"), "-o", str(out), "--spp", "4", "--png", "-q"]
    )
    assert result.exit_code == 0, result.output
    wide = tmp_path / "out" / "beauty.Wide.exr"
    assert out.is_file() and wide.is_file() and (tmp_path / "out" / "beauty.png").is_file()
    assert not (tmp_path / "out" / "beauty.Wide.png").exists()  # no beauty layer: no PNG
    spec = oiio.ImageInput.open(str(wide)).spec()
    assert (spec.width, spec.height) == (32, 16)
    assert sorted(spec.channelnames) == ["albedo.B", "albedo.G", "albedo.R", "depth.Z"]
    assert spec.get_string_attribute("pavonine:camera") == "/Far"
    depth = oiio.ImageBuf(str(wide)).get_pixels(oiio.FLOAT)[..., spec.channelnames.index("depth.Z")]
    assert depth[8, 16] == pytest.approx(10.0, rel=0.02)  # the Far camera is 10 units away
    main = oiio.ImageInput.open(str(out)).spec()
    assert (main.width, main.height, main.channelnames) == (24, 24, ("R", "G", "B"))
    # --product renders just one, named by its productName without -o
    result = CliRunner().invoke(
        cli,
        ["render", str(tmp_path / "aovs.usda"), "--product", "/Render/Wide", "--spp", "2", "-q"],
        catch_exceptions=False,
    )
    assert result.exit_code == 0, result.output
    assert "wide.exr" in result.output and (tmp_path / "wide.exr").is_file()
    bad = CliRunner().invoke(cli, ["render", str(tmp_path / "aovs.usda"), "--product", "/Nope"])
    assert bad.exit_code == 2 and "error: --product: no RenderProduct at /Nope" in bad.output


def test_twin_products_through_one_camera_write_each_its_own_file(tmp_path):
    """hdmitsuba's ``render_settings/aovs_multiple_products.usda`` pattern: a beauty and an AOV
    product through the same camera at the same size. Mitsuba builds one sensor for two equal
    sensor dictionaries; both products must still render (issue 35: ``'sensor_1' is not in
    list``), each to its own file, each with the pixels it renders alone."""
    products = (("Color", (20, 14), ("color",)), ("Aovs", (20, 14), ("albedo", "normal", "depth")))
    stage = aov_stage(tmp_path, products=products)
    stage.Save()
    out = tmp_path / "out" / "twin.exr"
    result = CliRunner().invoke(
        cli, ["render", str(tmp_path / "aovs.usda"), "-o", str(out), "--spp", "4", "-q"]
    )
    assert result.exit_code == 0, result.output
    aovs = tmp_path / "out" / "twin.Aovs.exr"
    assert out.is_file() and aovs.is_file()
    spec = oiio.ImageInput.open(str(aovs)).spec()
    assert (spec.width, spec.height) == (20, 14)
    assert "depth.Z" in spec.channelnames and "normal.Z" in spec.channelnames
    both = oiio.ImageBuf(str(out)).get_pixels(oiio.FLOAT)
    alone = tmp_path / "alone.exr"
    result = CliRunner().invoke(
        cli,
        ["render", str(tmp_path / "aovs.usda"), "--product", "/Render/Color", "-o", str(alone),
         "--spp", "4", "-q"],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    assert np.array_equal(both, oiio.ImageBuf(str(alone)).get_pixels(oiio.FLOAT))
    depth = oiio.ImageBuf(str(aovs)).get_pixels(oiio.FLOAT)[..., spec.channelnames.index("depth.Z")]
    assert depth[7, 10] == pytest.approx(5.0, rel=0.02)


def test_unsupported_render_settings_are_warned(tmp_path):
    stage = aov_stage(tmp_path, products=(("Main", (8, 8), ("color",)),))
    settings = UsdRender.Settings(stage.GetPrimAtPath("/Render/Settings"))
    settings.CreateIncludedPurposesAttr(["default", "render", "proxy"])
    settings.CreateMaterialBindingPurposesAttr(["preview", ""])
    product = UsdRender.Product(stage.GetPrimAtPath("/Render/Main"))
    product.CreateDataWindowNDCAttr(Gf.Vec4f(0.25, 0.25, 0.75, 0.75))
    lpe = UsdRender.Var.Define(stage, "/Render/Vars/diffuse")
    lpe.CreateSourceNameAttr("C<RD>.*")
    lpe.CreateSourceTypeAttr("lpe")
    product.GetOrderedVarsRel().AddTarget("/Render/Vars/diffuse")
    stage.GetPrimAtPath("/Render/Settings").CreateAttribute(
        "mitsuba:variant", Sdf.ValueTypeNames.String
    ).Set("scalar_rgb")
    warnings = render(stage, spp=1, resolution=None).warnings
    for expected in (
        "/Render/Settings: includedPurposes",
        "/Render/Settings: materialBindingPurposes",
        "/Render/Main: dataWindowNDC",
        "/Render/Vars/diffuse: light path expression 'C<RD>.*' is not supported",
        "/Render/Settings: mitsuba:variant",
    ):
        assert any(w.startswith(expected) for w in warnings), expected
