"""Baking: the atlas texels, the model's colour per texel, the thin-film stand-in, the texture
files and ``pavonine bake`` — checked against the model evaluated independently (NumPy,
``FeatherModel.brdf``, 1 nm colour integration) and the thin-film closed form."""

from __future__ import annotations

import json
import math
import shutil

import numpy as np
import OpenImageIO as oiio
import pytest
from click.testing import CliRunner

from pavonine.apps.cli import cli
from pavonine.materials import colour, materialx
from pavonine.materials.optics import COLOUR_WAVELENGTHS_NM, model_for
from pavonine.materials.parameters import preset
from pavonine.pipeline.bake import appearance
from pavonine.pipeline.bake.texels import dilate, nearest_covered, scatter, surface_texels
from pavonine.pipeline.bake.textures import (
    FILES,
    IOR_RANGE,
    bake_textures,
    read_data_textures,
    write_textures,
)
from pavonine.pipeline.convert.mesh import MeshData
from pavonine.pipeline.convert.vane import grid_mesh


def flat_patch(n: int = 9, tilt_deg: float = 0.0) -> MeshData:
    """A 10 cm square in the XY plane facing +Z (optionally turned about X), feather coordinate
    = (x, y)/10 + ½, barbs along +Y, ``st`` = the feather coordinate scaled into the atlas."""
    uv, faces = grid_mesh(n, n)
    points = np.column_stack([(uv - 0.5) * 10.0, np.zeros(len(uv))])
    normal = np.array([0.0, 0.0, 1.0])
    barb = np.array([0.0, 1.0, 0.0])
    if tilt_deg:
        t = math.radians(tilt_deg)
        rot = np.array([[1, 0, 0], [0, math.cos(t), -math.sin(t)], [0, math.sin(t), math.cos(t)]])
        points, normal, barb = points @ rot.T, rot @ normal, rot @ barb
    st = 0.1 + 0.8 * uv
    return MeshData(
        "Vane",
        points,
        faces,
        np.tile(normal, (len(uv), 1)),
        uv,
        np.tile(barb, (len(uv), 1)),
        st,
        faces.ravel(),
    )


def uniform_maps(**values: float) -> dict[str, np.ndarray]:
    return {name: np.full((8, 8), value, np.float32) for name, value in values.items()}


def model_colour(params, wi, wo, klass=0, gradation=0.0) -> np.ndarray:
    """Linear Rec. 709 of π f under D65, integrated at 1 nm (independent of the bake's 10 nm)."""
    f = model_for(params).brdf(wi, wo, COLOUR_WAVELENGTHS_NM, klass, gradation)
    return colour.reflectance_to_linear_srgb(COLOUR_WAVELENGTHS_NM, math.pi * f)


def delta_e(a, b) -> float:
    return float(colour.delta_e2000(colour.linear_srgb_to_lab(a), colour.linear_srgb_to_lab(b)))


def test_texels_interpolate_the_mesh_and_cover_its_atlas():
    mesh = flat_patch(tilt_deg=30.0)
    texels = surface_texels(mesh, 64)
    # st spans [0.1, 0.9]² → (0.8·64)² texel centres, bar the diagonals' exact hits
    assert abs(len(texels.index) - (0.8 * 64) ** 2) < 3 * 64
    row, col = np.divmod(texels.index, 64)
    st = np.stack([(col + 0.5) / 64, 1.0 - (row + 0.5) / 64], axis=1)
    assert np.allclose(texels.feather_uv, (st - 0.1) / 0.8, atol=1e-9)
    assert np.allclose(texels.normal, mesh.normals[0]) and np.allclose(
        texels.barb, mesh.barb_tangent[0]
    )
    assert np.allclose(texels.across, [1.0, 0.0, 0.0])  # ∂P/∂u: the feather's +u is +X
    # the surface point: (feather coordinate − ½)·10 cm in the plane, turned 30° about X
    flat = np.column_stack([(texels.feather_uv - 0.5) * 10.0, np.zeros(len(texels.index))])
    t = math.radians(30.0)
    turn = np.array([[1, 0, 0], [0, math.cos(t), -math.sin(t)], [0, math.sin(t), math.cos(t)]])
    assert np.allclose(texels.position, flat @ turn.T, atol=1e-9)


