"""``pavonine export``: a glTF 2.0 binary that the Khronos glTF validator (npm
``gltf-validator``, run by ``.ci/gltf_validate.mjs``) accepts with no errors, carrying the baked
look: base colour + alpha MASK, ``KHR_materials_iridescence`` with its thickness texture over a
``KHR_materials_specular`` substrate colour (the fitted look of pipeline/export/look.py)."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from pavonine.apps.cli import cli
from pavonine.pipeline.export import iridescence as irid
from pavonine.pipeline.export import look

CI = Path(__file__).resolve().parents[2] / ".ci"
VALIDATOR = CI / "node_modules" / "gltf-validator"


def run(*args: str):
    return CliRunner().invoke(cli, [str(a) for a in args])


@pytest.fixture(scope="module")
def glb(eye_asset, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("gltf") / "eye_feather.glb"
    result = run("export", eye_asset.parent, "-o", out, "--lod", "medium", "--json", "-")
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["lod"] == "medium" and len(report["meshes"]) == 2
    assert "own space" not in result.stderr  # the asset's meshes are not transformed
    # without --eye, the look is fitted for the eye `pavonine view` frames the asset from
    from pavonine.apps.view.scene import read_scene

    page = read_scene(eye_asset.parent, {"lod": "medium"}).camera
    assert report["eye"] == pytest.approx(page["eye"]) and page["path"] is None
    assert report["pivot"] == pytest.approx(page["centre"])
    return out


def _image_bytes(doc, texture_index: int) -> bytes:
    image = doc.images[doc.textures[texture_index].source]
    assert image.mimeType == "image/png"
    view = doc.bufferViews[image.bufferView]
    return doc.binary_blob()[view.byteOffset : view.byteOffset + view.byteLength]


def _image(doc, texture_index: int, folder: Path) -> np.ndarray:
    path = folder / f"texture{texture_index}.png"
    path.write_bytes(_image_bytes(doc, texture_index))
    return _image_file(path)


def _image_file(path: Path) -> np.ndarray:
    import OpenImageIO as oiio

    return np.asarray(oiio.ImageBuf(str(path)).get_pixels(oiio.FLOAT))


def test_glb_carries_the_baked_feather(glb, eye_asset, tmp_path):
    import pygltflib

    doc = pygltflib.GLTF2().load_binary(str(glb))
    assert doc.extensionsUsed == ["KHR_materials_iridescence", "KHR_materials_specular"]
    fitted = doc.asset.extras["pavonine"]  # the viewer the look is fitted for, in metres
    assert len(fitted["fittedForEye"]) == 3 and fitted["fittedForEye"][2] > 0.2  # 30 cm in front
    materials = {m.name: m for m in doc.materials}
    feather, rachis = materials["Feather"], materials["Rachis"]
    assert feather.alphaMode == "MASK" and feather.alphaCutoff == pytest.approx(0.5)
    assert feather.doubleSided and feather.pbrMetallicRoughness.metallicFactor == 0.0
    # The film's substrate: KHR_materials_specular's colour, F0 over [0, SUBSTRATE_F0_MAX].
    specular = feather.extensions["KHR_materials_specular"]
    assert specular["specularFactor"] == 1.0
    assert specular["specularColorFactor"] == [irid.SUBSTRATE_F0_MAX / 0.04] * 3
    substrate = _image(doc, specular["specularColorTexture"]["index"], tmp_path)[..., :3]
    iridescence = feather.extensions["KHR_materials_iridescence"]
    assert iridescence["iridescenceThicknessMinimum"] == 0.0
    assert iridescence["iridescenceThicknessMaximum"] == 1000.0
    assert iridescence["iridescenceIor"] in look.IOR_CANDIDATES  # the fit's pick
    # The fitted look (pipeline/export/look.py): the base holds what the film does not, so it is
    # darker than the bake's whole-colour base; the film has weight and thickness in the vane.
    base = _image(doc, feather.pbrMetallicRoughness.baseColorTexture.index, tmp_path)
    baked = _image_file(eye_asset.parent / "textures" / "basecolor.png")
    assert base.shape == baked.shape
    opaque = baked[..., 3] > 0.9
    assert np.allclose(base[..., 3], baked[..., 3], atol=1.0 / 255)  # the same opacity
    assert base[opaque][:, :3].mean() < baked[opaque][:, :3].mean() - 0.02
    film = _image(doc, iridescence["iridescenceThicknessTexture"]["index"], tmp_path)
    assert (
        iridescence["iridescenceTexture"]["index"]
        == iridescence["iridescenceThicknessTexture"]["index"]
    )
    assert film[opaque][:, 0].mean() > 0.3  # R: the film's weight
    assert 0.1 < np.median(film[opaque][:, 1]) < 0.9  # G: thickness over [0, 1000] nm
    assert np.ptp(film[opaque][:, 1]) > 0.1  # it varies over the feather
    # The substrate is coloured (channels chosen apart) and varies over the feather.
    assert np.ptp(substrate[opaque], axis=0).min() > 0.2
    assert np.mean(np.ptp(substrate[opaque], axis=1) > 0.05) > 0.1
    # The film's texture is sampled nearest (a mean thickness draws another colour); the others
    # are mipmapped.
    sampler = doc.samplers[doc.textures[iridescence["iridescenceTexture"]["index"]].sampler]
    assert sampler.minFilter == sampler.magFilter == pygltflib.NEAREST  # no mean thickness
    base_sampler = doc.textures[feather.pbrMetallicRoughness.baseColorTexture.index].sampler
    assert doc.samplers[base_sampler].minFilter == pygltflib.LINEAR_MIPMAP_LINEAR
    assert rachis.alphaMode == "OPAQUE" and len(rachis.pbrMetallicRoughness.baseColorFactor) == 4


def test_glb_geometry_is_in_metres_with_unit_normals_and_uvs(glb):
    import pygltflib

    doc = pygltflib.GLTF2().load_binary(str(glb))
    blob = doc.binary_blob()

    def values(index: int, width: int) -> np.ndarray:
        accessor = doc.accessors[index]
        view = doc.bufferViews[accessor.bufferView]
        raw = blob[view.byteOffset : view.byteOffset + view.byteLength]
        return np.frombuffer(raw, dtype=np.float32).reshape(-1, width)

    vane = next(m for m in doc.meshes if m.name == "Vane").primitives[0]
    points = values(vane.attributes.POSITION, 3)
    assert 0.15 < np.ptp(points[:, 1]) < 0.3  # a 20 cm feather (+ shaft), in metres
    normals = values(vane.attributes.NORMAL, 3)
    assert np.allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-5)
    uv = values(vane.attributes.TEXCOORD_0, 2)
    assert np.all((uv >= 0.0) & (uv <= 1.0))


def _validator() -> list[str]:
    node = shutil.which("node")
    if node is None or shutil.which("npm") is None:
        pytest.skip("Node.js/npm not installed: cannot run the Khronos glTF validator")
    if not VALIDATOR.is_dir():  # as .ci/setup does (which goes on without it when npm fails)
        done = subprocess.run(
            ["npm", "ci", "--prefix", str(CI), "--no-audit", "--no-fund", "--loglevel=error"],
            capture_output=True,
            text=True,
            check=False,
            timeout=600,
        )
        if done.returncode != 0:
            errors = [line for line in done.stderr.splitlines() if "error" in line.lower()]
            detail = " ".join(errors[:3]) or f"exit status {done.returncode}"
            pytest.skip(f"cannot install the Khronos glTF validator (npm ci: {detail[:300]})")
    return [node, str(CI / "gltf_validate.mjs")]


def test_khronos_glTF_validator_reports_no_errors(glb):
    result = subprocess.run(
        [*_validator(), str(glb)], capture_output=True, text=True, check=False, timeout=300
    )
    report = json.loads(result.stdout)
    assert result.returncode == 0 and report["errors"] == 0, report["messages"][:10]
    assert report["warnings"] == 0, report["messages"][:10]
    assert report["extensionsUsed"] == ["KHR_materials_iridescence", "KHR_materials_specular"]


def test_validator_script_catches_a_broken_file(glb, tmp_path):
    broken = tmp_path / "broken.glb"
    data = bytearray(glb.read_bytes())
    data[20:40] = b"x" * 20  # corrupt the JSON chunk
    broken.write_bytes(bytes(data))
    result = subprocess.run(
        [*_validator(), str(broken)], capture_output=True, text=True, check=False, timeout=300
    )
    assert result.returncode == 1 and json.loads(result.stdout)["errors"] > 0


@pytest.mark.parametrize(
    ("args", "field"),
    [
        (("-o", "x.gltf"), "x.gltf"),
        (("--lod", "ultra"), "--lod"),
        (("--eye", "0", "15", "-1"), "--eye"),  # inside the feather's bounds
        (("--eye", "0", "nan", "36"), "--eye"),
    ],
)
def test_bad_input_is_one_line(eye_asset, tmp_path, args, field):
    argv = ["export", eye_asset.parent, "-o", tmp_path / "x.glb", *args]
    if args[0] == "-o":
        argv = ["export", eye_asset.parent, "-o", tmp_path / args[1]]
    result = run(*argv)
    assert result.exit_code == 2 and field in result.stderr and result.stderr.count("\n") == 1
    assert not any(tmp_path.iterdir())


def test_a_missing_baked_texture_is_named_with_its_shader_input(eye_asset, tmp_path):
    """A texture the material authors but that is not there: the file and ``inputs:file``."""
    asset = tmp_path / "eye_feather"
    shutil.copytree(eye_asset.parent, asset)
    (asset / "textures" / "basecolor.png").unlink()
    result = run("export", asset, "-o", tmp_path / "x.glb")
    assert result.exit_code == 2 and result.stderr.count("\n") == 1, result.output
    missing = asset / "textures" / "basecolor.png"
    assert result.stderr.startswith(f"error: {missing}: /eye_feather/Materials/Feather/"), (
        result.stderr
    )
    assert ".inputs:file: " in result.stderr and "not found" in result.stderr
    assert not (tmp_path / "x.glb").exists()


def test_the_look_is_fitted_to_the_views_from_the_eye_turned_about_the_pivot(eye_asset):
    """``look_targets`` gives the fit, per texel and in its frame, the views toward the eye turned
    about the pivot (``viewer_views`` of the texel's surface point), and the model's reflectance
    at each of them (against the same texel given that view alone)."""
    from pxr import Usd, UsdShade

    from pavonine.pipeline.bake import appearance
    from pavonine.pipeline.bake.asset import bound_meshes, feather_inputs
    from pavonine.pipeline.export import look

    stage = Usd.Stage.Open(str(eye_asset))
    default = stage.GetDefaultPrim()
    material = next(
        bound
        for prim in Usd.PrimRange(default)
        if (bound := UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()[0])
        and "PavonineFeatherAPI" in bound.GetPrim().GetAppliedSchemas()
    )
    meshes = bound_meshes(stage, default, material)
    eye, pivot = np.array([3.0, 17.0, 36.0]), np.array([0.5, 10.0, -1.0])
    found = look.look_targets(material, meshes, 16, eye, pivot)
    toward = look.viewer_views(found.texels.position, eye, pivot)
    frames = found.inputs["frames"]
    assert np.allclose(found.views, np.einsum("nij,nkj->nki", frames, toward))
    tilted = irid.FIT_TILTS_DEG.index(irid.TILT_DEG)
    params, maps, _ = feather_inputs(material)
    for i in (0, len(toward) - 1):
        alone, _ = appearance.reflectance_at_views(
            found.texels, maps, params, appearance.REFERENCE_LIGHT, toward[i, tilted][None]
        )
        assert np.allclose(found.target[i, tilted], np.clip(alone[i, 0], 0.0, None))


def test_a_transformed_feather_mesh_is_named_in_a_warning(eye_asset, tmp_path):
    """The look is fitted at the meshes' own points and the eye is in the asset's space: a mesh
    a transform moves is exported, and named in a warning (its fitted views are off)."""
    from pxr import Sdf, Usd, UsdGeom

    stage = Usd.Stage.Open(str(eye_asset))
    vane = next(p for p in stage.Traverse() if p.IsA(UsdGeom.Mesh) and "Rachis" not in p.GetName())
    layer = Sdf.Layer.CreateNew(str(tmp_path / "moved.usda"))
    layer.subLayerPaths.append(str(eye_asset))
    layer.defaultPrim = stage.GetDefaultPrim().GetName()
    over = Usd.Stage.Open(layer)
    UsdGeom.Xformable(over.OverridePrim(vane.GetPath())).AddTranslateOp().Set((0.0, 0.0, 2.0))
    over.SetMetadata("metersPerUnit", UsdGeom.GetStageMetersPerUnit(stage))
    over.SetMetadata("upAxis", UsdGeom.GetStageUpAxis(stage))
    layer.Save()
    result = run("export", tmp_path / "moved.usda", "-o", tmp_path / "moved.glb", "--lod", "low")
    assert result.exit_code == 0, result.output
    assert str(vane.GetPath()) in result.stderr and "own space" in result.stderr
    assert (tmp_path / "moved.glb").exists()
