"""The asset's MaterialX document (``<name>.mtlx`` beside the material layer).

Two materials, every file path relative to the document (the asset folder):

``Feather``
    Pavonine's node ``ND_pavonine_feather_surfaceshader`` (``pavonine_feather.mtlx``, copied
    beside and ``xi:include``d, so the folder is self-contained), its schema-derived inputs as
    values and its per-texel inputs read from the six maps, each an ``image`` at the mesh's
    feather coordinate (``geompropvalue pavonine_featherUV``): ``ocellar``, ``gradation``,
    ``barbule_angle``, ``structural`` (melanin map), ``opacity`` (alpha map); the displacement
    map ``bump``s the ``normal`` and the mesh's barb direction (``geompropvalue
    pavonine_barbTangent``, object → world) is the ``tangent``. Hosts need the node definition:
    ``PXR_MTLX_PLUGIN_SEARCH_PATHS`` from ``pavonine env`` for USD, the include for MaterialX.
``FeatherPortable``
    Standard nodes only, for any MaterialX 1.39 host: ``open_pbr_surface`` with the baked base
    colour and opacity, roughness, and a thin film (``thin_film_weight``/``thickness``/``ior``)
    from the baked textures (:mod:`pavonine.pipeline.bake.textures`), at texture coordinate set 0
    (USD's ``st``).

The USD material layer carries the same networks as UsdShade prims
(:mod:`pavonine.pipeline.shading.usd`); both are made from this document.
"""

from __future__ import annotations

import shutil
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from pavonine.base.commit import atomic_path
from pavonine.base.truncation import refuse_size_other_than
from pavonine.materials import materialx
from pavonine.materials.parameters import FeatherParameters
from pavonine.schemas.authoring import MTLX_SHADER
from pavonine.schemas.primvars import BARB_TANGENT_PRIMVAR, FEATHER_UV_PRIMVAR

FEATHER_MATERIAL = "Feather"
PORTABLE_MATERIAL = "FeatherPortable"
FEATHER_SHADER = MTLX_SHADER
PORTABLE_SHADER = "OpenPbr"
FEATHER_UV = FEATHER_UV_PRIMVAR
BARB_TANGENT = BARB_TANGENT_PRIMVAR
#: Height scale of the displacement map's bump (shading detail, as the renderer's bump map).
BUMP_SCALE = 0.002
NODEDEF_FILE = materialx.MTLX_PATH.name

#: Map key → (nodedef input it drives, image filter).
MAP_INPUTS = {
    "ocellar": ("ocellar", "closest"),
    "gradation": ("gradation", "linear"),
    "angle": ("barbule_angle", "linear"),
    "melanin": ("structural", "linear"),
    "alpha": ("opacity", "linear"),
}


def _text(value: Any) -> str:
    """MaterialX value text; floats as the shortest text of their float32 (USD values are 32-bit)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        return np.format_float_positional(np.float32(value), unique=True, trim="-")
    if isinstance(value, str):
        return value
    return ", ".join(_text(float(v)) for v in value)


class _Graph:
    """Adds nodes to a document whose data library holds their definitions."""

    def __init__(self, doc):
        self.doc = doc

    def node(self, category: str, name: str, out_type: str, **inputs: Any):
        """A node with connections (node values, typed by the upstream node) and values (typed
        by the node definition that the connections and the output type select)."""
        node = self.doc.addNode(category, name, out_type)
        for key, value in inputs.items():
            if hasattr(value, "getCategory"):
                node.addInput(key, value.getType()).setConnectedNode(value)
        for key, value in inputs.items():
            if not hasattr(value, "getCategory"):
                inp = node.addInputFromNodeDef(key)
                if inp is None:
                    raise ValueError(f"{category} ({out_type}) has no input {key!r}")
                inp.setValueString(_text(value))
        return node

    def connect(self, node, key: str, upstream) -> None:
        """Connect ``upstream`` to ``node``'s input ``key``."""
        node.addInput(key, upstream.getType()).setConnectedNode(upstream)

    def image(self, name: str, file: str, out_type: str, texcoord, filtertype="linear", space=""):
        node = self.node(
            "image",
            name,
            out_type,
            file=file,
            texcoord=texcoord,
            filtertype=filtertype,
            uaddressmode="clamp",
            vaddressmode="clamp",
        )
        if space:
            node.getInput("file").setColorSpace(space)
        return node


