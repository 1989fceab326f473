"""Instancing → Mitsuba ``shapegroup`` + ``instance``: a prototype's triangles exist once.

* ``PointInstancer``: each prototype becomes one shape group; every instance is an ``instance``
  with the transform ``ComputeInstanceTransformsAtTime`` gives (prototype root xform included)
  times the instancer's world transform. ``invisibleIds`` / ``inactiveIds`` are honoured.
* Instanceable prims (native instancing): one shape group per USD prototype, translated from the
  first instance's proxies (so material bindings resolve as on the stage), one ``instance`` per
  instance prim at its world transform.

Nested instancing is flattened into the outer prototype (Mitsuba shape groups do not nest).
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
from pavonine.render.xform import to_mitsuba, transform_points


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

    def add_prototype(self, key: str, shapes: list, bounds) -> Prototype:
        group_id = f"shapegroup_{len(self.groups)}"
        if shapes:
            group: dict = {"type": "shapegroup"}
            group.update({f"shape_{i}": s for i, s in enumerate(shapes)})
            self.groups[group_id] = group
        proto = Prototype(group_id if shapes else "", bounds)
        self.prototypes[key] = proto
        return proto

    def add_instance(
        self, proto: Prototype, world_usd: np.ndarray, primvars: dict[str, float] | None = None
    ) -> None:
        if not proto.group_id:
            return
        import mitsuba as mi

        key = f"instance_{len(self.instances)}"
        if primvars:
            self.primvars[key] = primvars
        self.instances[key] = {
            "type": "instance",
            "shapegroup": {"type": "ref", "id": proto.group_id},
            "to_world": mi.ScalarTransform4f(to_mitsuba(world_usd).tolist()),
        }
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
    per_instance = instancer_primvars(instancer, time, len(indices), diag)
    prototypes: dict[int, Prototype] = {}
    out_of_range = 0
    for i, (proto_index, matrix) in enumerate(zip(indices, matrices, strict=True)):
        if mask and not mask[i]:
            continue
        if not 0 <= proto_index < len(targets):
            out_of_range += 1
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
        table.add_instance(
            prototypes[proto_index], np.array(matrix, dtype=np.float64) @ world_usd, values
        )
    if out_of_range:
        diag.warn(where, f"{out_of_range} protoIndices out of range; those instances skipped")


def native_instance(
    prim: Usd.Prim,
    world_usd: np.ndarray,
    table: InstanceTable,
    translate_subtree: SubtreeTranslator,
    time: Usd.TimeCode | None = None,
) -> None:
    """Add an instanceable prim: its prototype once (from this instance's proxies), then the instance."""
    key = str(prim.GetPrototype().GetPath())
    proto = table.prototypes.get(key)
    if proto is None:
        shapes, bounds = translate_subtree(prim, prim)
        proto = table.add_prototype(key, shapes, bounds)
    primvars = inherited_primvars(prim, Usd.TimeCode.Default() if time is None else time)
    table.add_instance(proto, world_usd, primvars)
