"""Write a feather as a USD component asset (usd-wg asset-structure guidelines).

Layout of ``OUTDIR/NAME/`` (every path inside is ``./``-relative, so the folder is movable)::

    NAME.usd                 root layer (text): defaultPrim /NAME (Xform, kind = component,
                             assetInfo, extentsHint per purpose), metersPerUnit 0.01, upAxis Y;
                             references the material layer; variant set "lod" = high | medium |
                             low, each variant payloads one geometry layer as /NAME/Geom
                             (purpose render); /NAME/Proxy payloads the low one (purpose proxy)
    NAME_material.usda       /NAME/Materials/Feather (PavonineFeatherAPI, via
                             pavonine.schemas.authoring; MaterialX network reading the maps;
                             baked UsdPreviewSurface), /NAME/Materials/FeatherPortable (OpenPBR
                             from the baked textures; baked UsdPreviewSurface) and
                             /NAME/Materials/Rachis; the bindings of Geom and Proxy meshes
    NAME_geo_<lod>.usdc      /NAME/Geom/Vane and /NAME/Geom/Rachis meshes
    NAME_geo_barbs.usdc      /NAME/Geom/Barbs: every barb as a BasisCurves ribbon
                             (pavonine.pipeline.convert.barb_layer); the root layer's variant
                             set "geometry" = sheet (default) | barbs payloads it in the barbs
                             variant and deactivates /NAME/Geom/Vane there
    NAME.mtlx                the MaterialX document of the two feather materials, and
    pavonine_feather.mtlx    Pavonine's node definition it includes
    maps/<map>.<ext>         the six maps as read: single-channel 16-bit PNG (half EXR for
                             float sources), RGB sources reduced to Rec. 709 luma
    textures/*.png           the baked textures (pavonine.pipeline.bake.textures)

The whole folder is first written inside OUTDIR under a hidden temporary name and committed
only when complete (:func:`staging_folder`, :func:`commit_asset`): renamed into place, or
exchanged with the old asset in one atomic step (:mod:`pavonine.base.commit`).
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pavonine.base.commit import commit_folder, staged_folder
from pavonine.base.errors import InputError
from pavonine.base.map_files import DataMap, write_map
from pavonine.base.truncation import save_whole
from pavonine.materials.parameters import FeatherParameters
from pavonine.pipeline.convert.mesh import MeshData
from pavonine.schemas.primvars import BARB_TANGENT_PRIMVAR, FEATHER_UV_PRIMVAR

LODS = ("high", "medium", "low")
#: The ``geometry`` variant set: the painted sheet (default) or every barb as a ribbon.
GEOMETRY_VARIANTS = ("sheet", "barbs")
PROXY_LOD = "low"
METERS_PER_UNIT = 0.01  # centimetres
UP_AXIS = "Y"
FEATHER_UV = FEATHER_UV_PRIMVAR
BARB_TANGENT = BARB_TANGENT_PRIMVAR
GEOM = "Geom"
PROXY = "Proxy"
#: Mesh name → the material it is bound to (the preview-purpose binding in brackets below).
MESH_MATERIALS = {"Vane": "Feather", "Rachis": "Rachis"}
PREVIEW_MATERIALS = {"Vane": "FeatherPortable"}
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

    @property
    def mtlx(self) -> str:
        return f"{self.name}.mtlx"

    def geometry(self, lod: str) -> str:
        return f"{self.name}_geo_{lod}.usdc"

    @property
    def barbs(self) -> str:
        return f"{self.name}_geo_barbs.usdc"


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


def author_polygons(
    usd_mesh, points: np.ndarray, counts: np.ndarray, indices: np.ndarray, normals: np.ndarray
) -> None:
    """A mesh's polygons as the assets write them: float32 points, int32 face counts and
    indices, vertex normals, ``extent``, no subdivision, double-sided."""
    from pxr import UsdGeom, Vt

    points = points.astype(np.float32)
    usd_mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(points))
    usd_mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(counts.astype(np.int32)))
    usd_mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(indices.astype(np.int32)))
    usd_mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    usd_mesh.CreateDoubleSidedAttr(True)
    usd_mesh.CreateNormalsAttr(Vt.Vec3fArray.FromNumpy(normals.astype(np.float32)))
    usd_mesh.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
    extent = np.stack([points.min(axis=0), points.max(axis=0)])
    usd_mesh.CreateExtentAttr(Vt.Vec3fArray.FromNumpy(extent))


def write_geometry_layer(path: Path, name: str, meshes: Sequence[MeshData]) -> None:
    """Write one LOD's meshes (crate) under ``/NAME/Geom``.

    Each mesh gets points, triangles, vertex normals, ``extent``, ``primvars:st`` (indexed,
    face-varying: the xatlas atlas), ``primvars:pavonine_featherUV`` (texCoord2f, vertex: map
    coordinates) and ``primvars:pavonine_barbTangent`` (vector3f, vertex: barb direction). The
    material layer binds them (the same layer is also the asset's proxy, at another path).
    """
    from pxr import Sdf, UsdGeom, Vt

    stage = _new_stage(path)
    root = UsdGeom.Xform.Define(stage, f"/{name}")
    UsdGeom.Scope.Define(stage, f"/{name}/{GEOM}")
    _layer_metadata(stage, name)
    for mesh in meshes:
        prim_path = f"/{name}/{GEOM}/{mesh.name}"
        usd_mesh = UsdGeom.Mesh.Define(stage, prim_path)
        counts = np.full(len(mesh.faces), 3)
        author_polygons(usd_mesh, mesh.points, counts, mesh.faces.ravel(), mesh.normals)
        primvars = UsdGeom.PrimvarsAPI(usd_mesh)
        st = primvars.CreatePrimvar(
            "st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying
        )
        st.Set(Vt.Vec2fArray.FromNumpy(mesh.st_values.astype(np.float32)))
        st.SetIndices(Vt.IntArray.FromNumpy(mesh.st_indices.astype(np.int32)))
        feather_uv = primvars.CreatePrimvar(
            FEATHER_UV, Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.vertex
        )
        feather_uv.Set(Vt.Vec2fArray.FromNumpy(mesh.feather_uv.astype(np.float32)))
        tangent = primvars.CreatePrimvar(
            BARB_TANGENT, Sdf.ValueTypeNames.Vector3fArray, UsdGeom.Tokens.vertex
        )
        tangent.Set(Vt.Vec3fArray.FromNumpy(mesh.barb_tangent.astype(np.float32)))
    del root
    save_whole(stage.GetRootLayer(), path)


def write_material_layer(
    path: Path,
    name: str,
    params: FeatherParameters,
    maps: Mapping[str, str],
    looks=None,
    barbs: bool = False,
) -> None:
    """Write the material layer: the feather material (``PavonineFeatherAPI`` by
    ``pavonine.schemas.authoring.create_feather_material``), with ``looks`` (a
    :class:`pavonine.pipeline.shading.looks.Looks`) its MaterialX network, baked preview and
    portable twin; the rachis material; and every mesh's binding, for ``Geom`` and ``Proxy``.
    With ``barbs``: also the barbs' preview material (their ``displayColor``,
    :func:`pavonine.pipeline.convert.barb_layer.author_barbs_preview`), bound by the root layer's
    ``barbs`` variant."""
    from pxr import Gf, Sdf, UsdGeom, UsdShade

    import pavonine  # noqa: F401  (registers the schema plugin before USD builds its registry)
    from pavonine.pipeline.shading.usd import bind
    from pavonine.schemas import authoring

    stage = _new_stage(path, text=True)
    UsdGeom.Xform.Define(stage, f"/{name}")
    UsdGeom.Scope.Define(stage, f"/{name}/Materials")
    _layer_metadata(stage, name)
    materials_path = Sdf.Path(f"/{name}/Materials")
    feather = authoring.create_feather_material(
        stage, materials_path.AppendChild("Feather"), params, maps
    )
    feather.GetPrim().SetDocumentation(
        "Peacock-feather barbules (Imamura et al.); maps are read at primvars:pavonine_featherUV."
    )
    materials = {"Feather": feather}
    if looks is not None:
        portable_path = materials_path.AppendChild("FeatherPortable")
        materials["Feather"], materials["FeatherPortable"] = looks.author(
            stage, feather.GetPath(), portable_path
        )
    rachis_path = materials_path.AppendChild("Rachis")
    rachis = UsdShade.Material.Define(stage, rachis_path)
    shader = UsdShade.Shader.Define(stage, rachis_path.AppendChild("PreviewSurface"))
    shader.SetShaderId("UsdPreviewSurface")
    shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*RACHIS_COLOR))
    shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(0.55)
    shader.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(0.0)
    rachis.CreateSurfaceOutput().ConnectToSource(
        shader.CreateOutput("surface", Sdf.ValueTypeNames.Token)
    )
    materials["Rachis"] = rachis
    for scope in (GEOM, PROXY):
        for mesh, material in MESH_MATERIALS.items():
            prim = stage.OverridePrim(f"/{name}/{scope}/{mesh}")
            preview = materials.get(PREVIEW_MATERIALS.get(mesh, ""))
            bind(prim, materials[material], preview)
    if barbs:
        from pavonine.pipeline.convert.barb_layer import BARBS_PREVIEW, author_barbs_preview

        author_barbs_preview(stage, materials_path.AppendChild(BARBS_PREVIEW))
    save_whole(stage.GetRootLayer(), path)


def write_root_layer(
    path: Path, name: str, version: str, default_lod: str = "high", barbs: bool = False
) -> None:
    """Root layer: component model, assetInfo, the material reference, the ``lod`` variants
    (``Geom``, purpose render), with ``barbs`` the ``geometry`` variants (sheet | barbs, default
    sheet), the proxy (``Proxy``, the low LOD), and ``extentsHint``."""
    from pxr import Kind, Sdf, Usd, UsdGeom

    names = AssetNames(name)
    stage = _new_stage(path, text=True)
    root = UsdGeom.Xform.Define(stage, f"/{name}")
    prim = root.GetPrim()
    _layer_metadata(stage, name)
    model = Usd.ModelAPI(prim)
    model.SetKind(Kind.Tokens.component)
    model.SetAssetName(name)
    model.SetAssetVersion(version)
    model.SetAssetIdentifier(Sdf.AssetPath(f"./{names.root}"))
    prim.GetReferences().AddReference(f"./{names.material}")
    variant_set = prim.GetVariantSets().AddVariantSet("lod")
    for lod in LODS:
        variant_set.AddVariant(lod)
        variant_set.SetVariantSelection(lod)
        with variant_set.GetVariantEditContext():
            prim.GetPayloads().AddPayload(f"./{names.geometry(lod)}")
    variant_set.SetVariantSelection(default_lod)
    if barbs:
        _author_geometry_variants(prim, names)
    geom = UsdGeom.Imageable(stage.OverridePrim(f"/{name}/{GEOM}"))
    geom.CreatePurposeAttr(UsdGeom.Tokens.render)
    proxy = UsdGeom.Scope.Define(stage, f"/{name}/{PROXY}")
    proxy.GetPrim().GetPayloads().AddPayload(
        Sdf.Payload(f"./{names.geometry(PROXY_LOD)}", Sdf.Path(f"/{name}/{GEOM}"))
    )
    proxy.CreatePurposeAttr(UsdGeom.Tokens.proxy)
    geom.GetProxyPrimRel().SetTargets([proxy.GetPath()])
    stage.GetRootLayer().documentation = (
        f"Pavonine feather asset {name!r}: vane + rachis, three LODs (the low one also the "
        "proxy), PavonineFeatherAPI material with baked textures and MaterialX twins."
    )
    save_whole(stage.GetRootLayer(), path)
    set_extents_hint(path, name)


def _author_geometry_variants(prim, names: AssetNames) -> None:
    """The ``geometry`` variant set: ``sheet`` as the ``lod`` variants make it, ``barbs`` with the
    barbs' layer payloaded, bound (the feather material; preview purpose: their displayColor)
    and the sheet's vane deactivated (the rachis stays). Nothing of the barbs is in ``sheet``."""
    from pxr import UsdShade

    from pavonine.pipeline.convert.barb_layer import BARBS, BARBS_PREVIEW
    from pavonine.pipeline.shading.usd import bind

    stage = prim.GetStage()
    base = prim.GetPath()
    variant_set = prim.GetVariantSets().AddVariantSet("geometry")
    for variant in GEOMETRY_VARIANTS:
        variant_set.AddVariant(variant)
    variant_set.SetVariantSelection("barbs")
    with variant_set.GetVariantEditContext():
        prim.GetPayloads().AddPayload(f"./{names.barbs}")
        stage.OverridePrim(base.AppendPath(f"{GEOM}/Vane")).SetActive(False)
        materials = base.AppendChild("Materials")
        bind(
            stage.OverridePrim(base.AppendPath(f"{GEOM}/{BARBS}")),
            UsdShade.Material(stage.GetPrimAtPath(materials.AppendChild("Feather"))),
            UsdShade.Material(stage.GetPrimAtPath(materials.AppendChild(BARBS_PREVIEW))),
        )
    variant_set.SetVariantSelection(GEOMETRY_VARIANTS[0])


