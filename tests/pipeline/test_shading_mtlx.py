"""The asset's MaterialX materials, judged by MaterialX's own tools: ``mxvalidate``, the GLSL and
OSL shader generators (and ``glslangValidator`` on the GLSL they emit), and the same networks
written as UsdShade prims."""

from __future__ import annotations

import shutil
import subprocess

import MaterialX as mx
import MaterialX.PyMaterialXGenGlsl as mx_glsl
import MaterialX.PyMaterialXGenOsl as mx_osl
import MaterialX.PyMaterialXGenShader as mx_gen
import pytest

from pavonine.materials import materialx
from pavonine.pipeline.shading import mtlx

MAPS = ("alpha", "ocellar", "gradation", "angle", "displacement", "melanin")
TEXTURES = ("basecolor", "roughness", "film_thickness", "film_ior", "film_weight")
GENERATORS = {
    "genglsl": mx_glsl.GlslShaderGenerator.create,
    "genosl": mx_osl.OslShaderGenerator.create,
}


@pytest.fixture(scope="module")
def asset_doc(eye_asset):
    """The asset's own .mtlx, read as a host would (its xi:include resolved beside it)."""
    path = eye_asset.parent / "eye_feather.mtlx"
    doc = mx.createDocument()
    mx.readFromXmlFile(doc, str(path))
    doc.importLibrary(materialx.load_libraries())
    return doc


def generate(doc, material: str, target: str):
    generator = GENERATORS[target]()
    context = mx_gen.GenContext(generator)
    context.registerSourceCodeSearchPath(mx.getDefaultDataSearchPath())
    return generator.generate(material, doc.getNode(material), context)


def file_uniforms(shader) -> dict[str, str]:
    """Uniform variable → file name of every ``filename`` uniform of the pixel stage."""
    stage = shader.getStage(mx_gen.PIXEL_STAGE)
    found = {}
    for name in stage.getUniformBlocks():
        block = stage.getUniformBlock(name)
        for i in range(block.size()):
            port = block[i]
            if port.getType().getName() == "filename" and port.getValue() is not None:
                found[port.getVariable()] = port.getValue().getValueString()
    return found


def test_asset_carries_both_mtlx_files_with_relative_paths(eye_asset):
    folder = eye_asset.parent
    assert (folder / "pavonine_feather.mtlx").read_text() == materialx.MTLX_PATH.read_text()
    text = (folder / "eye_feather.mtlx").read_text()
    assert 'href="pavonine_feather.mtlx"' in text and str(folder) not in text
    for name in MAPS:
        assert f'value="maps/{name}.png"' in text
    for name in TEXTURES:
        assert f'value="textures/{name}.png"' in text


