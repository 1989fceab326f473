"""USD shader definitions of the MaterialX nodes a converted asset uses, for USD builds without
``usdMtlx`` (usd-core).

A converted asset's looks are MaterialX networks written as UsdShade prims whose ``info:id`` is a
MaterialX node definition (``ND_image_float``, ``ND_pavonine_feather_surfaceshader``, …). Sdr learns
those from ``.mtlx`` files through ``usdMtlx``; usd-core has no ``usdMtlx``, so there Sdr knows none
of them and USD's ``ShaderSdrCompliance`` validator rejects every such shader.

usd-core does have Sdr's filesystem discovery (``PXR_SDR_FS_PLUGIN_SEARCH_PATHS``, files with an
extension in ``PXR_SDR_FS_PLUGIN_ALLOWED_EXTS``, identifier = file stem) and the parser of USD
shader-definition files (``UsdShadeShaderDefParserPlugin``, discovery types ``usda``/``usdc``/
``usd``, the prim ``/<identifier>``), which is how ``usdShaders`` defines ``UsdPreviewSurface``.
So :func:`write_definitions` writes one ``<node id>.usda`` per node of :func:`asset_node_ids`
into :data:`pavonine.schemas.plugin.SHADER_DEFS_DIR`: a ``Shader`` prim whose inputs and outputs,
types, defaults and ``uniform``-ness come from the node definition (MaterialX's standard
libraries through the MaterialX Python package; Pavonine's node from ``pavonine_feather.mtlx``),
value types mapped as ``usdMtlx`` maps them. ``pavonine env`` adds the folder to the search path.

The definitions carry no implementation (``info:sourceAsset`` names the file itself): they tell
Sdr a node's interface, nothing a renderer could run. Their Sdr source type is empty (the
filesystem discovery sets none), so in a USD build *with* ``usdMtlx`` they sit beside usdMtlx's
``mtlx`` nodes without replacing them: renderers ask for ``mtlx`` by name
(``GetShaderNodeByIdentifierAndType(id, "mtlx")``), and a lookup without a source type finds
either, with the same interface.

The files are generated and checked by the test suite; after changing the looks (or MaterialX),
run ``python -m pavonine.pipeline.shading.sdr_defs``.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

from pxr import Sdf, Usd, UsdShade

from pavonine.schemas.mtlx_types import SDF_TYPES
from pavonine.schemas.plugin import SHADER_DEFS_DIR, SHADER_DEFS_EXTENSION

#: MaterialX type → USD value type beyond :data:`~pavonine.schemas.mtlx_types.SDF_TYPES`, as
#: ``usdMtlx`` maps them; any other type (closures, shaders) becomes ``token``.
_MORE_TYPES = {
    "matrix33": Sdf.ValueTypeNames.Matrix3d,
    "matrix44": Sdf.ValueTypeNames.Matrix4d,
    "geomname": Sdf.ValueTypeNames.String,
    "floatarray": Sdf.ValueTypeNames.FloatArray,
    "integerarray": Sdf.ValueTypeNames.IntArray,
    "stringarray": Sdf.ValueTypeNames.StringArray,
    "color3array": Sdf.ValueTypeNames.Color3fArray,
    "color4array": Sdf.ValueTypeNames.Color4fArray,
    "vector2array": Sdf.ValueTypeNames.Float2Array,
    "vector3array": Sdf.ValueTypeNames.Float3Array,
    "vector4array": Sdf.ValueTypeNames.Float4Array,
}
#: Output type → Sdr ``renderType`` of a terminal (as ``usdShaders``' ``UsdPreviewSurface``).
_TERMINALS = {
    "surfaceshader": "terminal surface",
    "displacementshader": "terminal displacement",
    "volumeshader": "terminal volume",
}
#: MaterialX node group → Sdr node role.
_ROLES = {"texture2d": "texture", "texture3d": "texture"}
EXTENSION = SHADER_DEFS_EXTENSION


def _value_type(mtlx_type: str) -> Sdf.ValueTypeName:
    return SDF_TYPES.get(mtlx_type) or _MORE_TYPES.get(mtlx_type, Sdf.ValueTypeNames.Token)


def _default(port, value_type: Sdf.ValueTypeName):
    """The port's MaterialX default as a USD value, or None (no value, a geomprop default)."""
    text = port.getValueString()
    if not text or value_type == Sdf.ValueTypeNames.Token:
        return None
    if value_type == Sdf.ValueTypeNames.Asset:
        return Sdf.AssetPath(text)
    value = port.getValue()
    if isinstance(value, (bool, int, float, str)):
        return value
    return value_type.type.pythonClass(*[float(v) for v in value])


