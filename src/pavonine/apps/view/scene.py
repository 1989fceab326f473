"""What ``pavonine view`` draws: a USD stage (an asset, or a scene of several) read into meshes,
materials, a camera, a sun and a sky, in world space and the stage's units.

Meshes of default and render purpose (proxies and guides skipped), ``PointInstancer``
prototypes with their instance transforms (the train), the ``lod`` and ``geometry`` variants as
the page selects them. Feather materials (``PavonineFeatherAPI``) carry their parameters as a
BRDF table (:mod:`pavonine.apps.view.tables`) and their maps; any other material shows its
``UsdPreviewSurface`` diffuse colour. Everything the page may fetch is listed in
:attr:`ViewScene.files` (served by id, never by path).
"""

from __future__ import annotations

import functools
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pavonine.base.errors import InputError
from pavonine.pipeline.export.framing import framing, stage_bound

#: Variant sets the page offers (the asset's level of detail; barbs or sheet).
VIEW_VARIANT_SETS = ("lod", "geometry")
#: Per-instance feather primvars the renderer reads and the page does not (named in a warning).
INSTANCE_PRIMVARS = ("pavonine:gradationOffset", "pavonine:structuralScale")
#: Neutral grey for meshes without a preview colour.
DEFAULT_COLOR = (0.18, 0.18, 0.18)


@dataclass
class MeshBuffers:
    """One mesh in world space: float32 arrays per vertex and uint32 triangle indices."""

    path: str
    material: int
    position: np.ndarray
    normal: np.ndarray
    index: np.ndarray
    feather_uv: np.ndarray | None = None
    barb: np.ndarray | None = None
    instances: np.ndarray | None = None  # (n, 16): USD row-vector matrices, flattened
    instance_feather: np.ndarray | None = None  # (n, 2): gradation offset, structural scale

    def payload(self) -> tuple[dict, bytes]:
        """``(layout, bytes)``: each array's byte offset and length in the binary buffer."""
        layout, chunks, offset = {}, [], 0
        arrays = {
            "position": self.position.astype("<f4"),
            "normal": self.normal.astype("<f4"),
            "uv": None if self.feather_uv is None else self.feather_uv.astype("<f4"),
            "barb": None if self.barb is None else self.barb.astype("<f4"),
            "instances": None if self.instances is None else self.instances.astype("<f4"),
            "instanceFeather": None
            if self.instance_feather is None
            else self.instance_feather.astype("<f4"),
            "index": self.index.astype("<u4"),
        }
        for name, array in arrays.items():
            if array is None:
                continue
            data = np.ascontiguousarray(array).tobytes()
            layout[name] = [offset, array.size]
            chunks.append(data)
            offset += len(data)
        return layout, b"".join(chunks)


@dataclass
class ViewScene:
    """The stage as the page draws it (see the module docstring)."""

    stage_path: Path
    meshes: list[MeshBuffers]
    materials: list[dict]
    camera: dict
    sun: dict
    sky: dict
    variants: dict
    units: float
    files: dict[str, Path] = field(default_factory=dict)
    tables: list = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    def description(self) -> dict:
        """The JSON of ``/api/scene.json``."""
        meshes = []
        for i, m in enumerate(self.meshes):
            layout, _ = m.payload()
            meshes.append({"id": i, "path": m.path, "material": m.material, "layout": layout})
        return {
            "stage": str(self.stage_path),
            "meshes": meshes,
            "materials": self.materials,
            "camera": self.camera,
            "sun": self.sun,
            "sky": self.sky,
            "variants": self.variants,
            "metersPerUnit": self.units,
            "warnings": self.warnings,
        }


def stage_path(path: str | os.PathLike) -> Path:
    """The root layer to open: ``path``, or ``<folder>/<folder name>.usd`` for a folder."""
    from pavonine.pipeline.bake.asset import root_layer_path

    return root_layer_path(path).resolve()


def open_stage(path: Path, selections: dict[str, str] | None = None):
    """Open ``path`` with the page's variant selections in the session layer."""
    from pxr import Tf, Usd

    try:
        stage = Usd.Stage.Open(str(path))
    except Tf.ErrorException as exc:
        first = str(exc).strip().splitlines()[-1] if str(exc).strip() else "cannot be opened"
        raise InputError(str(path), first) from None
    if stage is None:
        raise InputError(str(path), "cannot be opened as a USD stage")
    if selections:
        with Usd.EditContext(stage, stage.GetSessionLayer()):
            for prim in stage.Traverse():
                sets = prim.GetVariantSets()
                for name, choice in selections.items():
                    if (
                        sets.HasVariantSet(name)
                        and choice in sets.GetVariantSet(name).GetVariantNames()
                    ):
                        sets.GetVariantSet(name).SetVariantSelection(choice)
    return stage


