"""A stage's point instancers written out as plain meshes: the train without instancing.

``bench_train.py --flat`` renders this beside the instanced train, to measure what the train costs
with the cheapest geometry Mitsuba can hold: every instance's copy of a prototype mesh transformed
to world space and merged with the other copies of that mesh into one ``Mesh`` (so 8 meshes for
the train's four two-part prototypes, no ``instance`` shapes and no per-instance call targets). It
is an experiment, not a way to render: the flat train holds every triangle (4.5 M) and the
per-instance primvars (``pavonine:gradationOffset``, ``pavonine:structuralScale``) are not carried
over, so each feather looks like its prototype.

The flat layer sublayers the scene, copies its stage metadata (camera, units, render settings)
and hides the instances with ``invisibleIds`` (the prototypes' materials stay where they are, and
the merged meshes bind them).

Usage: python benchmarks/flat_train.py SCENE.usda OUT.usdc
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade, Vt

#: Stage metadata the flat layer copies from the scene (a sublayer's own are ignored).
STAGE_METADATA = ("defaultPrim", "metersPerUnit", "upAxis", "renderSettingsPrimPath")


@dataclass
class Merged:
    """The copies of one prototype mesh, accumulated in world space."""

    source: UsdGeom.Mesh
    points: list[np.ndarray] = field(default_factory=list)
    counts: list[np.ndarray] = field(default_factory=list)
    indices: list[np.ndarray] = field(default_factory=list)
    normals: list[np.ndarray] = field(default_factory=list)
    primvars: dict[str, list[np.ndarray]] = field(default_factory=dict)
    vertices: int = 0

    def add(self, world: np.ndarray) -> None:
        """One more copy, ``world`` the 4×4 row-vector matrix from mesh space to world space."""
        mesh = self.source
        points = np.asarray(mesh.GetPointsAttr().Get(), dtype=np.float64)
        linear, normal_matrix = world[:3, :3], np.linalg.inv(world[:3, :3]).T
        self.points.append(points @ linear + world[3, :3])
        self.counts.append(np.asarray(mesh.GetFaceVertexCountsAttr().Get(), dtype=np.int32))
        indices = np.asarray(mesh.GetFaceVertexIndicesAttr().Get(), dtype=np.int32)
        self.indices.append(indices + self.vertices)
        normals = mesh.GetNormalsAttr().Get()
        if normals is not None:
            self.normals.append(_unit(np.asarray(normals, dtype=np.float64) @ normal_matrix))
        for primvar in UsdGeom.PrimvarsAPI(mesh).GetPrimvars():
            if primvar.GetInterpolation() == UsdGeom.Tokens.constant:
                continue
            values = primvar.ComputeFlattened()
            if values is None:
                continue
            values = np.asarray(values, dtype=np.float64)
            if primvar.GetTypeName().role in (Sdf.ValueRoleNames.Vector, Sdf.ValueRoleNames.Normal):
                values = _unit(values @ linear)
            self.primvars.setdefault(primvar.GetPrimvarName(), []).append(values)
        self.vertices += len(points)

    def write(self, stage: Usd.Stage, path: Sdf.Path) -> None:
        """Define the merged mesh at ``path``, with the source's primvars, sides and material."""
        mesh = UsdGeom.Mesh.Define(stage, path)
        source = self.source
        mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(np.concatenate(self.points).astype("f4")))
        mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.concatenate(self.counts)))
        mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.concatenate(self.indices)))
        if self.normals:
            normals = np.concatenate(self.normals).astype("f4")
            mesh.CreateNormalsAttr(Vt.Vec3fArray.FromNumpy(normals))
            mesh.SetNormalsInterpolation(source.GetNormalsInterpolation())
        for name in ("subdivisionScheme", "doubleSided", "orientation"):
            mesh.GetPrim().CreateAttribute(
                name, source.GetPrim().GetAttribute(name).GetTypeName()
            ).Set(source.GetPrim().GetAttribute(name).Get())
        api = UsdGeom.PrimvarsAPI(mesh)
        for primvar in UsdGeom.PrimvarsAPI(source).GetPrimvars():
            name = primvar.GetPrimvarName()
            if primvar.GetInterpolation() == UsdGeom.Tokens.constant:
                value = primvar.Get()
            elif name in self.primvars:
                value = primvar.GetTypeName().type.pythonClass.FromNumpy(
                    np.concatenate(self.primvars[name]).astype("f4")
                )
            else:
                continue
            if value is None:
                continue
            api.CreatePrimvar(name, primvar.GetTypeName(), primvar.GetInterpolation()).Set(value)
        material, _ = UsdShade.MaterialBindingAPI(source.GetPrim()).ComputeBoundMaterial()
        if material:
            UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(material)