def library():
    """MaterialX's standard libraries plus Pavonine's node definition, in one document."""
    import MaterialX as mx

    lib = materialx.load_libraries()
    nodedef = mx.createDocument()
    mx.readFromXmlFile(nodedef, str(materialx.MTLX_PATH))
    lib.importLibrary(nodedef)
    return lib


def asset_document(
    params: FeatherParameters,
    maps: Mapping[str, str | None],
    textures: Mapping[str, str] | None,
    lib=None,
):
    """Both materials (the portable one only with ``textures``). ``maps``/``textures``: key →
    file path relative to the document (``maps/alpha.png``, ``textures/basecolor.png``)."""
    import MaterialX as mx

    doc = mx.createDocument()
    doc.setDataLibrary(lib or library())
    doc.setColorSpace("lin_rec709")
    mx.prependXInclude(doc, NODEDEF_FILE)
    graph = _Graph(doc)
    uv = graph.node("geompropvalue", "feather_uv", "vector2", geomprop=FEATHER_UV)
    values = materialx.input_values(params)
    shader = graph.node(
        materialx.NODE,
        FEATHER_SHADER,
        "surfaceshader",
        **{k: v for k, v in values.items() if k not in materialx.PER_TEXEL_INPUTS},
    )
    for key, (input_name, filtertype) in MAP_INPUTS.items():
        if maps.get(key):
            image = graph.image(f"{key}_map", maps[key], "float", uv, filtertype)
            graph.connect(shader, input_name, image)
    if maps.get("displacement"):
        height = graph.image("displacement_map", maps["displacement"], "float", uv)
        bump = graph.node("bump", "displacement_bump", "vector3", height=height, scale=BUMP_SCALE)
        graph.connect(shader, "normal", bump)
    barb = graph.node("geompropvalue", "barb_tangent_object", "vector3", geomprop=BARB_TANGENT)
    world = graph.node(
        "transformvector",
        "barb_tangent_world",
        "vector3",
        fromspace="object",
        tospace="world",
        **{"in": barb},
    )
    tangent = graph.node("normalize", "barb_tangent", "vector3", **{"in": world})
    graph.connect(shader, "tangent", tangent)
    graph.node("surfacematerial", FEATHER_MATERIAL, "material", surfaceshader=shader)
    if textures:
        _portable(graph, textures)
    return doc


def _portable(graph: _Graph, textures: Mapping[str, str]) -> None:
    from pavonine.pipeline.bake.textures import IOR_RANGE

    st = graph.node("texcoord", "atlas_uv", "vector2", index=0)
    color = graph.image(
        "base_color_texture", textures["base_color"], "color4", st, space="srgb_texture"
    )
    base = graph.node("convert", "base_color", "color3", **{"in": color})
    opacity = graph.node("extract", "opacity", "float", index=3, **{"in": color})
    rough = graph.image("roughness_texture", textures["roughness"], "float", st)
    thickness = graph.image("film_thickness_texture", textures["film_thickness"], "float", st)
    weight = graph.image("film_weight_texture", textures["film_weight"], "float", st)
    ior_code = graph.image("film_ior_texture", textures["film_ior"], "float", st)
    ior = graph.node(
        "remap", "film_ior", "float", outlow=IOR_RANGE[0], outhigh=IOR_RANGE[1], **{"in": ior_code}
    )
    shader = graph.node(
        "open_pbr_surface",
        PORTABLE_SHADER,
        "surfaceshader",
        base_color=base,
        specular_roughness=rough,
        specular_ior=materialx.KERATIN_INDEX,
        thin_film_weight=weight,
        thin_film_thickness=thickness,
        thin_film_ior=ior,
        geometry_opacity=opacity,
    )
    graph.node("surfacematerial", PORTABLE_MATERIAL, "material", surfaceshader=shader)


def write_document(doc, folder: Path, name: str) -> Path:
    """Write ``doc`` as ``folder/<name>.mtlx`` and copy Pavonine's node definition beside it
    (both atomically); returns the document's path."""
    import MaterialX as mx

    folder = Path(folder)
    with atomic_path(folder / NODEDEF_FILE) as tmp:
        shutil.copyfile(materialx.MTLX_PATH, tmp)
        refuse_size_other_than(tmp, materialx.MTLX_PATH.stat().st_size, folder / NODEDEF_FILE)
    target = folder / f"{name}.mtlx"
    with atomic_path(target) as tmp:
        mx.writeToXmlFile(doc, str(tmp))  # reports no short write: the size is checked
        refuse_size_other_than(tmp, len(mx.writeToXmlString(doc).encode("utf-8")), target)
    return target
