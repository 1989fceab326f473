"""The USD shader definitions of the asset's MaterialX nodes (``schemas/shaderDefs``) are
generated from MaterialX's node definitions and cover every node a converted asset names."""

from __future__ import annotations

from pxr import Sdf, Usd, UsdShade

from pavonine.pipeline.shading.mtlx import library
from pavonine.pipeline.shading.sdr_defs import EXTENSION, define_node, write_definitions
from pavonine.schemas.plugin import SHADER_DEFS_DIR


def test_committed_definitions_are_current(tmp_path):
    written = write_definitions(tmp_path / "shaderDefs")
    committed = sorted(SHADER_DEFS_DIR.glob(f"*.{EXTENSION}"))
    assert [p.name for p in written] == [p.name for p in committed], (
        "run python -m pavonine.pipeline.shading.sdr_defs"
    )
    for new, old in zip(written, committed, strict=True):
        assert new.read_text() == old.read_text(), f"{old.name} is stale"


def test_every_materialx_node_of_a_converted_asset_has_a_definition(eye_asset):
    stage = Usd.Stage.Open(str(eye_asset))
    shaders = [UsdShade.Shader(p) for p in stage.Traverse() if p.IsA(UsdShade.Shader)]
    ids = {s.GetShaderId() for s in shaders if (s.GetShaderId() or "").startswith("ND_")}
    assert len(ids) > 10
    assert ids <= {p.stem for p in SHADER_DEFS_DIR.glob(f"*.{EXTENSION}")}


def test_a_definition_carries_the_nodedef_interface(tmp_path):
    lib = library()  # keeps the document alive: a nodedef of a freed document is orphaned
    nodedef = lib.getNodeDef("ND_image_color3")
    path = tmp_path / "ND_image_color3.usda"
    define_node(nodedef, path)
    stage = Usd.Stage.Open(str(path))
    shader = UsdShade.Shader(stage.GetPrimAtPath("/ND_image_color3"))
    assert shader.GetIdAttr().Get() == "ND_image_color3"
    assert (
        shader.GetImplementationSource() == UsdShade.Tokens.sourceAsset
    )  # what Sdr's parser needs
    file = shader.GetInput("file")
    assert file.GetTypeName() == Sdf.ValueTypeNames.Asset
    assert file.GetConnectability() == UsdShade.Tokens.interfaceOnly  # uniform in MaterialX
    assert shader.GetInput("texcoord").GetTypeName() == Sdf.ValueTypeNames.Float2
    assert shader.GetInput("uaddressmode").Get() == "periodic"
    assert shader.GetOutput("out").GetTypeName() == Sdf.ValueTypeNames.Color3f
    assert shader.GetSdrMetadataByKey("role") == "texture"
    names = {i.GetBaseName() for i in shader.GetInputs()}
    assert names == {i.getName() for i in nodedef.getActiveInputs()}
