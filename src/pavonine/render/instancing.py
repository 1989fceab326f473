"""Instancing → Mitsuba ``shapegroup`` + ``instance``: a prototype's triangles exist once.

* ``PointInstancer``: each prototype becomes one shape group; every instance is an ``instance``
  with the transform ``ComputeInstanceTransformsAtTime`` gives (prototype root xform included)
  times the instancer's world transform. ``invisibleIds`` / ``inactiveIds`` are honoured.
* Instanceable prims (native instancing): one shape group per USD prototype, translated from the
  first instance's proxies (so material bindings resolve as on the stage), one ``instance`` per
  instance prim at its world transform.

Nested instancing is flattened into the outer prototype (Mitsuba shape groups do not nest).
The table refuses to grow beyond the render ceiling on instances (:mod:`pavonine.render.limits`):
a PointInstancer is counted *before* any of its prototypes is translated. An instance whose
transform is NaN, infinite or beyond :data:`~pavonine.render.limits.MAX_COORDINATE` is skipped
with a warning naming the instancer and the attributes that make the transform.
Per-instance primvars the feather BSDF reads are recorded per instance id (``primvars``) and
bound after the scene is built (:mod:`pavonine.render.instance_primvars`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from pxr import Usd, UsdGeom

from pavonine.render.diagnostics import Diagnostics
from pavonine.render.instance_primvars import inherited_primvars, instancer_primvars
from pavonine.render.limits import MAX_COORDINATE
from pavonine.render.xform import to_mitsuba, transform_points

#: The PointInstancer attributes an instance's transform is made of (named in warnings).
TRANSFORM_ATTRIBUTES = "positions/orientations/scales"
#: Report progress every this many instances.
PROGRESS_EVERY = 256


@dataclass
class Prototype:
    """A translated prototype: its shape-group id, and bounds in prototype space."""

    group_id: str
    bounds: tuple[np.ndarray, np.ndarray] | None


@dataclass
class InstanceTable:
    """Shape groups and instances for the Mitsuba scene dict."""

    groups: dict[str, dict] = field(default_factory=dict)
    instances: dict[str, dict] = field(default_factory=dict)
    prototypes: dict[str, Prototype] = field(default_factory=dict)
    world_bounds: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)
    primvars: dict[str, dict[str, float]] = field(default_factory=dict)  # instance id → values
    #: instance id → (the PointInstancer's or instanceable prim's path, its index there or -1)
    sources: dict[str, tuple[str, int]] = field(default_factory=dict)
    limit: int | None = None  # the render ceiling on instances (None: no ceiling)
    on_progress: Callable[[int], None] | None = None  # called with the instance count

    def reserve(self, count: int, where: str) -> None:
        """Refuse (an :class:`InputError` from :mod:`.limits`) ``count`` more instances beyond
        :attr:`limit`, before any work is done for them."""
        from pavonine.render.limits import RenderLimits

        RenderLimits(pixels=None, spp=None, instances=self.limit).check_instances(
            len(self.instances) + count, where
        )

    def add_prototype(self, key: str, shapes: list, bounds) -> Prototype:
        group_id = f"shapegroup_{len(self.groups)}"
        if shapes:
            group: dict = {"type": "shapegroup"}
            group.update({f"shape_{i}": s for i, s in enumerate(shapes)})
            self.groups[group_id] = group
        proto = Prototype(group_id if shapes else "", bounds)
        self.prototypes[key] = proto
        return proto

    def sources_of(self, path: str) -> list[tuple[str, int]]:
        """(instance id, index) of every instance made from the prim at ``path``."""
        return [(key, index) for key, (where, index) in self.sources.items() if where == path]

    def add_instance(
        self,
        proto: Prototype,
        world_usd: np.ndarray,
        primvars: dict[str, float] | None = None,
        source: tuple[str, int] | None = None,
    ) -> None:
        if not proto.group_id:
            return
        import mitsuba as mi

        key = f"instance_{len(self.instances)}"
        if source is not None:
            self.sources[key] = source
        if primvars:
            self.primvars[key] = primvars
        self.instances[key] = {
            "type": "instance",
            "shapegroup": {"type": "ref", "id": proto.group_id},
            "to_world": mi.ScalarTransform4f(to_mitsuba(world_usd).tolist()),
        }
        if self.on_progress is not None and len(self.instances) % PROGRESS_EVERY == 0:
            self.on_progress(len(self.instances))
        if proto.bounds is not None:
            lo, hi = proto.bounds
            corners = np.array(
                [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
            )
            moved = transform_points(corners, world_usd)
            self.world_bounds.append((moved.min(axis=0), moved.max(axis=0)))


# translate(prim, root) -> (list of mi shapes, bounds) for the subtree of ``prim`` relative to ``root``
SubtreeTranslator = Callable[
    [Usd.Prim, Usd.Prim], tuple[list, tuple[np.ndarray, np.ndarray] | None]
]


def point_instancer(
    prim: Usd.Prim,
    world_usd: np.ndarray,
    time: Usd.TimeCode,
    table: InstanceTable,
    translate_subtree: SubtreeTranslator,
    diag: Diagnostics,
) -> None:
    """Add a ``PointInstancer``'s prototypes (once each) and instances to ``table``."""
    where = str(prim.GetPath())
    instancer = UsdGeom.PointInstancer(prim)
    targets = instancer.GetPrototypesRel().GetForwardedTargets()
    indices = instancer.GetProtoIndicesAttr().Get(time)
    if not targets or indices is None or len(indices) == 0:
        diag.warn(where, "PointInstancer has no prototypes or no protoIndices; skipped")
        return
    matrices = instancer.ComputeInstanceTransformsAtTime(
        time, time, UsdGeom.PointInstancer.IncludeProtoXform, UsdGeom.PointInstancer.IgnoreMask
    )
    if matrices is None or len(matrices) != len(indices):
        diag.warn(
            where, "PointInstancer positions/orientations/scales do not match protoIndices; skipped"
        )
        return
    mask = instancer.ComputeMaskAtTime(time)
    visible = len(indices) if not mask else int(sum(bool(m) for m in mask))
    table.reserve(visible, f"{where}.protoIndices")
    world = np.array(matrices, dtype=np.float64).reshape(-1, 4, 4) @ world_usd
    usable = np.all(np.isfinite(world) & (np.abs(world) <= MAX_COORDINATE), axis=(1, 2))
    per_instance = instancer_primvars(instancer, time, len(indices), diag)
    prototypes: dict[int, Prototype] = {}
    out_of_range = 0
    for i, proto_index in enumerate(indices):
        if mask and not mask[i]:
            continue
        if not 0 <= proto_index < len(targets):
            out_of_range += 1
            continue
        if not usable[i]:
            continue
        if proto_index not in prototypes:
            root = prim.GetStage().GetPrimAtPath(targets[proto_index])
            key = f"{where}:{targets[proto_index]}"
            if not root:
                diag.warn(where, f"prototype {targets[proto_index]} does not exist")
                prototypes[proto_index] = table.add_prototype(key, [], None)
            else:
                shapes, bounds = translate_subtree(root, root)
                prototypes[proto_index] = table.add_prototype(key, shapes, bounds)
        values = {name: float(array[i]) for name, array in per_instance.items()}
        table.add_instance(prototypes[proto_index], world[i], values, (where, i))
    if out_of_range:
        diag.warn(where, f"{out_of_range} protoIndices out of range; those instances skipped")
    if not usable.all():
        diag.warn(
            where,
            f"{TRANSFORM_ATTRIBUTES}: {int((~usable).sum())} of {len(indices)} instance transforms "
            f"are NaN, infinite or beyond ±{MAX_COORDINATE:g}; those instances skipped",
        )


def native_instance(
    prim: Usd.Prim,
    world_usd: np.ndarray,
    table: InstanceTable,
    translate_subtree: SubtreeTranslator,
    time: Usd.TimeCode | None = None,
) -> None:
    """Add an instanceable prim: its prototype once (from this instance's proxies), then the instance."""
    table.reserve(1, str(prim.GetPath()))
    key = str(prim.GetPrototype().GetPath())
    proto = table.prototypes.get(key)
    if proto is None:
        shapes, bounds = translate_subtree(prim, prim)
        proto = table.add_prototype(key, shapes, bounds)
    primvars = inherited_primvars(prim, Usd.TimeCode.Default() if time is None else time)
    table.add_instance(proto, world_usd, primvars, (str(prim.GetPath()), -1))