def _variants(stage) -> dict:
    found: dict[str, dict] = {}
    for prim in stage.Traverse():
        sets = prim.GetVariantSets()
        for name in VIEW_VARIANT_SETS:
            if sets.HasVariantSet(name) and name not in found:
                vs = sets.GetVariantSet(name)
                found[name] = {
                    "choices": vs.GetVariantNames(),
                    "selection": vs.GetVariantSelection(),
                }
    return found


def _triangles(counts: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """Fan triangulation of polygons, ``(m, 3)`` vertex indices."""
    if np.all(counts == 3):
        return indices.reshape(-1, 3)
    tris, start = [], 0
    for c in counts:
        tris += [
            (indices[start], indices[start + j], indices[start + j + 1]) for j in range(1, c - 1)
        ]
        start += c
    return np.asarray(tris, dtype=np.int64).reshape(-1, 3)


def _vertex_normals(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    n = np.zeros_like(points)
    a, b, c = (points[faces[:, i]] for i in range(3))
    face_n = np.cross(b - a, c - a)
    for i in range(3):
        np.add.at(n, faces[:, i], face_n)
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-20)


def _vertex_primvar(prim, names: tuple[str, ...], count: int) -> np.ndarray | None:
    from pxr import UsdGeom

    api = UsdGeom.PrimvarsAPI(prim)
    for name in names:
        pv = api.GetPrimvar(name)
        if pv and pv.HasValue() and pv.GetInterpolation() in ("vertex", "varying"):
            values = np.asarray(pv.ComputeFlattened(), dtype=np.float64)
            if len(values) == count:
                return values
    return None


def _mesh(prim, world: np.ndarray, material: int, feather: bool) -> MeshBuffers | None:
    """A mesh prim's buffers with ``world`` (USD row-vector matrix) applied."""
    from pxr import UsdGeom

    from pavonine.render.shading.feather import BARB_TANGENT, FEATHER_UV, LEGACY_PRIMVARS

    mesh = UsdGeom.Mesh(prim)
    points = np.asarray(mesh.GetPointsAttr().Get() or [], dtype=np.float64)
    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get() or [], dtype=np.int64)
    indices = np.asarray(mesh.GetFaceVertexIndicesAttr().Get() or [], dtype=np.int64)
    if len(points) == 0 or len(counts) == 0:
        return None
    faces = _triangles(counts, indices)
    normals = mesh.GetNormalsAttr().Get()
    if normals is not None and len(normals) == len(points):
        normals = np.asarray(normals, dtype=np.float64)
    else:
        normals = _vertex_normals(points, faces)
    linear = world[:3, :3]
    normal_matrix = np.linalg.inv(linear)  # row vectors: n' = n · (M⁻¹)ᵀ ᵀ
    position = points @ linear + world[3, :3]
    normal = normals @ normal_matrix.T
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-20)
    uv = barb = None
    if feather:
        uv = _vertex_primvar(prim, (FEATHER_UV, LEGACY_PRIMVARS[FEATHER_UV]), len(points))
        barb = _vertex_primvar(prim, (BARB_TANGENT, LEGACY_PRIMVARS[BARB_TANGENT]), len(points))
        barb = None if barb is None else barb @ linear
    return MeshBuffers(str(prim.GetPath()), material, position, normal, faces, uv, barb)


@functools.lru_cache(maxsize=8)
def _table(params):
    from pavonine.apps.view.tables import build_table

    return build_table(params)