def set_extents_hint(root_path: Path, name: str) -> None:
    """Author ``extentsHint`` on the model from its composed bounds, one box per purpose
    (``UsdGeom.ModelAPI.ComputeExtentsHint``), so ``drawMode`` cards and bounds need no payload."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(root_path))
    prim = stage.GetPrimAtPath(f"/{name}")
    purposes = UsdGeom.Imageable.GetOrderedPurposeTokens()
    cache = UsdGeom.BBoxCache(Usd.TimeCode.Default(), purposes, useExtentsHint=False)
    model = UsdGeom.ModelAPI.Apply(prim)
    model.SetExtentsHint(model.ComputeExtentsHint(cache))
    save_whole(stage.GetRootLayer(), root_path)


def map_paths(maps: Mapping[str, DataMap]) -> dict[str, str]:
    """The ``./maps/<name><ext>`` asset paths :func:`write_maps` writes the maps to."""
    return {key: f"./maps/{key}{data.suffix}" for key, data in maps.items()}


def write_maps(maps: Mapping[str, DataMap], folder: Path) -> dict[str, str]:
    """Write the maps as read (single-channel data, RGB already reduced to luma) into
    ``folder/maps``; returns their ``./maps/<name><ext>`` asset paths.

    The asset holds exactly the values the geometry was built from, so every reader (renderer,
    validator, DCC) sees one channel whatever the source file had: 16-bit PNG, or half-float
    EXR for float sources, tagged ``Raw`` (:func:`pavonine.base.map_files.write_map`; PNG
    compressed for speed, :data:`~pavonine.base.map_files.FAST_PNG`: maps can be big).
    """
    out = map_paths(maps)

    def write(key: str) -> None:
        description = f"pavonine {key} map (paper section 3.3)"
        write_map(folder / out[key][2:], maps[key].values, description=description, fast=True)

    in_threads(write, list(maps))
    return out


def in_threads(work, items: Sequence) -> list:
    """``[work(item) for item in items]`` on up to one thread per core (OpenImageIO and NumPy
    release the GIL while they code images: six 8192-pixel maps take 2.5 s of CPU each to write
    and 1.5 s to read); the results in order, the first failing item's error raised."""
    from concurrent.futures import ThreadPoolExecutor

    workers = max(1, min(len(items), os.cpu_count() or 1))
    if workers == 1:
        return [work(item) for item in items]
    with ThreadPoolExecutor(workers) as pool:
        return list(pool.map(work, items))


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
def staging_folder(outdir: Path, name: str, force: bool, subject: str | None = None):
    """Yield a hidden temporary folder inside ``outdir`` for ``outdir/name``; on success it is
    committed (replacing an existing asset only with ``force``; :func:`commit_asset`); on
    failure it is removed.

    ``outdir`` is created first, so nothing is written outside it, and removed again if the
    conversion fails and it is still empty: a failed conversion leaves nothing behind. Write
    errors (a full disk, a file-size limit, USD failing to save a layer) are one-line
    :class:`InputError` naming ``outdir/name``. See :mod:`pavonine.base.commit`.
    """
    target = outdir / name
    if target.exists() and not force:
        raise InputError(str(target), "asset exists; pass --force to replace it")
    check_outdir(outdir)
    try:
        with staged_folder(target, replace=force, subject=subject or name) as staging:
            yield staging
    except FileExistsError:
        raise InputError(str(target), "asset exists; pass --force to replace it") from None


