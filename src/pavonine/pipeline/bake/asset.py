"""``pavonine bake``: re-bake an existing feather asset in place.

For every ``PavonineFeatherAPI`` material under the asset's default prim: the meshes bound to
it (render and default purpose, the ``lod`` variant set to ``high`` when there is one) are read
back into :class:`~pavonine.pipeline.convert.mesh.MeshData`, its maps through USD's asset
resolver, and :class:`~pavonine.pipeline.shading.looks.Looks` bakes the textures, writes the
MaterialX document and re-authors the materials in the layer that defines the feather material
(each file written atomically; the layer saved by rename).

An asset in a folder of its own (``NAME/NAME.usd``, as ``pavonine convert`` writes it) is baked
as one commit: the folder is copied to a hidden staging folder beside it, baked there, and
exchanged with the original in one atomic step (:mod:`pavonine.base.commit`), so a crash
or a full disk leaves the old asset whole. Any other root layer is baked in place, file by file.

Only a feather asset's root layer is baked: its default prim a ``component`` model, every feather
material defined in a layer inside the root layer's folder (bake writes nowhere else), not a
``.usdz`` package. Every material's inputs (parameters, maps and their aspects) are checked
before the first file is written.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pavonine.base.errors import TEMPORARY_MARK, InputError
from pavonine.pipeline.convert.asset import BARB_TANGENT, FEATHER_UV
from pavonine.pipeline.convert.mesh import MeshData

PORTABLE_SUFFIX = "Portable"  # Feather → FeatherPortable, as pavonine convert names it


@dataclass
class BakeReport:
    """What :func:`bake_asset` did: per feather material its meshes and written files."""

    asset: str
    resolution: int
    materials: list[dict] = field(default_factory=list)

    def as_dict(self) -> dict:
        return {"asset": self.asset, "resolution": self.resolution, "materials": self.materials}


def root_layer_path(asset: str | os.PathLike) -> Path:
    """The asset's root layer: ``asset`` itself, or ``<folder>/<folder name>.usd``."""
    path = Path(asset)
    if path.is_dir():
        path = path / f"{path.name}.usd"
    if not path.is_file():
        raise InputError(str(path), "no such USD file")
    return path


def _primvar(mesh_prim, name: str, interpolations: tuple[str, ...]) -> np.ndarray:
    from pxr import UsdGeom

    primvar = UsdGeom.PrimvarsAPI(mesh_prim).GetPrimvar(name)
    where = f"{mesh_prim.GetPath()}: primvars:{name}"
    if not primvar or not primvar.HasValue():
        raise InputError(where, "missing (bake needs a mesh written by pavonine convert)")
    if primvar.GetInterpolation() not in interpolations:
        raise InputError(
            where, f"interpolation {primvar.GetInterpolation()!r}, expected {interpolations}"
        )
    return np.asarray(primvar.Get(), dtype=np.float64)


def mesh_data(mesh_prim) -> MeshData:
    """A triangle mesh with the primvars baking needs (``st`` face-varying, feather coordinate
    and barb direction per vertex, vertex normals); :class:`InputError` naming what is missing."""
    from pxr import UsdGeom

    mesh = UsdGeom.Mesh(mesh_prim)
    where = str(mesh_prim.GetPath())
    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get() or [], dtype=np.int64)
    if len(counts) == 0 or np.any(counts != 3):
        raise InputError(f"{where}: faceVertexCounts", "bake needs a triangle mesh")
    faces = np.asarray(mesh.GetFaceVertexIndicesAttr().Get(), dtype=np.int64).reshape(-1, 3)
    points = np.asarray(mesh.GetPointsAttr().Get(), dtype=np.float64)
    normals = mesh.GetNormalsAttr().Get()
    if normals is None or len(normals) != len(points):
        raise InputError(f"{where}: normals", "bake needs one normal per vertex")
    st_primvar = UsdGeom.PrimvarsAPI(mesh_prim).GetPrimvar("st")
    st = _primvar(mesh_prim, "st", ("faceVarying",))
    indices = st_primvar.GetIndices()
    st_indices = np.asarray(indices, dtype=np.int64) if indices else np.arange(len(st))
    if len(st_indices) != faces.size:
        raise InputError(f"{where}: primvars:st", "needs one value per face corner")
    return MeshData(
        mesh_prim.GetName(),
        points,
        faces,
        np.asarray(normals, dtype=np.float64),
        _primvar(mesh_prim, FEATHER_UV, ("vertex", "varying")),
        _primvar(mesh_prim, BARB_TANGENT, ("vertex", "varying")),
        st,
        st_indices,
    )