def test_per_texel_views_give_each_texel_the_reflectance_at_its_own_view():
    """A viewer at a finite distance: ``reflectance_at_views`` given one view per texel agrees,
    texel by texel, with the same view given to every texel (the path the bake's reference view
    and the tests above take), melanin share and all."""
    params = preset("paper-table1")
    maps = uniform_maps(ocellar=1.0 - 2 / 5, gradation=0.5, angle=0.3, melanin=0.6, alpha=1.0)
    texels = surface_texels(flat_patch(), 8)
    rng = np.random.default_rng(11)
    views = rng.normal(size=(len(texels.index), 2, 3)) * [0.4, 0.4, 0.1] + [0.0, 0.0, 1.0]
    views[-1, 1] *= [1.0, 1.0, -1.0]  # one view from behind the vane: no melanin there
    views /= np.linalg.norm(views, axis=-1, keepdims=True)
    light = appearance.REFERENCE_LIGHT
    each, _ = appearance.reflectance_at_views(texels, maps, params, light, views)
    assert each.shape == (len(texels.index), 2, 3)
    for i in (0, len(views) // 2, len(views) - 1):
        shared, _ = appearance.reflectance_at_views(texels, maps, params, light, views[i])
        assert np.allclose(each[i], shared[i], rtol=1e-6, atol=1e-9)
    assert np.ptp(each[:, 0, 1]) > 1e-3  # the views differ, and so do the colours


def test_dilation_fills_every_texel_from_the_nearest_covered_one():
    texels = surface_texels(flat_patch(), 32)
    image = scatter(texels, texels.feather_uv[:, 0], fill=-1.0)
    filled = dilate(image, nearest_covered(texels.covered))
    assert np.all(filled >= 0.0)
    assert np.array_equal(filled[texels.covered], image[texels.covered])
    assert filled[0, 0] == image[texels.covered].reshape(-1)[0]  # top-left corner ← nearest


@pytest.mark.parametrize(("angle", "tilt"), [(0.0, 0.0), (0.19, 0.0), (0.5, 0.0), (0.81, 20.0)])
def test_base_colour_is_the_models_reflectance_factor_at_the_reference(angle, tilt):
    params = preset("paper-table1")
    mesh = flat_patch(tilt_deg=tilt)
    maps = uniform_maps(ocellar=1.0 - 2 / 5, gradation=0.5, angle=angle, melanin=1.0, alpha=1.0)
    texels = surface_texels(mesh, 16)
    look = appearance.texel_appearance(texels, maps, params, roughness=0.6)
    # Independent evaluation: barbule axis = +Y (barbs) turned angle·180° about the normal.
    n, b = mesh.normals[0], mesh.barb_tangent[0]
    x = math.cos(math.pi * angle) * b + math.sin(math.pi * angle) * np.cross(n, b)
    frame = np.stack([x, np.cross(n, x), n])
    expected = model_colour(
        params, frame @ appearance.REFERENCE_LIGHT, frame @ appearance.REFERENCE_VIEW, 2, 0.5
    )
    assert np.allclose(look.base_color, look.base_color[0])
    assert delta_e(look.base_color[0], np.clip(expected, 0, 1)) < 0.5


def test_jit_and_numpy_evaluations_agree():
    params = preset("paper-table1")
    rng = np.random.default_rng(3)
    n = 40
    k = rng.integers(0, 6, n)
    t = np.round(rng.random(n) * appearance.FALLBACK_STEPS) / appearance.FALLBACK_STEPS
    wi = rng.normal(size=(n, 3)) * [0.4, 0.4, 0.1] + [0.0, 0.0, 1.0]
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    wo = np.tile(appearance.REFERENCE_VIEW, (n, 1))
    jit = appearance._structure_jit(params, k, t, wi, wo)
    numpy = appearance._structure_numpy(params, k, t, wi, wo)
    scale = np.max(numpy.spectra, axis=1, keepdims=True) + 1e-3
    assert np.max(np.abs(jit.spectra - numpy.spectra) / scale) < 2e-3  # float32 vs float64
    for a, b in zip((*jit.long, *jit.short), (*numpy.long, *numpy.short), strict=True):
        assert np.allclose(a, b, rtol=1e-5)


def test_melanin_share_blends_toward_melanin_brown():
    params = preset("paper-table1")
    texels = surface_texels(flat_patch(), 8)

    def look(share: float):  # class 0, barbules at 45°: a colour inside the sRGB gamut
        maps = uniform_maps(melanin=share, angle=0.25)
        return appearance.texel_appearance(texels, maps, params, 0.6)

    brown, structural, half = look(0.0), look(1.0), look(0.5)
    assert np.all((structural.base_color > 0.01) & (structural.base_color < 0.99))
    assert delta_e(brown.base_color[0], params.melanin_color) < 1.0
    assert np.allclose(half.base_color, 0.5 * (brown.base_color + structural.base_color), atol=2e-3)
    assert np.allclose(brown.roughness, 1.0) and np.allclose(structural.roughness, 0.6)
    assert np.allclose(half.film_weight, 0.5)


@pytest.mark.parametrize("name", ["yellow", "blue"])
def test_thin_film_peaks_where_the_model_peaks(name):
    """The film of the baked thickness and index reflects most (its m = 1 order) at the
    wavelength where the model's structural spectrum peaks."""
    params = preset(name)
    texels = surface_texels(flat_patch(), 8)
    look = appearance.texel_appearance(texels, uniform_maps(angle=0.5), params, 0.6)
    found = appearance.structure(
        params,
        np.zeros(1, np.int64),
        np.zeros(1),
        appearance.barbule_frames(texels, np.full(len(texels.index), 0.5))[:1]
        @ appearance.REFERENCE_LIGHT,
        np.array([appearance.REFERENCE_VIEW]),
    )
    peak = appearance.WAVELENGTHS_NM[np.argmax(found.spectra[0])]
    visible = np.arange(380.0, 781.0, 1.0)
    film = materialx.thin_film_reflectance(
        visible, look.thickness_nm[0], look.film_ior[0], materialx.KERATIN_INDEX
    )
    assert visible[np.argmax(film)] == pytest.approx(peak, abs=8.0)
    stack = params.classes[0].long[0]
    n_eff = 1.0 + math.pi * stack.radius / (2 * stack.interval) * (params.melanin_index - 1.0)
    assert look.film_ior[0] == pytest.approx(n_eff, rel=2e-2)  # Eq. 1, both axes alike here


def test_texture_files_hold_the_documented_encodings(tmp_path):
    params = preset("paper-table1")
    mesh = flat_patch()
    maps = uniform_maps(ocellar=0.2, gradation=0.3, angle=0.2, melanin=0.8, alpha=0.6)
    baked = bake_textures(mesh, maps, params, roughness=0.6, resolution=32)
    paths = write_textures(tmp_path, baked)
    assert paths == {key: f"./textures/{name}" for key, name in FILES.items()}
    assert sorted(p.name for p in (tmp_path / "textures").iterdir()) == sorted(FILES.values())
    spec = oiio.ImageInput.open(str(tmp_path / "textures" / FILES["base_color"])).spec()
    assert (spec.nchannels, spec.format.basetype) == (4, oiio.UINT8)
    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)  # as stored: colour not premultiplied
    image = oiio.ImageInput.open(str(tmp_path / "textures" / FILES["base_color"]), config)
    pixels = image.read_image(oiio.FLOAT)
    image.close()
    encoded = colour.display_encode(baked.base_color[..., :3])
    assert np.max(np.abs(pixels[..., :3] - encoded)) <= 0.5 / 255 + 1e-6  # sRGB-encoded
    assert np.allclose(pixels[..., 3], 0.6, atol=1 / 255)  # alpha linear
    data = read_data_textures({k: str(tmp_path / p[2:]) for k, p in paths.items()})
    for key in ("roughness", "film_thickness", "film_ior", "film_weight"):
        assert np.allclose(data[key], getattr(baked, key), atol=1 / 65535)
    assert np.allclose(data["film_weight"], 0.8, atol=1e-4)
    index = IOR_RANGE[0] + (IOR_RANGE[1] - IOR_RANGE[0]) * data["film_ior"]
    assert np.all((index > 1.3) & (index < 2.0))
    assert np.all((data["film_thickness"] > 0.1) & (data["film_thickness"] < 0.5))  # µm


