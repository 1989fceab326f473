"""The asset's materials as UsdShade prims: MaterialX networks (``outputs:mtlx:surface``), the
baked UsdPreviewSurface (``outputs:surface``) and the material bindings.

* :func:`author_mtlx_network` writes one material of the asset's MaterialX document
  (:mod:`pavonine.pipeline.shading.mtlx`) as Shader prims under a USD Material, one per node,
  ``info:id`` = the node's MaterialX node definition (``ND_image_float``, …), as ``usdMtlx``
  would, so Storm-with-MaterialX, Karma and Omniverse read it from USD alone.
* :func:`author_baked_preview` makes the UsdPreviewSurface read the baked textures at ``st``
  (``inputs:frame:stPrimvarName`` on the Material): base colour, opacity with
  ``opacityThreshold``, roughness. The model has no white surface reflection of its own (its
  structural lobe *is* the gloss, and it is in the baked colour), so the preview's specular is
  switched off (specular workflow, black ``specularColor``, ``ior`` 1).
* :func:`bind` binds a full-purpose material and, for real-time viewers, a preview-purpose one
  (``material:binding:preview``) with ``UsdShade.MaterialBindingAPI``.
"""

from __future__ import annotations

from collections.abc import Mapping

from pxr import Gf, Sdf, Usd, UsdShade

from pavonine.pipeline.bake.textures import FILES
from pavonine.schemas.authoring import ALPHA_TEXTURE, PREVIEW_SHADER, TEXCOORD_READER
from pavonine.schemas.mtlx_types import SDF_TYPES, mtlx_input_value

ST_READER = "StReader"
BAKED_COLOR = "BakedColor"
BAKED_ROUGHNESS = "BakedRoughness"
#: Shaders of the schema's unbaked preview (``pavonine.schemas.authoring``), replaced by the bake.
UNBAKED_PREVIEW = (TEXCOORD_READER, ALPHA_TEXTURE)
ST_PRIMVAR = "st"
#: Opacity below which the preview cuts the vane away (glTF's default ``alphaCutoff``).
OPACITY_THRESHOLD = 0.5


def author_mtlx_network(stage: Usd.Stage, path: Sdf.Path | str, doc, material_name: str):
    """Define the Material ``path`` with the network of ``doc``'s ``material_name`` in the
    ``mtlx`` render context (an existing shader of the same name is replaced)."""
    material = UsdShade.Material.Define(stage, Sdf.Path(str(path)))
    base = material.GetPath()
    outputs: dict[str, UsdShade.Output] = {}

    def define(node) -> UsdShade.Output:
        name = node.getName()
        if name in outputs:
            return outputs[name]
        prim_path = base.AppendChild(name)
        stage.RemovePrim(prim_path)
        shader = UsdShade.Shader.Define(stage, prim_path)
        nodedef = node.getNodeDef()
        if nodedef is None:
            raise ValueError(f"MaterialX node {name!r} ({node.getCategory()}) has no definition")
        shader.SetShaderId(nodedef.getName())
        out_type = node.getType()
        output = shader.CreateOutput("out", SDF_TYPES.get(out_type, Sdf.ValueTypeNames.Token))
        outputs[name] = output
        for inp in node.getInputs():
            usd_input = shader.CreateInput(inp.getName(), SDF_TYPES[inp.getType()])
            upstream = inp.getConnectedNode()
            if upstream is not None:
                usd_input.ConnectToSource(define(upstream))
                continue
            usd_input.Set(mtlx_input_value(inp))
            if inp.getColorSpace():
                usd_input.GetAttr().SetColorSpace(inp.getColorSpace())
        return output

    surface = doc.getNode(material_name).getInput("surfaceshader").getConnectedNode()
    material.CreateSurfaceOutput("mtlx").ConnectToSource(define(surface))
    return material


