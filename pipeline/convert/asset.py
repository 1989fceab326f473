"""Write a feather as a USD component asset (usd-wg asset-structure guidelines).

Layout of ``OUTDIR/NAME/`` (every path inside is ``./``-relative, so the folder is movable)::

    NAME.usd                 root layer (text): defaultPrim /NAME (Xform, kind = component,
                             assetInfo, extentsHint), metersPerUnit 0.01, upAxis Y; references
                             the material layer; variant set "lod" = high | medium | low, each
                             variant payloads one geometry layer
    NAME_material.usda       /NAME/Materials/Feather (PavonineFeatherAPI, via
                             pavonine.schemas.authoring) and /NAME/Materials/Rachis
    NAME_geo_<lod>.usdc      /NAME/Geom/Vane and /NAME/Geom/Rachis meshes, bound to the materials
    maps/<map>.<ext>         the six maps as read: single-channel 16-bit PNG (half EXR for
                             float sources), RGB sources reduced to Rec. 709 luma

The whole folder is first written beside its destination under a hidden temporary name and
renamed into place only when complete (:func:`staging_folder`, :func:`commit_asset`).
"""

from __future__ import annotations

import errno
import os
import shutil
import tempfile
from collections.abc import Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pavonine.materials.parameters import FeatherParameters
from pavonine.pipeline.convert.mesh import MeshData
from pavonine.pipeline.errors import InputError
from pavonine.pipeline.maps.io import DataMap, write_map

LODS = ("high", "medium", "low")
METERS_PER_UNIT = 0.01  # centimetres
UP_AXIS = "Y"
FEATHER_UV = "pavonine:featherUV"
BARB_TANGENT = "pavonine:barbTangent"
#: Keratin-brown of the rachis (linear sRGB), a UsdPreviewSurface material.
RACHIS_COLOR = (0.42, 0.33, 0.22)


@dataclass(frozen=True)
class AssetNames:
    """File names inside an asset folder."""

    name: str

    @property
    def root(self) -> str:
        return f"{self.name}.usd"

    @property
    def material(self) -> str:
        return f"{self.name}_material.usda"

    def geometry(self, lod: str) -> str:
        return f"{self.name}_geo_{lod}.usdc"


def _layer_metadata(stage, name: str) -> None:
    from pxr import UsdGeom

    UsdGeom.SetStageMetersPerUnit(stage, METERS_PER_UNIT)
    UsdGeom.SetStageUpAxis(stage, UP_AXIS)
    stage.SetDefaultPrim(stage.GetPrimAtPath(f"/{name}"))


def _new_stage(path: Path, *, text: bool = False):
    from pxr import Sdf, Usd

    args = {"format": "usda"} if text else {}
    layer = Sdf.Layer.CreateNew(str(path), args)
    if layer is None:
        raise OSError(f"{path}: cannot create USD layer")
    return Usd.Stage.Open(layer)


def write_geometry_layer(
    path: Path, name: str, meshes: Sequence[MeshData], bindings: Mapping[str, str]
) -> np.ndarray:
    """Write one LOD's meshes (crate) under ``/NAME/Geom``; returns their joint extent.

    Each mesh gets points, triangles, vertex normals, ``extent``, ``primvars:st`` (indexed,
    face-varying: the xatlas atlas), ``primvars:pavonine:featherUV`` (float2, vertex: map
    coordinates) and ``primvars:pavonine:barbTangent`` (vector3f, vertex: barb direction), and a
    ``material:binding`` to ``bindings[mesh.name]``.
    """
    from pxr import Sdf, UsdGeom, UsdShade, Vt

    stage = _new_stage(path)
    root = UsdGeom.Xform.Define(stage, f"/{name}")
    UsdGeom.Scope.Define(stage, f"/{name}/Geom")
    _layer_metadata(stage, name)
    extents = []
    for mesh in meshes:
        prim_path = f"/{name}/Geom/{mesh.name}"
        usd_mesh = UsdGeom.Mesh.Define(stage, prim_path)
        points = mesh.points.astype(np.float32)
        usd_mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(points))
        usd_mesh.CreateFaceVertexCountsAttr(
            Vt.IntArray.FromNumpy(np.full(len(mesh.faces), 3, dtype=np.int32))
        )
        usd_mesh.CreateFaceVertexIndicesAttr(
            Vt.IntArray.FromNumpy(mesh.faces.astype(np.int32).ravel())
        )
        usd_mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        usd_mesh.CreateDoubleSidedAttr(True)
        usd_mesh.CreateNormalsAttr(Vt.Vec3fArray.FromNumpy(mesh.normals.astype(np.float32)))
        usd_mesh.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
        extent = np.stack([points.min(axis=0), points.max(axis=0)])
        usd_mesh.CreateExtentAttr(Vt.Vec3fArray.FromNumpy(extent.astype(np.float32)))
        extents.append(extent)
        primvars = UsdGeom.PrimvarsAPI(usd_mesh)
        st = primvars.CreatePrimvar(
            "st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying
        )
        st.Set(Vt.Vec2fArray.FromNumpy(mesh.st_values.astype(np.float32)))
        st.SetIndices(Vt.IntArray.FromNumpy(mesh.st_indices.astype(np.int32)))
        feather_uv = primvars.CreatePrimvar(
            FEATHER_UV, Sdf.ValueTypeNames.Float2Array, UsdGeom.Tokens.vertex
        )
        feather_uv.Set(Vt.Vec2fArray.FromNumpy(mesh.feather_uv.astype(np.float32)))
        tangent = primvars.CreatePrimvar(
            BARB_TANGENT, Sdf.ValueTypeNames.Vector3fArray, UsdGeom.Tokens.vertex
        )
        tangent.Set(Vt.Vec3fArray.FromNumpy(mesh.barb_tangent.astype(np.float32)))
        binding = UsdShade.MaterialBindingAPI.Apply(usd_mesh.GetPrim())
        binding.GetDirectBindingRel().SetTargets([Sdf.Path(bindings[mesh.name])])
    extent = np.stack(
        [np.min([e[0] for e in extents], axis=0), np.max([e[1] for e in extents], axis=0)]
    )
    del root
    stage.GetRootLayer().Save()
    return extent