class _Materials:
    """Materials in first-seen order, and the files their maps name."""

    def __init__(self, scene_files: dict[str, Path], warnings: list[str]):
        self.index: dict[str, int] = {}
        self.entries: list[dict] = []
        self.tables: list = []
        self.files = scene_files
        self.warnings = warnings

    def of(self, prim) -> tuple[int, bool]:
        from pxr import UsdShade

        from pavonine.render.shading.feather import is_feather_material

        material, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
        key = str(material.GetPath()) if material else ""
        if key in self.index:
            i = self.index[key]
            return i, self.entries[i]["kind"] == "feather"
        entry = (
            self._feather(material)
            if material and is_feather_material(material)
            else self._preview(material)
        )
        entry.update(id=len(self.entries), path=key)
        self.index[key] = len(self.entries)
        self.entries.append(entry)
        return entry["id"], entry["kind"] == "feather"

    def _feather(self, material) -> dict:
        from pavonine.materials.parameters import ParameterError
        from pavonine.schemas import authoring
        from pavonine.schemas.authoring import parameter_input_error

        try:
            params = authoring.read_feather_parameters(material).validate()
        except ParameterError as exc:
            raise parameter_input_error(material.GetPrim(), exc) from None
        table = _table(params)
        self.tables.append(table)
        maps = {}
        for name, file in authoring.resolve_maps(material).items():
            if not file:
                continue
            served = self._map_file(material, name, Path(file))
            if served:
                maps[name] = served
        return {
            "kind": "feather",
            "table": f"/api/table/{len(self.tables) - 1}.bin",
            "albedo": f"/api/albedo/{len(self.tables) - 1}.bin",
            "tableMeta": table.meta(),
            "maps": maps,
        }

    def _map_file(self, material, name: str, file: Path) -> str | None:
        """The URL of a map, if it is a readable file inside the folder of the layer naming it."""
        from pavonine.base.limits import check_image

        layer_dirs = [
            Path(spec.layer.realPath).resolve().parent
            for spec in material.GetPrim().GetPrimStack()
            if spec.layer.realPath
        ]
        real = file.resolve()
        if not any(real.is_relative_to(d) for d in layer_dirs):
            self.warnings.append(f"{material.GetPath()}: {name} map {file} lies outside its asset")
            return None
        try:
            check_image(str(real))
        except InputError as exc:
            raise InputError(str(file), f"{name} map: {exc.message}") from None
        except OSError as exc:
            raise InputError(str(file), f"{name} map: {exc.strerror or exc}") from None
        key = f"{len(self.files)}/{real.name}"
        self.files[key] = real
        return f"/files/{key}"

    @staticmethod
    def _preview(material) -> dict:
        color = DEFAULT_COLOR
        if material:
            shader = material.ComputeSurfaceSource()[0]
            if shader:
                value = shader.GetInput("diffuseColor")
                got = value.Get() if value and not value.HasConnectedSource() else None
                if got is not None:
                    color = tuple(float(c) for c in got)
        return {"kind": "preview", "color": list(color)}


def _world(cache, prim) -> np.ndarray:
    return np.array(cache.GetLocalToWorldTransform(prim), dtype=np.float64)


def _camera(stage, cache, lo: np.ndarray, hi: np.ndarray) -> dict:
    from pxr import UsdGeom, UsdRender

    prim = None
    settings = UsdRender.Settings.GetStageRenderSettings(stage)
    if settings:
        targets = settings.GetCameraRel().GetForwardedTargets()
        prim = stage.GetPrimAtPath(targets[0]) if targets else None
    if prim is None:
        prim = next((p for p in stage.Traverse() if p.IsA(UsdGeom.Camera)), None)
    if prim is None:
        eye, centre, _ = framing(lo, hi)
        return {"eye": eye.tolist(), "target": centre.tolist(), "fov": 39.6, "path": None}
    cam = UsdGeom.Camera(prim).GetCamera()
    m = _world(cache, prim)
    eye, forward = m[3, :3], -m[2, :3] / np.linalg.norm(m[2, :3])
    depth = max(float(np.dot((lo + hi) / 2.0 - eye, forward)), 1e-3)
    fov = 2.0 * math.degrees(math.atan(0.5 * cam.verticalAperture / cam.focalLength))
    return {
        "eye": eye.tolist(),
        "target": (eye + forward * depth).tolist(),
        "fov": fov,
        "path": str(prim.GetPath()),
    }


def _lights(stage, cache, warnings: list[str]) -> tuple[dict, dict]:
    from pxr import UsdLux

    from pavonine.render.lights.common import cone_solid_angle

    sun = {"direction": [0.4226, 0.0, 0.9063], "irradiance": [math.pi] * 3, "path": None}
    sky = {"radiance": [0.06, 0.08, 0.11], "path": None}
    for prim in stage.Traverse():
        if prim.IsA(UsdLux.DistantLight) and sun["path"] is None:
            light = UsdLux.DistantLight(prim)
            L = _light_radiance(light)
            angle = float(light.GetAngleAttr().Get() or 0.0)
            normalize = bool(light.GetNormalizeAttr().Get())
            e = L if normalize or angle < 1e-3 else L * cone_solid_angle(angle)
            d = _world(cache, prim)[2, :3]
            sun = {
                "direction": (d / np.linalg.norm(d)).tolist(),
                "irradiance": e.tolist(),
                "path": str(prim.GetPath()),
            }
        elif prim.IsA(UsdLux.DomeLight) and sky["path"] is None:
            light = UsdLux.DomeLight(prim)
            if light.GetTextureFileAttr().Get():
                warnings.append(f"{prim.GetPath()}: the dome's texture is shown as its colour")
            sky = {"radiance": _light_radiance(light).tolist(), "path": str(prim.GetPath())}
    return sun, sky


def _light_radiance(light) -> np.ndarray:
    intensity = float(light.GetIntensityAttr().Get() or 0.0)
    exposure = float(light.GetExposureAttr().Get() or 0.0)
    color = np.asarray(light.GetColorAttr().Get() or (1.0, 1.0, 1.0), dtype=np.float64)
    return intensity * 2.0**exposure * color


