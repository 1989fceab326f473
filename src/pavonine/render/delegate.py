"""The scene delegate: walks a USD stage at one time code and hands each prim to its translator.

Structure after hdmitsuba's per-prim translators (``mesh``, ``instancing``, ``camera``,
``lights``, ``materials``), without Hydra: ``StageDelegate.sync()`` returns everything Mitsuba
needs (shapes, shape groups, instances, emitters, cameras, world bounds). Invisible prims and
``guide``/``proxy`` purposes are skipped; unsupported prim types give one warning each. Which
translator a prim goes to is decided in one place, :mod:`.prim_kinds`, for the stage and for
instance prototypes alike.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field, replace

import numpy as np
from pxr import Tf, Usd, UsdGeom, UsdLux, UsdShade

from pavonine.base.errors import InputError
from pavonine.base.nesting import check_nesting, deep_call
from pavonine.render import (
    curves,
    displacement,
    instancing,
    lights,
    materials,
    mesh,
    shapes,
    skel,
    subdivision,
)
from pavonine.render import (
    prim_kinds as kinds,
)
from pavonine.render.diagnostics import Diagnostics, first_line
from pavonine.render.integrator_settings import warn_unread
from pavonine.render.limits import (
    DEFAULT_LIMITS,
    MAX_COORDINATE,
    RenderLimits,
    coordinates_ok,
)
from pavonine.render.progress import SyncProgress
from pavonine.render.xform import TransformCache, transform_source, usable_transform


@dataclass
class SyncedScene:
    """The translated stage."""

    shapes: dict[str, object] = field(default_factory=dict)
    emitters: dict[str, dict] = field(default_factory=dict)
    cameras: dict[str, Usd.Prim] = field(default_factory=dict)
    bounds: tuple[np.ndarray, np.ndarray] | None = None
    up_axis: str = "Y"
    mesh_count: int = 0
    instance_count: int = 0
    feather_materials: int = 0
    mesh_lights: int = 0  # emitting meshes (MeshLightAPI, emissive materials): area emitters
    dark_lights: int = 0  # lights authored to emit nothing (skipped, but the stage is lit by them)


def open_stage(path: str | os.PathLike, diag: Diagnostics) -> Usd.Stage:
    """Open a USD stage; a missing or unparsable root layer, or prims nested beyond
    :data:`~pavonine.base.nesting.MAX_NESTING`, is an :class:`InputError` (one line)."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise InputError(path, "no such file")
    try:  # parsing and composing recurse per level of nesting: on a deep stack (base.nesting)
        stage = deep_call(Usd.Stage.Open, path, depth=0)
    except Tf.ErrorException as exc:
        raise InputError(path, f"cannot open USD stage: {usd_error_message(exc)}") from None
    if stage is None:
        raise InputError(path, "cannot open USD stage")
    check_nesting(stage, path)
    errors = [first_line(error) for error in stage.GetCompositionErrors()]
    if any(".mtlx" in error.lower() for error in errors):  # usd-core has no usdMtlx
        from pavonine.render.shading.mtlx_documents import substitute_references

        translated = substitute_references(stage, diag)
        errors = [
            f"{e} (its materials are read with the MaterialX package instead, as usdMtlx would)"
            if any(f"@{doc}@" in e for doc in translated)
            else e
            for e in errors
        ]
    for error in errors:
        diag.warn(path, f"composition error: {error}")
    return stage


def render_time(stage: Usd.Stage, time: float | None) -> Usd.TimeCode:
    """``time`` if given; else the stage's startTimeCode if authored; else the earliest sample."""
    if time is not None:
        return Usd.TimeCode(time)
    if stage.HasAuthoredTimeCodeRange():
        return Usd.TimeCode(stage.GetStartTimeCode())
    return Usd.TimeCode.EarliestTime()