def test_converted_asset_preview_reads_the_baked_textures(eye_asset):
    from pxr import Usd, UsdShade

    stage = Usd.Stage.Open(str(eye_asset))
    material = UsdShade.Material(stage.GetPrimAtPath("/eye_feather/Materials/Feather"))
    preview = material.ComputeSurfaceSource()[0]
    assert preview.GetShaderId() == "UsdPreviewSurface"
    assert preview.GetInput("opacityThreshold").Get() == pytest.approx(0.5)
    colour_source = preview.GetInput("diffuseColor").GetConnectedSources()[0][0]
    texture = UsdShade.Shader(colour_source.source.GetPrim())
    assert texture.GetInput("file").Get().path == "./textures/basecolor.png"
    assert texture.GetInput("sourceColorSpace").Get() == "sRGB"
    assert preview.GetInput("opacity").GetConnectedSources()[0][0].sourceName == "a"
    reader = UsdShade.Shader(texture.GetInput("st").GetConnectedSources()[0][0].source.GetPrim())
    assert reader.GetShaderId() == "UsdPrimvarReader_float2"
    assert material.GetInput("frame:stPrimvarName").Get() == "st"
    for name in FILES.values():
        assert (eye_asset.parent / "textures" / name).is_file()


def test_pavonine_bake_rebakes_in_place(eye_asset, tmp_path):
    asset = tmp_path / "eye_feather"
    shutil.copytree(eye_asset.parent, asset)
    before = (asset / "textures" / "basecolor.png").read_bytes()
    result = CliRunner().invoke(cli, ["bake", str(asset), "--resolution", "64", "--json", "-"])
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["resolution"] == 64 and len(report["materials"]) == 1
    entry = report["materials"][0]
    assert entry["material"] == "/eye_feather/Materials/Feather"
    assert entry["meshes"] == ["/eye_feather/Geom/Vane"]  # the render LOD, not the proxy
    assert oiio.ImageInput.open(str(asset / "textures" / "basecolor.png")).spec().width == 64
    assert (asset / "textures" / "basecolor.png").read_bytes() != before
    assert sorted(p.name for p in asset.iterdir() if p.name.startswith(".")) == []  # no temp
    validate = CliRunner().invoke(cli, ["validate", str(asset / "eye_feather.usd")])
    assert validate.exit_code == 0 and validate.output == "1 file, no findings\n", validate.output