@pytest.mark.skipif(shutil.which("mxvalidate") is None, reason="mxvalidate not installed")
def test_mxvalidate_passes_on_the_asset_document(eye_asset):
    result = subprocess.run(
        ["mxvalidate", str(eye_asset.parent / "eye_feather.mtlx")],
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 0 and "is a valid MaterialX document" in result.stdout, (
        result.stdout + result.stderr
    )


def test_document_validates_with_the_standard_libraries(asset_doc):
    ok, message = asset_doc.validate()
    assert ok, message


@pytest.mark.parametrize("target", sorted(GENERATORS))
def test_feather_material_code_reads_the_six_maps(asset_doc, target):
    shader = generate(asset_doc, mtlx.FEATHER_MATERIAL, target)
    source = shader.getSourceCode(mx_gen.PIXEL_STAGE)
    files = file_uniforms(shader)
    for name in MAPS:
        variable = next(v for v, f in files.items() if f == f"maps/{name}.png")
        assert f"mx_image_float({variable}" in source, (name, variable)
    assert f"geomprop_{mtlx.FEATHER_UV}" in source or f'"{mtlx.FEATHER_UV}"' in source


@pytest.mark.parametrize("target", sorted(GENERATORS))
def test_portable_material_code_reads_the_baked_textures_in_open_pbr(asset_doc, target):
    shader = generate(asset_doc, mtlx.PORTABLE_MATERIAL, target)
    source = shader.getSourceCode(mx_gen.PIXEL_STAGE)
    files = set(file_uniforms(shader).values())
    assert files == {f"textures/{name}.png" for name in TEXTURES}
    assert "open_pbr_surface" in source.lower() or "OpenPbr" in source


def test_portable_material_uses_only_standard_nodes(asset_doc):
    libraries = materialx.load_libraries()
    material = asset_doc.getNode(mtlx.PORTABLE_MATERIAL)
    pending = [material.getInput("surfaceshader").getConnectedNode()]
    seen = set()
    while pending:
        node = pending.pop()
        if node.getName() in seen:
            continue
        seen.add(node.getName())
        nodedef = node.getNodeDef()
        assert libraries.getNodeDef(nodedef.getName()) is not None, nodedef.getName()
        pending += [i.getConnectedNode() for i in node.getInputs() if i.getConnectedNode()]
    assert "OpenPbr" in seen and len(seen) > 8


@pytest.mark.skipif(
    shutil.which("glslangValidator") is None,
    reason="glslangValidator not installed (Debian glslang-tools, installed by .ci/setup)",
)
@pytest.mark.parametrize("material", [mtlx.FEATHER_MATERIAL, mtlx.PORTABLE_MATERIAL])
def test_generated_glsl_compiles(asset_doc, material, tmp_path):
    shader = generate(asset_doc, material, "genglsl")
    for stage, suffix in ((mx_gen.VERTEX_STAGE, "vert"), (mx_gen.PIXEL_STAGE, "frag")):
        path = tmp_path / f"{material}.{suffix}"
        path.write_text(shader.getSourceCode(stage))
        result = subprocess.run(
            ["glslangValidator", str(path)], capture_output=True, text=True, check=False
        )
        assert result.returncode == 0, result.stdout[-2000:]


def test_usd_networks_are_the_mtlx_networks(eye_asset, asset_doc):
    """Every node upstream of each MaterialX material is a Shader prim of the USD material with
    the node's definition as ``info:id`` and the same connections."""
    from pxr import Usd, UsdShade

    stage = Usd.Stage.Open(str(eye_asset))
    for name in (mtlx.FEATHER_MATERIAL, mtlx.PORTABLE_MATERIAL):
        material = UsdShade.Material(stage.GetPrimAtPath(f"/eye_feather/Materials/{name}"))
        surface = material.GetSurfaceOutput("mtlx").GetConnectedSources()[0][0].source
        node = asset_doc.getNode(name).getInput("surfaceshader").getConnectedNode()
        assert surface.GetPath().name == node.getName()
        pending = [node]
        while pending:
            node = pending.pop()
            shader = UsdShade.Shader(material.GetPrim().GetChild(node.getName()))
            assert shader.GetShaderId() == node.getNodeDef().getName()
            for inp in node.getInputs():
                usd_input = shader.GetInput(inp.getName())
                assert usd_input, f"{name}/{node.getName()}.{inp.getName()}"
                upstream = inp.getConnectedNode()
                if upstream is not None:
                    source = usd_input.GetConnectedSources()[0][0].source
                    assert source.GetPath().name == upstream.getName()
                    pending.append(upstream)


def test_preview_purpose_binds_the_portable_twin(eye_asset):
    from pxr import Usd, UsdShade

    stage = Usd.Stage.Open(str(eye_asset))
    for scope in ("Geom", "Proxy"):
        vane = stage.GetPrimAtPath(f"/eye_feather/{scope}/Vane")
        api = UsdShade.MaterialBindingAPI(vane)
        assert vane.HasAPI(UsdShade.MaterialBindingAPI)
        full, _ = api.ComputeBoundMaterial()
        preview, _ = api.ComputeBoundMaterial(UsdShade.Tokens.preview)
        assert full.GetPath().name == "Feather"
        assert preview.GetPath().name == "FeatherPortable"