def asset_node_ids(lib=None) -> list[str]:
    """Every MaterialX node definition a converted asset's looks name: the nodes of the asset
    document (:func:`~pavonine.pipeline.shading.mtlx.asset_document`) with all six maps and all
    baked textures."""
    from pavonine.materials.parameters import preset
    from pavonine.pipeline.bake.textures import FILES
    from pavonine.pipeline.maps.paint import MAP_NAMES
    from pavonine.pipeline.shading import mtlx

    lib = lib or mtlx.library()
    maps = {name: f"maps/{name}.png" for name in MAP_NAMES}
    textures = {key: f"textures/{file}" for key, file in FILES.items()}
    doc = mtlx.asset_document(preset("freyer2020"), maps, textures, lib)
    ids = set()
    for node in doc.getNodes():
        nodedef = node.getNodeDef()
        if nodedef is not None and node.getType() != "material":
            ids.add(nodedef.getName())
    return sorted(ids)


def define_node(nodedef, path: Path) -> None:
    """Write the USD shader definition of the MaterialX ``nodedef`` to ``path`` (``<id>.usda``)."""
    node_id = nodedef.getName()
    stage = Usd.Stage.CreateInMemory()
    layer = stage.GetRootLayer()
    layer.documentation = (
        f"Sdr definition of the MaterialX node {node_id} (interface only), generated from its "
        "node definition by pavonine.pipeline.shading.sdr_defs: do not edit."
    )
    shader = UsdShade.Shader.Define(stage, Sdf.Path.absoluteRootPath.AppendChild(node_id))
    shader.SetShaderId(node_id)
    shader.SetSourceAsset(Sdf.AssetPath(f"./{path.name}"))
    doc = nodedef.getAttribute("doc")
    if doc:
        shader.GetPrim().SetDocumentation(doc)
    role = _ROLES.get(nodedef.getNodeGroup())
    if role:
        shader.SetSdrMetadataByKey("role", role)
    for port in nodedef.getActiveInputs():
        value_type = _value_type(port.getType())
        inp = shader.CreateInput(port.getName(), value_type)
        value = _default(port, value_type)
        if value is not None:
            inp.Set(value)
        if port.getAttribute("uniform") == "true":
            inp.SetConnectability(UsdShade.Tokens.interfaceOnly)
        if port.getAttribute("doc"):
            inp.GetAttr().SetDocumentation(port.getAttribute("doc"))
    for port in nodedef.getActiveOutputs():
        out = shader.CreateOutput(port.getName(), _value_type(port.getType()))
        if port.getType() in _TERMINALS:
            out.SetSdrMetadataByKey("renderType", _TERMINALS[port.getType()])
    layer.Export(str(path))


def write_definitions(folder: Path = SHADER_DEFS_DIR) -> list[Path]:
    """Replace ``folder``'s contents with the definitions of :func:`asset_node_ids` (atomically:
    written beside, then swapped in); returns the files."""
    from pavonine.pipeline.shading import mtlx

    lib = mtlx.library()
    folder = Path(folder)
    folder.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", dir=folder.parent))
    for node_id in asset_node_ids(lib):
        define_node(lib.getNodeDef(node_id), staging / f"{node_id}.{EXTENSION}")
    old = folder.with_name(f".{folder.name}.old")
    if folder.exists():
        folder.rename(old)
    staging.rename(folder)
    shutil.rmtree(old, ignore_errors=True)
    return sorted(folder.glob(f"*.{EXTENSION}"))


if __name__ == "__main__":
    for file in write_definitions():
        print(file)