def test_changed_parameters_make_the_baked_textures_stale(eye_asset, tmp_path):
    from pxr import Usd

    asset = tmp_path / "eye_feather"
    shutil.copytree(eye_asset.parent, asset)
    layer = Usd.Stage.Open(str(asset / "eye_feather_material.usda"))
    layer.GetPrimAtPath("/eye_feather/Materials/Feather").GetAttribute(
        "pavonine:crescentSigma"
    ).Set(12.0)
    layer.Save()
    result = CliRunner().invoke(cli, ["validate", str(asset / "eye_feather.usd")])
    assert "BakedTexturesStale" in result.output and "pavonine bake" in result.output
    assert CliRunner().invoke(cli, ["bake", str(asset), "--resolution", "32", "-q"]).exit_code == 0
    again = CliRunner().invoke(cli, ["validate", str(asset / "eye_feather.usd")])
    assert "BakedTexturesStale" not in again.output


@pytest.mark.parametrize("case", ["missing", "not_a_feather"])
def test_bake_bad_input_is_one_line(tmp_path, case):
    from pxr import Usd, UsdGeom

    target = tmp_path / "nope.usd"
    if case == "not_a_feather":
        stage = Usd.Stage.CreateNew(str(target))
        stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, "/Thing").GetPrim())
        stage.Save()
    result = CliRunner().invoke(cli, ["bake", str(target)])
    assert result.exit_code == 2
    assert result.stderr.startswith(f"error: {target}") and result.stderr.count("\n") == 1