def commit_asset(staging: Path, target: Path, force: bool = False) -> None:
    """Move a finished asset folder into place; an existing asset is replaced only with ``force``
    (in one atomic step: :func:`pavonine.base.commit.commit_folder`).

    Without ``force`` the single ``rename`` is the existence check: the kernel refuses to
    rename a folder onto a non-empty folder or a file, so of two writers racing for one name
    the second fails instead of replacing the first.
    """
    try:
        commit_folder(staging, target, replace=force)
    except FileExistsError:
        raise InputError(str(target), "asset exists; pass --force to replace it") from None


def write_asset(
    folder: Path,
    name: str,
    version: str,
    params: FeatherParameters,
    maps: Mapping[str, DataMap],
    lods: Mapping[str, Sequence[MeshData]],
    looks=None,
    barbs=None,
) -> Path:
    """Write every layer of the asset into ``folder`` (a staging folder); returns the root.

    ``looks`` (:class:`pavonine.pipeline.shading.looks.Looks`, after it wrote its files into
    ``folder``) adds the MaterialX networks and the baked previews; ``barbs``
    (:class:`pavonine.pipeline.convert.barb_polylines.BarbCurves`) the ``geometry = barbs`` variant.
    """
    names = AssetNames(name)
    map_paths = write_maps(maps, folder)
    has_barbs = barbs is not None
    write_material_layer(folder / names.material, name, params, map_paths, looks, has_barbs)
    for lod in LODS:
        write_geometry_layer(folder / names.geometry(lod), name, lods[lod])
    if has_barbs:
        from pavonine.pipeline.convert.barb_layer import write_barbs_layer

        write_barbs_layer(folder / names.barbs, name, barbs, GEOM)
    write_root_layer(folder / names.root, name, version, barbs=has_barbs)
    return folder / names.root