def merge(meshes: list[MeshData]) -> MeshData:
    """One mesh from several (indices offset), for meshes sharing one material and atlas."""
    if len(meshes) == 1:
        return meshes[0]
    offsets = np.cumsum([0] + [len(m.points) for m in meshes[:-1]])
    st_offsets = np.cumsum([0] + [len(m.st_values) for m in meshes[:-1]])
    return MeshData(
        meshes[0].name,
        np.concatenate([m.points for m in meshes]),
        np.concatenate([m.faces + o for m, o in zip(meshes, offsets, strict=True)]),
        np.concatenate([m.normals for m in meshes]),
        np.concatenate([m.feather_uv for m in meshes]),
        np.concatenate([m.barb_tangent for m in meshes]),
        np.concatenate([m.st_values for m in meshes]),
        np.concatenate([m.st_indices + o for m, o in zip(meshes, st_offsets, strict=True)]),
    )


def _open(root: Path):
    """The stage at ``root`` and its default prim, refused unless it is a feather asset's root
    layer: a component model (as ``pavonine convert`` writes it) with a feather material."""
    from pxr import Kind, Tf, Usd

    import pavonine  # noqa: F401  (registers the schema)

    try:
        stage = Usd.Stage.Open(str(root))
    except Tf.ErrorException as exc:
        raise InputError(str(root), f"cannot open USD stage: {str(exc).strip()}") from None
    default = stage.GetDefaultPrim() if stage else None
    if not default:
        raise InputError(str(root), "no defaultPrim: bake works on a component asset")
    kind = Usd.ModelAPI(default).GetKind()
    if kind != Kind.Tokens.component:
        raise InputError(
            str(root),
            f"not a feather asset's root layer: its default prim {default.GetPath()} is of kind "
            f"{kind or 'none'!r}, not 'component' (bake works on an asset pavonine convert wrote)",
        )
    lod = default.GetVariantSet("lod")
    if "high" in lod.GetVariantNames():
        with Usd.EditContext(stage, stage.GetSessionLayer()):
            lod.SetVariantSelection("high")
    return stage, default


def bound_meshes(stage, default, material) -> list:
    """The mesh prims under ``default`` (render or default purpose) bound to ``material``."""
    from pxr import Usd, UsdGeom, UsdShade

    found = []
    for prim in Usd.PrimRange(default):
        if not prim.IsA(UsdGeom.Mesh):
            continue
        if UsdGeom.Imageable(prim).ComputePurpose() not in (
            UsdGeom.Tokens.default_,
            UsdGeom.Tokens.render,
        ):
            continue
        bound, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
        if bound and bound.GetPath() == material.GetPath():
            found.append(prim)
    return found


def _edit_target(prim):
    """An edit target on the strongest file layer holding a spec of ``prim``, through the
    composition arc (reference, payload) that brings that layer in, so that edits made on
    the composed stage land in it at the right paths."""
    from pxr import Usd

    nodes = [prim.GetPrimIndex().rootNode]
    while nodes:
        node = nodes.pop(0)
        for layer in node.layerStack.layers:
            if not layer.anonymous and layer.GetPrimAtPath(node.path):
                return Usd.EditTarget(layer, node), layer
        nodes.extend(node.children)
    raise InputError(str(prim.GetPath()), "no file layer defines this material")


def save_layer(layer) -> None:
    """Save ``layer`` by exporting a temporary file beside it and renaming it into place."""
    path = Path(layer.realPath)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    try:
        if not layer.Export(tmp):
            raise OSError(f"{path}: cannot write")
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    layer.Reload(force=True)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def bake_asset(asset: str | os.PathLike, resolution: int, report=None) -> BakeReport:
    """Re-bake every feather material of ``asset`` (see the module docstring): an asset folder
    of its own in one atomic commit, any other root layer in place."""
    from pavonine.base.commit import staged_folder

    root = root_layer_path(asset)
    if root.suffix.lower() == ".usdz":
        raise InputError(
            str(root),
            "a .usdz package cannot be baked: bake needs the unpacked asset (its folder or root "
            "layer); bake that, then pavonine package it again",
        )
    folder = root.parent
    if root.name != f"{folder.name}.usd":
        return _bake_in_place(root, resolution, report)
    folder = Path(os.path.abspath(folder))  # errors name USD's absolute paths inside staging
    with staged_folder(folder, replace=True, subject=folder.name) as staging:
        shutil.copytree(
            folder, staging, symlinks=True, dirs_exist_ok=True,
            ignore=lambda _, names: [n for n in names if TEMPORARY_MARK in n],
        )  # fmt: skip
        result = _bake_in_place(staging / root.name, resolution, report)
    from pxr import Sdf

    replaced = Path(os.path.realpath(folder))
    for layer in Sdf.Layer.GetLoadedLayers():  # this process's cache of the files just replaced
        if layer.realPath and Path(os.path.realpath(layer.realPath)).is_relative_to(replaced):
            layer.Reload(force=True)
    relocated = json.loads(json.dumps(result.as_dict()).replace(str(staging), str(folder)))
    return BakeReport(str(root), resolution, relocated["materials"])