def _snapshot(folder) -> dict:
    """Every file under ``folder`` with its bytes, to show that nothing was written."""
    return {p: p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _refused(target, snapshot_of, named=None) -> str:
    """Bake ``target``; assert exit 2, one line naming ``named`` (default ``target``), no file
    under ``snapshot_of`` touched."""
    before = _snapshot(snapshot_of)
    result = CliRunner().invoke(cli, ["bake", str(target), "--resolution", "16"])
    assert result.exit_code == 2 and result.stderr.count("\n") == 1, result.output
    assert result.stderr.startswith(f"error: {named or target}: "), result.stderr
    assert _snapshot(snapshot_of) == before
    return result.stderr


def test_bake_refuses_a_usdz_package_up_front(eye_asset, tmp_path):
    package = tmp_path / "pk" / "eye.usdz"
    made = CliRunner().invoke(cli, ["package", str(eye_asset.parent), "-o", str(package), "-q"])
    assert made.exit_code == 0, made.output
    assert "unpacked asset" in _refused(package, tmp_path)
    assert sorted(p.name for p in package.parent.iterdir()) == ["eye.usdz"]


SCENE = """#usda 1.0
(
    defaultPrim = "{name}"
)

def Xform "{name}" (
    kind = "{kind}"
    prepend references = @../eye_feather/eye_feather.usd@</eye_feather>
)
{{
}}
"""


@pytest.mark.parametrize(
    ("kind", "says"),
    [("assembly", "kind 'assembly', not 'component'"), ("component", "outside the asset's folder")],
)
def test_bake_refuses_what_is_not_a_feather_asset_root(eye_asset, tmp_path, kind, says):
    """A scene (or a component of its own) referencing a feather asset elsewhere: refused,
    the feather it references left alone, no ``<default prim>.mtlx`` beside it."""
    shutil.copytree(eye_asset.parent, tmp_path / "eye_feather")
    scene = tmp_path / "scenes" / "scene.usda"
    scene.parent.mkdir()
    scene.write_text(SCENE.format(name="World", kind=kind))
    assert says in _refused(scene, tmp_path)
    assert not (tmp_path / "eye_feather" / "World.mtlx").exists()


def test_bake_refuses_maps_of_different_aspects_like_convert(eye_asset, tmp_path):
    asset = tmp_path / "eye_feather"
    shutil.copytree(eye_asset.parent, asset)
    gradation = next((asset / "maps").glob("gradation.*"))
    resized = oiio.ImageBufAlgo.resize(oiio.ImageBuf(str(gradation)), roi=oiio.ROI(0, 50, 0, 20))
    assert resized.write(str(gradation), oiio.UINT16)
    message = _refused(asset, tmp_path, named=f"{gradation.absolute()}: pavonine:gradationMap")
    assert "aspect 50x20 differs from the alpha map's" in message


@pytest.mark.parametrize("relative", [False, True])
def test_bake_names_the_layer_and_attribute_of_a_nan_parameter(
    eye_asset, tmp_path, monkeypatch, relative
):
    """Named in the asset folder, not in the hidden staging copy (also given a relative path)."""
    from pxr import Sdf

    asset = tmp_path / "eye_feather"
    shutil.copytree(eye_asset.parent, asset)
    layer = Sdf.Layer.FindOrOpen(str(asset / "eye_feather_material.usda"))
    layer.GetAttributeAtPath(
        "/eye_feather/Materials/Feather.pavonine:crescentSigma"
    ).default = float("nan")
    layer.Save()
    if relative:
        monkeypatch.chdir(tmp_path)
    given = asset.name if relative else str(asset)
    result = CliRunner().invoke(cli, ["bake", given, "--resolution", "16"])
    assert result.exit_code == 2 and result.stderr.count("\n") == 1, result.output
    assert result.stderr == (
        f"error: {(asset / 'eye_feather_material.usda').absolute()}: "
        "/eye_feather/Materials/Feather.pavonine:crescentSigma: is NaN\n"
    )