def read_scene(path: str | os.PathLike, selections: dict[str, str] | None = None) -> ViewScene:
    """Read the stage at ``path`` (asset folder or root layer, or a scene) for the page."""
    from pxr import Usd, UsdGeom

    root = stage_path(path)
    stage = open_stage(root, selections)
    time = Usd.TimeCode.Default()
    cache = UsdGeom.XformCache(time)
    warnings: list[str] = []
    files: dict[str, Path] = {}
    materials = _Materials(files, warnings)
    meshes: list[MeshBuffers] = []
    instanced: set[str] = set()
    it = iter(Usd.PrimRange(stage.GetPseudoRoot()))
    for prim in it:
        purpose = UsdGeom.Imageable(prim).ComputePurpose() if prim.IsA(UsdGeom.Imageable) else ""
        if purpose in (UsdGeom.Tokens.proxy, UsdGeom.Tokens.guide):
            it.PruneChildren()
            continue
        if prim.IsA(UsdGeom.PointInstancer):
            meshes += _instancer(prim, cache, materials, time)
            instanced.add(str(prim.GetPath()))
            it.PruneChildren()
            continue
        if prim.IsA(UsdGeom.Mesh):
            material, feather = materials.of(prim)
            mesh = _mesh(prim, _world(cache, prim), material, feather)
            if mesh is not None:
                meshes.append(mesh)
    if not meshes:
        raise InputError(str(root), "has no mesh to show (default or render purpose)")
    lo, hi = stage_bound(stage)
    _, centre, radius = framing(lo, hi)
    sun, sky = _lights(stage, cache, warnings)
    return ViewScene(
        stage_path=root,
        meshes=meshes,
        materials=materials.entries,
        camera={
            **_camera(stage, cache, lo, hi),
            "centre": centre.tolist(),
            "radius": radius,
        },
        sun=sun,
        sky=sky,
        variants=_variants(stage),
        units=float(UsdGeom.GetStageMetersPerUnit(stage)),
        files=files,
        tables=materials.tables,
        warnings=warnings,
    )


def _instance_primvars(prim, warnings: list[str]) -> np.ndarray:
    """Per instance ``(gradation offset, structural scale)``, as the renderer reads them
    (:mod:`pavonine.render.instance_primvars`; neutral 0 and 1 where not authored)."""
    from pxr import UsdGeom

    count = len(UsdGeom.PointInstancer(prim).GetProtoIndicesAttr().Get() or [])
    out = np.tile(np.array([0.0, 1.0]), (count, 1))
    api = UsdGeom.PrimvarsAPI(prim)
    for column, name in enumerate(INSTANCE_PRIMVARS):
        pv = api.GetPrimvar(name)
        if not pv or not pv.HasValue():
            continue
        values = np.asarray(pv.ComputeFlattened(), dtype=np.float64).ravel()
        if pv.GetInterpolation() in ("constant", "uniform") and len(values) == 1:
            out[:, column] = values[0]
        elif len(values) == count:
            out[:, column] = values
        else:
            warnings.append(
                f"{prim.GetPath()}: primvars:{name} has {len(values)} values for "
                f"{count} instances; not shown"
            )
    return out


def _instancer(prim, cache, materials: _Materials, time) -> list[MeshBuffers]:
    """Each prototype mesh of a PointInstancer once, with the instances' world matrices."""
    from pxr import Usd, UsdGeom

    instancer = UsdGeom.PointInstancer(prim)
    per_instance = _instance_primvars(prim, materials.warnings)
    xforms = np.asarray(instancer.ComputeInstanceTransformsAtTime(time, time), dtype=np.float64)
    indices = np.asarray(instancer.GetProtoIndicesAttr().Get() or [], dtype=np.int64)
    world = _world(cache, prim)
    out = []
    for p, target in enumerate(instancer.GetPrototypesRel().GetForwardedTargets()):
        chosen = xforms[indices == p] @ world if len(xforms) else np.zeros((0, 4, 4))
        proto = prim.GetStage().GetPrimAtPath(target)
        proto_world = _world(cache, proto)
        for sub in Usd.PrimRange(proto):
            purpose = UsdGeom.Imageable(sub).ComputePurpose() if sub.IsA(UsdGeom.Imageable) else ""
            if not sub.IsA(UsdGeom.Mesh) or purpose in (UsdGeom.Tokens.proxy, UsdGeom.Tokens.guide):
                continue
            local = _world(cache, sub) @ np.linalg.inv(proto_world)
            material, feather = materials.of(sub)
            mesh = _mesh(sub, local, material, feather)
            if mesh is not None and len(chosen):
                mesh.instances = chosen.reshape(-1, 16)  # = three.js column-major
                if feather and len(per_instance) == len(indices):
                    mesh.instance_feather = per_instance[indices == p]
                out.append(mesh)
    return out
