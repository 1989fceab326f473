"""MaterialX documents that a stage references (``references = @look.mtlx@</MaterialX>``).

usd-core has no usdMtlx file-format plugin, so such an arc is a composition error and the materials
it brings are missing. This module reads the document with the ``MaterialX`` package and builds
what usdMtlx would: an (anonymous) layer whose ``/MaterialX/Materials/<material>`` is a UsdShade
Material per ``surfacematerial``, one ``Shader`` per node (``info:id``: its nodedef), one
``NodeGraph`` per node graph, file names resolved against the document, colour spaces kept, the
surface on ``outputs:mtlx:surface``. :func:`substitute_references` adds a reference to that layer
beside each ``.mtlx`` reference or payload authored in the stage's root layer stack (in the session
layer, so nothing is written), and the surfaces then translate as any MaterialX network does
(:mod:`.materialx`). Arcs authored inside variants or in referenced layers keep their composition
error.
"""

from __future__ import annotations

import os
from pathlib import Path

from pxr import Ar, Sdf, Usd, UsdGeom, UsdShade

from pavonine.render.diagnostics import Diagnostics
from pavonine.schemas.mtlx_types import SDF_TYPES, mtlx_input_value

ROOT = "/MaterialX/Materials"  # where usdMtlx puts a document's materials
_LAYERS: dict[tuple[str, float], Sdf.Layer] = {}  # kept alive: references name them by identifier


def translate(doc, stage: Usd.Stage, material_name: str, root: str = "/Looks") -> UsdShade.Material:
    """The UsdShade Material for ``doc``'s ``surfacematerial`` ``material_name`` (see module doc)."""
    material = UsdShade.Material.Define(stage, f"{root}/{prim_name(material_name)}")
    outputs: dict[tuple[str, str, str], UsdShade.Output] = {}
    graphs: dict[str, UsdShade.NodeGraph] = {}

    def graph_prim(graph) -> UsdShade.NodeGraph:
        name = graph.getName()
        if name not in graphs:
            graphs[name] = UsdShade.NodeGraph.Define(
                stage, material.GetPath().AppendChild(prim_name(name))
            )
        return graphs[name]

    def set_value(usd_input, inp) -> None:
        if inp.getType() == "filename":
            resolved = inp.getResolvedValueString()
            folder = Path(inp.getDocument().getSourceUri() or ".").parent
            path = resolved if Path(resolved).is_absolute() else str(folder / resolved)
            prefix = os.path.normpath(inp.getActiveFilePrefix() or ".")
            name = os.path.normpath(inp.getValueString())
            if prefix != "." and name.startswith(prefix + os.sep):  # the name holds the prefix:
                path = str(folder / name)  # once, as usdMtlx read usd-wg's MaterialXTest
            usd_input.Set(Sdf.AssetPath(path))
        else:
            usd_input.Set(mtlx_input_value(inp))
        space = inp.getActiveColorSpace()
        if space and inp.getType() == "filename":
            usd_input.GetAttr().SetColorSpace(space)

    def feed(usd_input, inp, scope, graph) -> None:
        """Connect or set ``usd_input`` as the MaterialX input ``inp`` (inside ``graph``) says."""
        if inp.getNodeGraphString():
            other = inp.getDocument().getNodeGraph(inp.getNodeGraphString())
            usd_input.ConnectToSource(graph_output(other, inp.getOutputString() or "out"))
        elif inp.getNodeName():
            node = scope.getNode(inp.getNodeName())
            usd_input.ConnectToSource(node_output(node, graph, inp.getOutputString() or "out"))
        elif inp.getInterfaceName() and graph is not None:
            outer = graph.getInput(inp.getInterfaceName())
            prim = graph_prim(graph)
            interface = prim.GetInput(outer.getName()) or prim.CreateInput(
                outer.getName(), SDF_TYPES[outer.getType()]
            )
            if outer.getValueString():
                set_value(interface, outer)
            usd_input.ConnectToSource(interface)
        elif inp.getValueString():
            set_value(usd_input, inp)

    def graph_output(graph, name: str) -> UsdShade.Output:
        key = (graph.getName(), "", name)
        if key not in outputs:
            prim = graph_prim(graph)
            out = graph.getOutput(name)
            usd_output = prim.CreateOutput(
                name, SDF_TYPES.get(out.getType(), Sdf.ValueTypeNames.Token)
            )
            outputs[key] = usd_output
            feed(usd_output, out, graph, graph)
        return outputs[key]

    def node_output(node, graph, name: str) -> UsdShade.Output:
        scope = graph.getName() if graph is not None else ""
        key = (scope, node.getName(), name)
        if key in outputs:
            return outputs[key]
        parent = graph_prim(graph).GetPath() if graph is not None else material.GetPath()
        shader = UsdShade.Shader.Define(stage, parent.AppendChild(prim_name(node.getName())))
        nodedef = node.getNodeDef()
        if nodedef is None:
            raise ValueError(
                f"MaterialX node {node.getName()!r} ({node.getCategory()}) has no definition"
            )
        shader.SetShaderId(nodedef.getName())
        for out in nodedef.getActiveOutputs():
            outputs[(scope, node.getName(), out.getName())] = shader.CreateOutput(
                out.getName(), SDF_TYPES.get(out.getType(), Sdf.ValueTypeNames.Token)
            )
        for inp in node.getInputs():
            usd_input = shader.CreateInput(
                inp.getName(), SDF_TYPES.get(inp.getType(), Sdf.ValueTypeNames.Token)
            )
            feed(usd_input, inp, graph if graph is not None else node.getDocument(), graph)
        return outputs[(scope, node.getName(), name)]

    mx_material = doc.getNode(material_name)
    for terminal, kind in (("surfaceshader", "surface"), ("displacementshader", "displacement")):
        inp = mx_material.getInput(terminal)
        if inp is None or not inp.getNodeName():
            continue
        node = doc.getNode(inp.getNodeName())
        out = node_output(node, None, "out")
        if kind == "surface":
            material.CreateSurfaceOutput("mtlx").ConnectToSource(out)
        else:
            material.CreateDisplacementOutput("mtlx").ConnectToSource(out)
    return material