def write_material_layer(
    path: Path, name: str, params: FeatherParameters, maps: Mapping[str, str]
) -> dict[str, str]:
    """Write the material layer; returns ``{mesh name: material path}`` for the bindings.

    The feather material is authored by ``pavonine.schemas.authoring.create_feather_material``
    (PavonineFeatherAPI + derived MaterialX and UsdPreviewSurface shaders), whose preview alpha
    texture reads ``primvars:pavonine:featherUV``: the maps are in feather space, not the atlas ``st``.
    """
    from pxr import Gf, Sdf, UsdGeom, UsdShade

    import pavonine  # noqa: F401  (registers the schema plugin before USD builds its registry)
    from pavonine.schemas import authoring

    stage = _new_stage(path, text=True)
    UsdGeom.Xform.Define(stage, f"/{name}")
    UsdGeom.Scope.Define(stage, f"/{name}/Materials")
    _layer_metadata(stage, name)
    feather_path = f"/{name}/Materials/Feather"
    material = authoring.create_feather_material(stage, feather_path, params, maps)
    material.GetPrim().SetDocumentation(
        "Peacock-feather barbules (Imamura et al.); maps are read at primvars:pavonine:featherUV."
    )
    rachis_path = f"/{name}/Materials/Rachis"
    rachis = UsdShade.Material.Define(stage, rachis_path)
    shader = UsdShade.Shader.Define(stage, f"{rachis_path}/PreviewSurface")
    shader.SetShaderId("UsdPreviewSurface")
    shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*RACHIS_COLOR))
    shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(0.55)
    shader.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(0.0)
    rachis.CreateSurfaceOutput().ConnectToSource(
        shader.CreateOutput("surface", Sdf.ValueTypeNames.Token)
    )
    stage.GetRootLayer().Save()
    return {"Vane": feather_path, "Rachis": rachis_path}


def write_root_layer(
    path: Path, name: str, version: str, extent: np.ndarray, default_lod: str = "high"
) -> None:
    """Root layer: component model, assetInfo, the material reference and the ``lod`` variants."""
    from pxr import Gf, Kind, Sdf, Usd, UsdGeom, Vt

    names = AssetNames(name)
    stage = _new_stage(path, text=True)
    root = UsdGeom.Xform.Define(stage, f"/{name}")
    prim = root.GetPrim()
    _layer_metadata(stage, name)
    Usd.ModelAPI(prim).SetKind(Kind.Tokens.component)
    model = Usd.ModelAPI(prim)
    model.SetAssetName(name)
    model.SetAssetVersion(version)
    model.SetAssetIdentifier(Sdf.AssetPath(f"./{names.root}"))
    UsdGeom.ModelAPI.Apply(prim).SetExtentsHint(
        Vt.Vec3fArray([Gf.Vec3f(*map(float, extent[0])), Gf.Vec3f(*map(float, extent[1]))])
    )
    prim.GetReferences().AddReference(f"./{names.material}")
    variant_set = prim.GetVariantSets().AddVariantSet("lod")
    for lod in LODS:
        variant_set.AddVariant(lod)
        variant_set.SetVariantSelection(lod)
        with variant_set.GetVariantEditContext():
            prim.GetPayloads().AddPayload(f"./{names.geometry(lod)}")
    variant_set.SetVariantSelection(default_lod)
    stage.GetRootLayer().documentation = (
        f"Pavonine feather asset {name!r}: vane + rachis, three LODs, PavonineFeatherAPI material."
    )
    stage.GetRootLayer().Save()