def _texture(stage, path: Sdf.Path, file: str, space: str, reader: UsdShade.Output, outputs):
    shader = UsdShade.Shader.Define(stage, path)
    shader.SetShaderId("UsdUVTexture")
    shader.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(Sdf.AssetPath(file))
    shader.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set(space)
    shader.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(reader)
    for wrap in ("wrapS", "wrapT"):
        shader.CreateInput(wrap, Sdf.ValueTypeNames.Token).Set("clamp")
    return {name: shader.CreateOutput(name, vtype) for name, vtype in outputs.items()}


def _connect(shader: UsdShade.Shader, name: str, vtype, source: UsdShade.Output) -> None:
    """Connect input ``name`` to ``source``, dropping any constant value it held."""
    inp = shader.CreateInput(name, vtype)
    inp.GetAttr().Clear()
    inp = shader.CreateInput(name, vtype)
    inp.ConnectToSource(source)


def author_baked_preview(material: UsdShade.Material, textures: Mapping[str, str]) -> None:
    """(Re)author ``material``'s UsdPreviewSurface to read the baked ``textures`` (key →
    ``./textures/…`` asset path, :data:`pavonine.pipeline.bake.textures.FILES`)."""
    missing = set(FILES) - set(textures)
    if missing:
        raise ValueError(f"baked textures missing: {sorted(missing)}")
    stage = material.GetPrim().GetStage()
    base = material.GetPath()
    for name in UNBAKED_PREVIEW:
        stage.RemovePrim(base.AppendChild(name))
    st_name = material.CreateInput("frame:stPrimvarName", Sdf.ValueTypeNames.String)
    st_name.Set(ST_PRIMVAR)
    reader = UsdShade.Shader.Define(stage, base.AppendChild(ST_READER))
    reader.SetShaderId("UsdPrimvarReader_float2")
    reader.CreateInput("varname", Sdf.ValueTypeNames.String).ConnectToSource(st_name)
    st = reader.CreateOutput("result", Sdf.ValueTypeNames.Float2)
    float_out, color_out = Sdf.ValueTypeNames.Float, Sdf.ValueTypeNames.Float3
    color = _texture(
        stage,
        base.AppendChild(BAKED_COLOR),
        textures["base_color"],
        "sRGB",
        st,
        {"rgb": color_out, "a": float_out},
    )
    rough = _texture(
        stage, base.AppendChild(BAKED_ROUGHNESS), textures["roughness"], "raw", st, {"r": float_out}
    )
    preview = UsdShade.Shader.Define(stage, base.AppendChild(PREVIEW_SHADER))
    preview.SetShaderId("UsdPreviewSurface")
    _connect(preview, "diffuseColor", Sdf.ValueTypeNames.Color3f, color["rgb"])
    _connect(preview, "opacity", float_out, color["a"])
    _connect(preview, "roughness", float_out, rough["r"])
    preview.CreateInput("opacityThreshold", float_out).Set(OPACITY_THRESHOLD)
    preview.CreateInput("metallic", float_out).Set(0.0)
    preview.CreateInput("useSpecularWorkflow", Sdf.ValueTypeNames.Int).Set(1)
    preview.CreateInput("specularColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(0.0))
    preview.CreateInput("ior", float_out).Set(1.0)
    surface = preview.CreateOutput("surface", Sdf.ValueTypeNames.Token)
    material.CreateSurfaceOutput().ConnectToSource(surface)


def is_baked(material: UsdShade.Material) -> bool:
    """True when ``material``'s preview reads baked textures (:func:`author_baked_preview`)."""
    shader = UsdShade.Shader.Get(
        material.GetPrim().GetStage(), material.GetPath().AppendChild(PREVIEW_SHADER)
    )
    diffuse = shader.GetInput("diffuseColor") if shader else None
    return bool(diffuse and diffuse.HasConnectedSource())


def bind(
    prim: Usd.Prim, material: UsdShade.Material, preview: UsdShade.Material | None = None
) -> None:
    """Bind ``material`` (all purposes) and ``preview`` (preview purpose) to ``prim``."""
    api = UsdShade.MaterialBindingAPI.Apply(prim)
    api.Bind(material)
    if preview is not None:
        api.Bind(preview, UsdShade.Tokens.fallbackStrength, UsdShade.Tokens.preview)