def prim_name(name: str) -> str:
    """A MaterialX element name as a USD prim name."""
    clean = "".join(c if c.isalnum() or c == "_" else "_" for c in name)
    return clean if clean[:1].isalpha() or clean[:1] == "_" else f"_{clean}"


def document_layer(path: str) -> Sdf.Layer:
    """usdMtlx's layer of the MaterialX document at ``path`` (cached while the file is unchanged);
    raises ``ValueError`` for a document MaterialX cannot read or a node without a definition."""
    import MaterialX as mx

    from pavonine.materials import materialx

    key = (path, os.path.getmtime(path))
    if key in _LAYERS:
        return _LAYERS[key]
    doc = mx.createDocument()
    try:
        mx.readFromXmlFile(doc, path)
    except Exception as exc:  # MaterialX raises its own ExceptionParseError, ExceptionFileMissing
        raise ValueError(f"MaterialX cannot read it: {exc}") from None
    doc.importLibrary(materialx.load_libraries())
    layer = Sdf.Layer.CreateAnonymous(f"{Path(path).name}.usda")
    stage = Usd.Stage.Open(layer)
    UsdGeom.Scope.Define(stage, "/MaterialX")
    UsdGeom.Scope.Define(stage, ROOT)
    for material in doc.getMaterialNodes():
        translate(doc, stage, material.getName(), ROOT)
    layer.defaultPrim = "MaterialX"
    _LAYERS[key] = layer
    return layer


def substitute_references(stage: Usd.Stage, diag: Diagnostics) -> set[str]:
    """Reference the translation of every ``.mtlx`` document that a reference or payload in the
    stage's root layer stack names (see module doc); the documents' absolute paths."""
    arcs: list[tuple[Sdf.Path, str, Sdf.Path, Sdf.LayerOffset]] = []
    for layer in stage.GetLayerStack(includeSessionLayers=False):

        def visit(path: Sdf.Path, layer: Sdf.Layer = layer) -> None:
            if not path.IsPrimPath() or path.ContainsPrimVariantSelection():
                return
            spec = layer.GetPrimAtPath(path)
            for listop in (spec.referenceList, spec.payloadList):
                for op in ("explicitItems", "prependedItems", "appendedItems", "addedItems"):
                    for item in getattr(listop, op):
                        if item.assetPath.lower().endswith(".mtlx"):
                            absolute = Sdf.ComputeAssetPathRelativeToLayer(layer, item.assetPath)
                            target = item.primPath
                            arcs.append((path, absolute, target, item.layerOffset))

        layer.Traverse(layer.pseudoRoot.path, visit)
    done: set[str] = set()
    session = stage.GetSessionLayer()
    for prim_path, absolute, target, offset in arcs:
        resolved = str(Ar.GetResolver().Resolve(absolute)) or absolute
        if not os.path.isfile(resolved):
            continue  # a missing document keeps its composition error
        try:
            translated = document_layer(resolved)
        except ValueError as exc:
            diag.warn(
                str(prim_path), f"MaterialX document {absolute}: {exc}; its materials are missing"
            )
            continue
        target = target if not target.isEmpty else Sdf.Path(f"/{translated.defaultPrim}")
        if translated.GetPrimAtPath(target) is None:
            continue  # the target prim is not in the document: the composition error stands
        over = Sdf.CreatePrimInLayer(session, prim_path)
        over.referenceList.Prepend(Sdf.Reference(translated.identifier, target, offset))
        done.update({absolute, resolved})
    return done