@dataclass
class _Job:
    """One feather material to bake, its inputs read and checked before anything is written."""

    material: object
    meshes: list
    params: object
    maps: dict
    paths: dict
    target: object
    layer: object


def _material_layer(root: Path, material):
    """The edit target and layer of ``material``'s definition, refused (naming ``root``) unless
    the layer is a file inside the asset's own folder, the only place bake writes."""
    from pxr import Ar

    target, layer = _edit_target(material.GetPrim())
    folder = Path(os.path.realpath(root.parent))
    real = layer.realPath
    inside = bool(real) and Path(os.path.realpath(real)).is_relative_to(folder)
    if not inside or Ar.IsPackageRelativePath(real) or layer.GetFileFormat().IsPackage():
        raise InputError(
            str(root),
            f"not a feather asset's root layer: its material {material.GetPath()} is defined in "
            f"{real or layer.identifier}, outside the asset's folder {root.parent}",
        )
    return target, layer


def _job(root: Path, stage, default, material) -> _Job:
    """``material``'s meshes, parameters and maps, read and checked (:class:`InputError`)."""
    where = str(material.GetPath())
    target, layer = _material_layer(root, material)
    meshes = bound_meshes(stage, default, material)
    if not meshes:
        raise InputError(where, "no mesh is bound to this material")
    params, maps, paths = feather_inputs(material)
    return _Job(material, meshes, params, maps, paths, target, layer)


def feather_inputs(material) -> tuple[object, dict, dict]:
    """A feather material's validated parameters, its maps (grey images by key) and their
    authored asset paths; :class:`InputError` naming the attribute or file at fault."""
    from pavonine.base.asset_io import local_file
    from pavonine.base.map_files import check_aspects, read_data_map
    from pavonine.materials.parameters import ParameterError
    from pavonine.schemas import authoring
    from pavonine.schemas.authoring import parameter_input_error

    try:
        params = authoring.read_feather_parameters(material).validate()
    except ParameterError as exc:
        raise parameter_input_error(material.GetPrim(), exc) from None
    maps, paths, fields = {}, {}, {}
    for key, resolved in authoring.resolve_maps(material).items():
        if resolved is None:
            continue
        name = authoring.MAP_ATTRS[key]
        fields[key] = f"{resolved}: {name}"
        try:
            maps[key] = read_data_map(local_file(resolved), name).values
        except OSError:
            raise InputError(fields[key], "not found") from None
        paths[key] = material.GetPrim().GetAttribute(name).Get().path
    check_aspects(maps, fields)
    return params, maps, paths


def _bake_in_place(root: Path, resolution: int, report=None) -> BakeReport:
    """Re-bake every feather material of the stage at ``root``, editing its files in place:
    every material's inputs are checked before the first file is written."""
    from pxr import Usd, UsdShade

    from pavonine.pipeline.shading.looks import Looks
    from pavonine.pipeline.shading.usd import bind
    from pavonine.schemas import authoring

    stage, default = _open(root)
    materials = [
        UsdShade.Material(p)
        for p in Usd.PrimRange(default)
        if p.IsA(UsdShade.Material) and authoring.SCHEMA_NAME in p.GetAppliedSchemas()
    ]
    if not materials:
        raise InputError(str(root), "no PavonineFeatherAPI material under the default prim")
    jobs = [_job(root, stage, default, material) for material in materials]
    result = BakeReport(str(root), resolution)
    for job in jobs:
        material, meshes, layer = job.material, job.meshes, job.layer
        where = str(material.GetPath())
        if report:
            report(where)
        folder = Path(layer.realPath).parent
        vane = merge([mesh_data(prim) for prim in meshes])
        looks = Looks.bake(
            folder, default.GetName(), vane, job.maps, job.paths, job.params, resolution
        )
        portable_path = (
            material.GetPath()
            .GetParentPath()
            .AppendChild(material.GetPath().name + PORTABLE_SUFFIX)
        )
        with Usd.EditContext(stage, job.target):
            feather, portable = looks.author(stage, material.GetPath(), portable_path)
            for prim in meshes:
                bind(stage.OverridePrim(prim.GetPath()), feather, portable)
        save_layer(layer)
        result.materials.append(
            {
                "material": where,
                "portable": str(portable_path),
                "meshes": [str(p.GetPath()) for p in meshes],
                "layer": layer.realPath,
                "textures": looks.textures,
                "mtlx": str(folder / f"{default.GetName()}.mtlx"),
            }
        )
    return result
