"""``pavonine export ASSET -o X.usdc``: the asset as one USD layer that hosts without Pavonine
show as Pavonine's preview does (docs/pipeline.md, "Portable USD export").

The asset is composed with the chosen ``lod`` and ``geometry`` variants and flattened into one
layer (:meth:`Usd.Stage.Flatten`: every payload, reference and variant baked in, asset paths made
relative to the output's folder so the maps and textures still resolve). Every ribbon
``BasisCurves`` prim (curves with authored ``normals``: the barbs) then becomes, at the same path,
a triangle ``Mesh``: the flat ribbon of the curves' authored width facing their normals, exactly
the tessellation Pavonine's renderer draws for USD ribbons (its plain ribbon, handed in by the
application as ``tessellate``: :func:`pavonine.render.curves.ribbons.plain_ribbons`, the same
vertices the glTF export writes; :mod:`pavonine.pipeline.export.ribbons`), with its vertex normals, ``displayColor`` (the bake's
colour), ``displayOpacity`` where authored, the barb id per triangle, and an all-purpose
``material:binding`` to the curves' preview material (``material:binding:preview``, the
asset's ``FeatherBarbsPreview``: ``UsdPreviewSurface`` whose diffuse colour is a
``UsdPrimvarReader_float3`` of ``displayColor``), or to a new one like it when none is bound.

Why a mesh: Blender 5.3's USD importer brings curves in as round hair curves (it ignores
``normals``) and binds no material to them, while a mesh keeps its normals and its binding, and
the importer turns the primvar reader into an Attribute node reading ``displayColor`` into the
Principled BSDF's Base Color (``benchmarks/blender_barbs.py``). The asset itself keeps the
curves: Pavonine renders the barbs with their barbules from them.
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from pavonine.base.commit import atomic_path
from pavonine.base.errors import InputError
from pavonine.pipeline.bake.asset import root_layer_path
from pavonine.pipeline.convert.asset import author_polygons
from pavonine.pipeline.export.ribbons import Tessellate
from pavonine.pipeline.export.selection import open_selected
from pavonine.schemas.primvars import BARB_ID_PRIMVAR

#: Output suffixes the portable export writes (crate or text USD).
SUFFIXES = (".usd", ".usdc", ".usda")
#: Curve primvars carried to the ribbon mesh (the rest are Pavonine's shading inputs).
CARRIED = ("displayColor", "displayOpacity", BARB_ID_PRIMVAR)
#: Where a preview material is authored when the curves bind none (under the default prim).
PREVIEW_PATH = "Materials/FeatherBarbsPreview"
#: Curve properties kept on the mesh that replaces them (the rest are the curves' own).
KEPT = ("visibility", "purpose", "proxyPrim", "xformOpOrder")


@dataclass
class PortableReport:
    """What :func:`export_portable_usd` wrote."""

    asset: str
    output: str
    lod: str | None
    geometry: str | None
    meshes: list[dict] = field(default_factory=list)
    materials: list[str] = field(default_factory=list)
    bytes: int = 0

    def as_dict(self) -> dict:
        return asdict(self)


def is_portable_target(output: str | os.PathLike) -> bool:
    """True when ``output`` names a USD layer (the portable export), not a ``.glb``."""
    return Path(output).suffix.lower() in SUFFIXES


def export_portable_usd(
    asset: str | os.PathLike,
    output: str | os.PathLike,
    tessellate: Tessellate,
    lod: str | None = None,
    geometry: str | None = None,
) -> PortableReport:
    """Write ``asset`` with ``lod`` and ``geometry`` selected (default: its own) to ``output``,
    its ribbon curves as preview-bound meshes drawn by ``tessellate`` (module docstring);
    written atomically."""
    from pxr import Sdf, Usd, UsdGeom, UsdUtils

    output = Path(output)
    if not is_portable_target(output):
        raise InputError(str(output), f"the portable export must be one of {', '.join(SUFFIXES)}")
    root = root_layer_path(asset)
    stage, default = open_selected(root, lod, geometry)
    report = PortableReport(
        str(root),
        str(output),
        default.GetVariantSet("lod").GetVariantSelection() or None,
        default.GetVariantSet("geometry").GetVariantSelection() or None,
    )
    flat = stage.Flatten()
    folder = output.resolve().parent
    UsdUtils.ModifyAssetPaths(flat, lambda path: _relative(path, folder))
    portable = Usd.Stage.Open(flat)
    for prim in [p for p in portable.Traverse() if p.IsA(UsdGeom.BasisCurves)]:
        surface = tessellate(prim)
        if surface is not None:  # ribbons (tubes stay curves)
            report.meshes.append(
                replace_with_ribbon_mesh(portable, prim, surface, report.materials)
            )
    suffix = output.suffix.lower()
    with atomic_path(output) as tmp:
        layer = Sdf.Layer.CreateNew(
            str(tmp), args={"format": "usda" if suffix == ".usda" else "usdc"}
        )
        layer.TransferContent(flat)
        layer.Save()
    report.bytes = output.stat().st_size
    return report


def _relative(path: str, folder: Path) -> str:
    """An absolute asset path (Flatten anchors them) relative to the output's folder."""
    if not path or not os.path.isabs(path) or "[" in path:
        return path
    relative = os.path.relpath(path, folder)
    return relative if relative.startswith("..") else f"./{relative}"