class StageDelegate:
    """Translate one stage at one time code."""

    def __init__(
        self,
        stage: Usd.Stage,
        time: Usd.TimeCode,
        diag: Diagnostics,
        *,
        limits: RenderLimits = DEFAULT_LIMITS,
        progress: bool = False,
    ):
        self.stage = stage
        self.time = time
        self.diag = diag
        self.xforms = TransformCache(time)
        self.progress = SyncProgress(stage.GetRootLayer().realPath or "stage", progress)
        self.table = instancing.InstanceTable(
            limit=limits.instances, on_progress=self.progress.instanced
        )
        self._materials: dict[str, materials.MaterialSpec] = {}
        self._bsdfs: dict[tuple, object] = {}
        self.feather_bsdfs: list = []  # the pavonine_feather objects (per-instance primvars)
        self._bounds: list[tuple[np.ndarray, np.ndarray]] = []
        self.scene = SyncedScene(up_axis=str(UsdGeom.GetStageUpAxis(stage)))
        self.skinning = skel.Skinning()
        #: (path, kind) of every prim translated at the stage level (kinds; "instance" for an
        #: instanceable prim): what :mod:`.motion.blur` looks at for time-varying prims
        self.synced_prims: list[tuple[str, str]] = []
        self.limits = limits
        self.base_time: Usd.TimeCode | None = None  # see at_time
        #: per translated subtree's root path, the prim path of each of its meshes, in order
        self.subtree_owners: dict[str, list[str]] = {}
        #: when a dict: per gprim path, (surface, triangle mesh, matrix) of each mesh translated
        #: (:mod:`.motion.deform` learns from them how to move a skinned mesh by its points alone)
        self.recorded: dict[str, list] | None = None

    def at_time(self, time: Usd.TimeCode, base: Usd.TimeCode | None = None) -> StageDelegate:
        """A delegate of the same stage at ``time`` that shares this one's materials and BSDFs
        (nothing is translated until asked: :meth:`translate_prim`); ``base``: the frame's time
        when ``time`` is within its shutter (velocities move points from there)."""
        view = StageDelegate(self.stage, time, self.diag, limits=self.limits)
        view.base_time = base
        view._materials, view._bsdfs = self._materials, self._bsdfs
        view.feather_bsdfs = []  # the scene's feather BSDFs are this delegate's
        if self.skinning.points or self.skinning.transforms:
            view.skinning = skel.skin_stage(self.stage, time, view.xforms, self.diag)
        return view

    def translate_prim(self, prim: Usd.Prim, kind: str) -> dict[str, object]:
        """The shapes of one stage-level gprim or curves prim at this delegate's time, by shape
        name (``/prim#0``); none when its transform is unusable at this time (warned)."""
        if self._world(prim) is None:
            return {}
        before = dict(self.scene.shapes)
        self.scene.shapes.clear()
        self._sync_prim(prim, kind)
        made, self.scene.shapes = self.scene.shapes, before
        return made

    def prototype_prim_shapes(self, root: Usd.Prim, prim: Usd.Prim) -> list:
        """The meshes of ``prim``, a gprim or curves inside the prototype ``root``, at this
        delegate's time and in prototype space, as the sync made them (:mod:`.motion.blur` moves
        them in place); none when its transform is unusable at this time (warned)."""
        relative = np.eye(4) if prim == root else self.xforms.relative(prim, root)
        matrix = self._usable(prim, relative)
        if matrix is None:
            return []
        kind = kinds.prim_kind(prim)
        translate = self._curves if kind == kinds.CURVES else self._gprim_in_prototype
        return translate(prim, matrix)[0]

    def sync(self) -> SyncedScene:
        """Walk the stage and translate every renderable prim (progress on stderr if asked)."""
        with self.progress:
            return self._sync()

    def _sync(self) -> SyncedScene:
        light_prims: list[Usd.Prim] = []
        self.skinning = skel.skin_stage(self.stage, self.time, self.xforms, self.diag)
        it = iter(Usd.PrimRange(self.stage.GetPseudoRoot()))
        for prim in it:
            if prim.IsPseudoRoot():
                continue
            self.progress.prim()
            if not self._visible(prim):
                it.PruneChildren()
                continue
            kind = kinds.prim_kind(prim)
            warn_unread(prim, self.diag)
            geometric = prim.IsInstance() or kind in kinds.GEOMETRIC
            if geometric and self._world(prim) is None:
                it.PruneChildren()
                continue
            if prim.IsInstance():
                instancing.native_instance(
                    prim, self.xforms.world(prim), self.table, self._subtree, self.time
                )
                self.synced_prims.append((str(prim.GetPath()), "instance"))
                it.PruneChildren()
            elif kind == kinds.LIGHT:
                light_prims.append(prim)
                self.synced_prims.append((str(prim.GetPath()), kind))
            else:
                if kind in kinds.GEOMETRIC:
                    self.synced_prims.append((str(prim.GetPath()), kind))
                if self._sync_prim(prim, kind):
                    it.PruneChildren()
        self.scene.shapes.update(self.table.groups)
        self.scene.shapes.update(self.table.instances)
        self.scene.instance_count = len(self.table.instances)
        boxes = self._bounds + self.table.world_bounds
        if boxes:
            self.scene.bounds = (
                np.min([b[0] for b in boxes], axis=0),
                np.max([b[1] for b in boxes], axis=0),
            )
        center, radius = self.bounding_sphere()
        for prim in light_prims:
            if self._world(prim) is None:
                continue
            entry = lights.translate_light(
                prim, self.xforms.world(prim), self.time, self.diag, center, radius
            )
            if entry is not None:
                self.scene.emitters[str(prim.GetPath())] = entry
            elif lights.is_dark(prim, self.time):
                self.scene.dark_lights += 1
        self.scene.feather_materials = sum(m.is_feather for m in self._materials.values())
        return self.scene

    def _sync_prim(self, prim: Usd.Prim, kind: str) -> bool:
        """Translate one prim of the stage by its kind (lights wait for the world bounds);
        True when its children are not to be visited."""
        if kind in (kinds.GPRIM, kinds.CURVES):
            if kind == kinds.GPRIM:
                world = self.skinning.transforms.get(str(prim.GetPath()))
                world = self.xforms.world(prim) if world is None else world
                built, boxes = self._gprim(prim, world, world=True)
            else:
                built, boxes = self._curves(prim, self.xforms.world(prim), world=True)
            for i, shape in enumerate(built):
                self.scene.shapes[f"{prim.GetPath()}#{i}"] = shape
            self._bounds.extend(boxes)
            return False
        if kind == kinds.INSTANCER:
            instancing.point_instancer(
                prim, self.xforms.world(prim), self.time, self.table, self._subtree, self.diag
            )
            return True
        if kind == kinds.CAMERA:
            self.scene.cameras[str(prim.GetPath())] = prim
            return False
        if kind == kinds.UNSUPPORTED:
            _warn_unsupported(prim, self.diag)
        return kind == kinds.PRUNED

    def bounding_sphere(self) -> tuple[np.ndarray, float]:
        """Centre and radius of the world bounds (unit sphere at the origin for an empty scene)."""
        if self.scene.bounds is None:
            return np.zeros(3), 1.0
        lo, hi = self.scene.bounds
        return (lo + hi) / 2.0, max(float(np.linalg.norm(hi - lo)) / 2.0, 1e-3)

    # -- translators ---------------------------------------------------------------------------

    def _world(self, prim: Usd.Prim) -> np.ndarray | None:
        """The prim's world transform; ``None`` (with a warning naming the xformOp) when it is NaN,
        infinite or beyond :data:`~pavonine.render.limits.MAX_COORDINATE`: the prim is skipped."""
        return self._usable(prim, self.xforms.world(prim))

    def _usable(self, prim: Usd.Prim, matrix: np.ndarray) -> np.ndarray | None:
        if usable_transform(matrix, MAX_COORDINATE):
            return matrix
        source = transform_source(prim, self.time, MAX_COORDINATE)
        self.diag.warn(
            str(prim.GetPath()),
            f"transform is NaN, infinite or beyond ±{MAX_COORDINATE:g} (from {source}); skipped",
        )
        return None

    def _visible(self, prim: Usd.Prim) -> bool:
        imageable = UsdGeom.Imageable(prim)
        if not imageable:
            return True
        if imageable.ComputeVisibility(self.time) == UsdGeom.Tokens.invisible:
            return False
        return imageable.ComputePurpose() not in (UsdGeom.Tokens.guide, UsdGeom.Tokens.proxy)

    def _surface(self, prim: Usd.Prim) -> mesh.Surface | None:
        """The gprim as polygons: a mesh as authored (subdivided), or an implicit prim tessellated."""
        if prim.GetTypeName() == "Mesh":
            surface = mesh.read_mesh(UsdGeom.Mesh(prim), self.time, self.diag, self.base_time)
            if surface is None:
                return None
            skinned = self.skinning.points.get(str(prim.GetPath()))
            if skinned is not None:
                surface = mesh.with_points(surface, skinned, self.diag)
            return subdivision.refine_surface(surface, self.time, self.diag)
        return shapes.implicit_surface(prim, self.time, self.diag)

    def _gprim(
        self,
        prim: Usd.Prim,
        matrix_usd: np.ndarray,
        world: bool,
        surface: mesh.Surface | None = None,
    ) -> tuple[list, list[tuple[np.ndarray, np.ndarray]]]:
        """The prim's Mitsuba meshes (one per material) and their bounds, in ``matrix_usd``'s space
        (``surface``: the prim already as polygons, e.g. tessellated ribbons)."""
        curves_mesh = surface is not None and prim.GetTypeName() == "BasisCurves"
        surface = self._surface(prim) if surface is None else surface
        if surface is None:
            return [], []
        built = []
        for index, (material, mask) in enumerate(
            mesh.material_groups(surface, self.time, self.diag)
        ):
            spec = self._material(material, prim)
            if curves_mesh:  # tessellated ribbons or tubes
                spec = spec.on_ribbon(prim, self.diag)
            uv_primvar, attributes = spec.primvars_for(prim)
            triangles = mesh.build_triangle_mesh(
                surface,
                mask,
                matrix_usd,
                uv_primvar,
                attributes,
                self.diag,
                f"{prim.GetPath()}#{index}",
                primvars=spec.primvars,
            )
            if not coordinates_ok(triangles.positions):
                self.diag.warn(
                    str(prim.GetPath()),
                    f"points through the transform are NaN, infinite or beyond "
                    f"±{MAX_COORDINATE:g} (points × xformOps); skipped",
                )
                continue
            if self.recorded is not None:
                self.recorded.setdefault(str(prim.GetPath()), []).append(
                    (surface, triangles, matrix_usd)
                )
            binding = spec.binding(prim, self.time, triangles.attributes)
            bsdf = self._bsdf(spec, surface.double_sided, binding)
            displaced = self._displaced_bsdf(spec, surface.double_sided, binding)
            built.append((triangles, bsdf, spec, binding, displaced))
        light = self._mesh_light(prim, sum(t.area() for t, *_ in built), world)
        meshes = []
        for triangles, bsdf, spec, binding, displaced in built:
            if light is not None and spec.emission is not None:
                self.diag.warn(
                    str(prim.GetPath()),
                    "MeshLightAPI with an emissive material: the material's glow does not tint "
                    "the light (materialSyncMode); the light's own emission is used",
                )
            emitter = (
                light
                if light is not None
                else self._emission(spec, binding, prim, surface.double_sided, world)
            )
            if displaced is None:
                meshes.append(mesh.to_mitsuba_mesh(triangles, bsdf, self._load(emitter)))
                continue
            meshes.append(  # tessellated once the cameras are known (api: displacement.resolve)
                displacement.DisplacedMesh(
                    str(prim.GetPath()),
                    triangles,
                    matrix_usd,
                    spec.displacement,
                    displaced,
                    bsdf,
                    self._load(emitter),
                    world,
                    tuple(spec.attributes.values()),
                )
            )
        self.scene.mesh_count += len(built)
        return meshes, [t.bounds() for t, *_ in built]

    def _displaced_bsdf(self, spec: materials.MaterialSpec, double_sided: bool, binding):
        """The BSDF of a displaced mesh (the material's own, or without its bump-map fallback),
        ``None`` when the material does not displace."""
        if spec.displacement is None:
            return None
        if spec.displacement.keep_bump or spec.bsdf.get("type") != "bumpmap":
            return self._bsdf(spec, double_sided, binding)
        bare = replace(spec, key=f"{spec.key}#displaced", bsdf=spec.bsdf["bsdf"])
        return self._bsdf(bare, double_sided, binding)

    def _gprim_in_prototype(self, prim: Usd.Prim, matrix_usd: np.ndarray) -> tuple[list, list]:
        return self._gprim(prim, matrix_usd, world=False)

    def _emission(self, spec, binding, prim: Usd.Prim, double_sided: bool, world: bool):
        """An emissive material's ``area`` emitter for one mesh (see ``shading.spec``)."""
        where = str(prim.GetPath())
        entry = spec.emitter_dict(binding, where, self.diag)
        if entry is None:
            return None
        if not world:
            self.diag.warn(
                where,
                "emissive material inside an instance prototype is not supported "
                "(Mitsuba instances cannot emit); rendered without emission",
            )
            return None
        if double_sided:
            self.diag.warn(
                where,
                "emissive doubleSided mesh: Mitsuba area lights emit from the front side only",
            )
        self.scene.mesh_lights += 1
        return entry

    def _curves(self, prim: Usd.Prim, matrix_usd: np.ndarray, world: bool = False) -> tuple:
        """A ``BasisCurves`` prim: ribbons (authored normals) as a mesh like any gprim's; tubes as
        one Mitsuba curve shape with its bound material, or a tube mesh when the material reads a
        primvar that varies on them."""
        if curves.has_normals(prim):
            ribbons = curves.ribbon_surface(prim, self.time, self.diag)
            if ribbons is not None:
                return self._gprim(prim, matrix_usd, world, surface=ribbons)
        material = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()[0]
        spec = self._material(material if material else None, prim)
        if curves.reads_varying_primvars(prim, spec.primvars):
            tubes = curves.tube_surface(prim, self.time, self.diag)
            return ([], []) if tubes is None else self._gprim(prim, matrix_usd, world, tubes)
        built = curves.curve_control_points(prim, matrix_usd, self.time, self.diag)
        if built is None:
            return [], []
        kind, control_points = built
        binding = spec.binding(prim, self.time, {})  # constant primvars only
        try:
            shape = curves.to_mitsuba_curves(kind, control_points, self._bsdf(spec, True, binding))
        except Exception as exc:
            self.diag.warn(str(prim.GetPath()), f"Mitsuba rejected the curves ({first_line(exc)})")
            return [], []
        return [shape], [curves.bounds_of(control_points)]

    def _mesh_light(self, prim: Usd.Prim, world_area: float, world: bool) -> dict | None:
        """A ``MeshLightAPI`` mesh's Mitsuba ``area`` emitter (UsdLux radiance, ``normalize``)."""
        if not prim.HasAPI(UsdLux.MeshLightAPI):
            return None
        if not world:
            self.diag.warn(
                str(prim.GetPath()),
                "MeshLightAPI inside an instance prototype is not supported "
                "(Mitsuba instances cannot emit); rendered without emission",
            )
            return None
        radiance = lights.mesh_light_radiance(prim, self.time, self.diag)
        if UsdLux.LightAPI(prim).GetNormalizeAttr().Get(self.time):
            radiance = radiance / max(world_area, 1e-12)
        self.scene.mesh_lights += 1
        return {"type": "area", "radiance": {"type": "rgb", "value": radiance.tolist()}}

    @staticmethod
    def _load(entry: dict | None):
        import mitsuba as mi

        return None if entry is None else mi.load_dict(entry)

    def _subtree(self, root: Usd.Prim, relative_to: Usd.Prim) -> tuple[list, tuple | None]:
        """Meshes under ``root`` (instance proxies included) relative to ``relative_to``."""
        meshes: list = []
        boxes: list = []
        owners: list[str] = self.subtree_owners.setdefault(str(root.GetPath()), [])
        owners.clear()
        it = iter(Usd.PrimRange(root, Usd.TraverseInstanceProxies()))
        for prim in it:
            if not self._visible(prim):
                it.PruneChildren()
                continue
            kind = kinds.prim_kind(prim)
            warn_unread(prim, self.diag)
            if kind in (kinds.GPRIM, kinds.CURVES):
                matrix = self._usable(
                    prim,
                    np.eye(4) if prim == relative_to else self.xforms.relative(prim, relative_to),
                )
                if matrix is None:
                    continue
                translate = self._curves if kind == kinds.CURVES else self._gprim_in_prototype
                prim_shapes, prim_boxes = translate(prim, matrix)
                meshes.extend(prim_shapes)
                owners.extend(str(prim.GetPath()) for _ in prim_shapes)
                boxes.extend(prim_boxes)
            elif kind == kinds.INSTANCER:
                self.diag.warn(
                    str(prim.GetPath()),
                    "PointInstancer inside a prototype (nested instancing) is not supported; skipped",
                )
                it.PruneChildren()
            elif kind == kinds.PRUNED:
                it.PruneChildren()
            elif kind == kinds.UNSUPPORTED:
                _warn_unsupported(prim, self.diag)
        bounds = (
            (np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0))
            if boxes
            else None
        )
        return meshes, bounds

    def _material(
        self, material: UsdShade.Material | None, prim: Usd.Prim
    ) -> materials.MaterialSpec:
        if material is None:
            material_key = "__fallback"
            if material_key not in self._materials:
                self._materials[material_key] = materials.fallback_material()
            return self._materials[material_key]
        key = str(material.GetPath())
        if key not in self._materials:
            self._materials[key] = materials.translate_material(material, self.time, self.diag)
        return self._materials[key]

    def _bsdf(self, spec: materials.MaterialSpec, double_sided: bool, binding):
        """The loaded BSDF of a material for one mesh (cached per sidedness and primvar binding,
        and shared by materials of the same content: :meth:`MaterialSpec.content_key`)."""
        key = (spec.content_key(), double_sided and not spec.two_sided, binding)
        if key not in self._bsdfs:
            self._bsdfs[key] = materials.load_bsdf(
                spec, double_sided, binding, spec.key, self.diag, feathers=self.feather_bsdfs
            )
        return self._bsdfs[key]


def _warn_unsupported(prim: Usd.Prim, diag: Diagnostics) -> None:
    diag.warn(
        str(prim.GetPath()),
        f"{prim.GetTypeName()} prims are not supported by the Mitsuba delegate; skipped",
    )


def usd_error_message(exc: object) -> str:
    """The first diagnostic of a ``Tf.ErrorException`` on one line, without C++ namespaces."""
    text = str(exc)
    quoted = re.findall(r" : '(.*?)'\s*(?:\n|$)", text, flags=re.S)
    message = (quoted[0] if quoted else first_line(exc)).strip()
    message = re.sub(r"pxrInternal_v\w+?__pxrReserved__::", "", message)
    return " ".join(message.split())