def write_maps(maps: Mapping[str, DataMap], folder: Path) -> dict[str, str]:
    """Write the maps as read (single-channel data, RGB already reduced to luma) into
    ``folder/maps``; returns their ``./maps/<name><ext>`` asset paths.

    The asset holds exactly the values the geometry was built from, so every reader (renderer,
    validator, DCC) sees one channel whatever the source file had: 16-bit PNG, or half-float
    EXR for float sources, tagged ``Raw`` (:func:`pavonine.pipeline.maps.io.write_map`).
    """
    out = {}
    for key, data in maps.items():
        target = folder / "maps" / f"{key}{data.suffix}"
        write_map(target, data.values, description=f"pavonine {key} map (paper section 3.3)")
        out[key] = f"./maps/{target.name}"
    return out


def _existing_ancestor(path: Path) -> Path:
    """``path`` itself or its nearest ancestor that exists."""
    path = Path(os.path.abspath(path))
    while not os.path.lexists(path) and path != path.parent:
        path = path.parent
    return path


def check_outdir(outdir: Path) -> None:
    """Raise :class:`InputError` when ``outdir`` cannot be a folder (a file on its path)."""
    ancestor = _existing_ancestor(outdir)
    if not ancestor.is_dir():
        raise InputError(str(outdir), f"cannot make this folder: {ancestor} is not a folder")


@contextmanager
def staging_folder(outdir: Path, name: str, force: bool):
    """Yield a hidden temporary folder for ``outdir/name``; on success it is renamed into place
    (replacing an existing asset only with ``force``); on failure it is removed.

    The folder sits in ``outdir``, or while that does not exist in its nearest existing
    ancestor (the same file system, so the final rename is atomic): ``outdir`` is created only
    when the asset is committed, and a failed conversion leaves nothing behind.
    """
    target = outdir / name
    if target.exists() and not force:
        raise InputError(str(target), "asset exists; pass --force to replace it")
    check_outdir(outdir)
    staging = Path(tempfile.mkdtemp(prefix=f".{name}.tmp-", dir=_existing_ancestor(outdir)))
    umask = os.umask(0)
    os.umask(umask)
    staging.chmod(0o777 & ~umask)  # mkdtemp makes 0700; an asset folder is shared
    try:
        yield staging
        outdir.mkdir(parents=True, exist_ok=True)
        commit_asset(staging, target, force)
    finally:
        if staging.exists():
            shutil.rmtree(staging, ignore_errors=True)


def commit_asset(staging: Path, target: Path, force: bool = False) -> None:
    """Move a finished asset folder into place; an existing asset is replaced only with ``force``.

    Without ``force`` the single ``rename`` is the existence check: the kernel refuses to
    rename a folder onto a non-empty folder or a file, so of two writers racing for one name
    the second fails instead of replacing the first.
    """
    if not force:
        try:
            os.rename(staging, target)
        except OSError as exc:
            if exc.errno in (errno.EEXIST, errno.ENOTEMPTY, errno.ENOTDIR, errno.EISDIR):
                raise InputError(str(target), "asset exists; pass --force to replace it") from None
            raise
        return
    if not target.exists():
        os.replace(staging, target)
        return
    old = Path(tempfile.mkdtemp(prefix=f".{target.name}.old-", dir=target.parent))
    old.rmdir()
    os.replace(target, old)
    try:
        os.replace(staging, target)
    except OSError:
        os.replace(old, target)
        raise
    shutil.rmtree(old, ignore_errors=True)


def write_asset(
    folder: Path,
    name: str,
    version: str,
    params: FeatherParameters,
    maps: Mapping[str, DataMap],
    lods: Mapping[str, Sequence[MeshData]],
) -> Path:
    """Write every layer of the asset into ``folder`` (a staging folder); returns the root."""
    names = AssetNames(name)
    maps = write_maps(maps, folder)
    bindings = write_material_layer(folder / names.material, name, params, maps)
    extents = {}
    for lod in LODS:
        extents[lod] = write_geometry_layer(folder / names.geometry(lod), name, lods[lod], bindings)
    write_root_layer(folder / names.root, name, version, extents["high"])
    return folder / names.root