def _unit(vectors: np.ndarray) -> np.ndarray:
    length = np.linalg.norm(vectors, axis=1, keepdims=True)
    return vectors / np.where(length > 0.0, length, 1.0)


def _matrix(m: Gf.Matrix4d) -> np.ndarray:
    return np.array(m, dtype=np.float64).reshape(4, 4)


def drawn_meshes(root: Usd.Prim) -> list[UsdGeom.Mesh]:
    """Meshes under ``root`` the delegate draws (default and render purposes)."""
    drawn = (UsdGeom.Tokens.default_, UsdGeom.Tokens.render)
    return [
        UsdGeom.Mesh(prim)
        for prim in Usd.PrimRange(root)
        if prim.IsA(UsdGeom.Mesh) and UsdGeom.Imageable(prim).ComputePurpose() in drawn
    ]


def flatten(scene: str | os.PathLike, out: str | os.PathLike) -> int:
    """Write ``out``: ``scene`` with its point instancers as merged plain meshes; the instance count."""
    stage = Usd.Stage.Open(os.fspath(scene))
    time = Usd.TimeCode.Default()
    cache = UsdGeom.XformCache(time)
    layer = Sdf.Layer.CreateNew(os.fspath(out))
    layer.subLayerPaths.append(os.path.abspath(scene))
    flat = Usd.Stage.Open(layer)
    root_layer = stage.GetRootLayer()
    for key in STAGE_METADATA:
        if root_layer.pseudoRoot.HasInfo(key):
            layer.pseudoRoot.SetInfo(key, root_layer.pseudoRoot.GetInfo(key))
    instances = 0
    for prim in stage.Traverse():
        if not prim.IsA(UsdGeom.PointInstancer):
            continue
        instancer = UsdGeom.PointInstancer(prim)
        targets = instancer.GetPrototypesRel().GetTargets()
        transforms = instancer.ComputeInstanceTransformsAtTime(time, time)
        to_world = _matrix(cache.GetLocalToWorldTransform(prim))
        merged: dict[Sdf.Path, Merged] = {}
        for proto, transform in zip(
            instancer.GetProtoIndicesAttr().Get(time), transforms, strict=True
        ):
            root = stage.GetPrimAtPath(targets[proto])
            instance_world = _matrix(transform) @ to_world
            for mesh in drawn_meshes(root):
                relative, _ = cache.ComputeRelativeTransform(mesh.GetPrim(), root)
                entry = merged.setdefault(mesh.GetPath(), Merged(mesh))
                entry.add(_matrix(relative) @ instance_world)
            instances += 1
        # a root prim: the merged points are in world space already
        group = Sdf.Path.absoluteRootPath.AppendChild(f"Flat_{prim.GetName()}")
        UsdGeom.Xform.Define(flat, group)
        for n, (path, entry) in enumerate(merged.items()):
            entry.write(flat, group.AppendChild(f"{path.name}_{n}"))
        ids = list(range(len(transforms)))
        flat.OverridePrim(prim.GetPath()).CreateAttribute(
            "invisibleIds", Sdf.ValueTypeNames.Int64Array
        ).Set(Vt.Int64Array(ids))
    layer.Save()
    return instances


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__.splitlines()[-1])
    count = flatten(Path(sys.argv[1]), Path(sys.argv[2]))
    print(f"{sys.argv[2]}: {count} instances written as plain meshes")