def replace_with_ribbon_mesh(stage, prim, surface, materials: list[str]) -> dict:
    """Replace the ribbon curves ``prim`` by ``surface`` (their ribbon, as :data:`Tessellate`
    draws it) as a mesh at the same path, bound to their preview material (its path appended to
    ``materials`` once); the report row."""
    from pxr import UsdGeom, UsdShade

    where = str(prim.GetPath())
    material = _preview_material(stage, prim)
    spec = stage.GetRootLayer().GetPrimAtPath(prim.GetPath())
    for prop in list(spec.properties):
        if prop.name not in KEPT and not prop.name.startswith("xformOp"):
            spec.RemoveProperty(prop)
    spec.typeName = "Mesh"
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath(prim.GetPath()))
    topology = surface.topology
    counts = topology.face_vertex_counts
    author_polygons(
        mesh, topology.points, counts, topology.face_vertex_indices, surface.normals.values
    )
    _carry_primvars(mesh, surface)
    mesh.GetPrim().SetDocumentation(
        "Barbs as flat ribbon triangles (pavonine export: the renderer's ribbon tessellation of "
        "the BasisCurves at their authored width), coloured by displayColor for any host."
    )
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(material)
    key = str(material.GetPath())
    if key not in materials:
        materials.append(key)
    return {"path": where, "vertices": len(topology.points), "triangles": len(counts)}


def _carry_primvars(mesh, surface) -> None:
    """The :data:`CARRIED` primvars the renderer sampled onto the ribbon, as it carries them
    (``vertex`` per mesh point, ``uniform`` per triangle, ``constant`` as authored)."""
    from pxr import Sdf, UsdGeom, Vt

    api = UsdGeom.PrimvarsAPI(mesh)
    kinds = {
        "displayColor": (Sdf.ValueTypeNames.Color3fArray, Vt.Vec3fArray, np.float32),
        "displayOpacity": (Sdf.ValueTypeNames.FloatArray, Vt.FloatArray, np.float32),
        BARB_ID_PRIMVAR: (Sdf.ValueTypeNames.IntArray, Vt.IntArray, np.int32),
    }
    for name in CARRIED:
        primvar = surface.primvars.get(name)
        if primvar is None:
            continue
        kind, array, dtype = kinds[name]
        values = np.asarray(primvar.values)
        values = np.rint(values) if dtype is np.int32 else values
        values = values[:, 0] if values.shape[1] == 1 else values
        api.CreatePrimvar(name, kind, primvar.interpolation).Set(
            array.FromNumpy(values.astype(dtype))
        )


def _preview_material(stage, prim):
    """The curves' own preview-purpose material (``material:binding:preview``), else the
    default prim's :data:`PREVIEW_PATH`, authored as :func:`author_barbs_preview` if absent."""
    from pxr import Sdf, UsdShade

    from pavonine.pipeline.convert.barb_layer import author_barbs_preview

    preview = UsdShade.MaterialBindingAPI(prim).GetDirectBinding(UsdShade.Tokens.preview)
    if preview.GetMaterial():
        return preview.GetMaterial()
    path = stage.GetDefaultPrim().GetPath().AppendPath(Sdf.Path(PREVIEW_PATH))
    existing = UsdShade.Material(stage.GetPrimAtPath(path))
    return existing if existing else author_barbs_preview(stage, path)
