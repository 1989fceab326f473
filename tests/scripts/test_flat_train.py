"""``benchmarks/flat_train.py``: an instancer written out as merged plain meshes, the same geometry."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade, Vt

BENCHMARKS = Path(__file__).parents[2] / "benchmarks"


def _load(name: str):
    spec = importlib.util.spec_from_file_location(name, BENCHMARKS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # its dataclass resolves annotations through sys.modules
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def flat_train():
    return _load("flat_train")


def _instanced_stage(path: Path) -> None:
    """Two prototypes (a card with a tangent primvar and a material, a triangle) under a moved
    instancer; three instances, one rotated 90 degrees about Z and scaled."""
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    stage.SetMetadata("metersPerUnit", 0.01)
    root = UsdGeom.Xform.Define(stage, "/World")
    root.AddTranslateOp().Set(Gf.Vec3d(10, 0, 0))
    stage.SetDefaultPrim(root.GetPrim())
    instancer = UsdGeom.PointInstancer.Define(stage, "/World/Inst")
    card = UsdGeom.Mesh.Define(stage, "/World/Inst/Protos/card/Geom/Card")
    card.CreatePointsAttr([(0, 0, 0), (2, 0, 0), (2, 1, 0), (0, 1, 0)])
    card.CreateFaceVertexCountsAttr([4])
    card.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    card.CreateSubdivisionSchemeAttr("none")
    card.CreateNormalsAttr([(0, 0, 1)] * 4)
    card.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
    api = UsdGeom.PrimvarsAPI(card)
    api.CreatePrimvar("tangent", Sdf.ValueTypeNames.Vector3fArray, UsdGeom.Tokens.vertex).Set(
        [(1, 0, 0)] * 4
    )
    st = api.CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying)
    st.Set([(0, 0), (1, 1)])
    st.SetIndices(Vt.IntArray([0, 1, 1, 0]))
    material = UsdShade.Material.Define(stage, "/World/Inst/Protos/card/Materials/M")
    UsdShade.MaterialBindingAPI.Apply(card.GetPrim()).Bind(material)
    tri = UsdGeom.Mesh.Define(stage, "/World/Inst/Protos/tri/Tri")
    tri.CreatePointsAttr([(0, 0, 0), (1, 0, 0), (0, 1, 0)])
    tri.CreateFaceVertexCountsAttr([3])
    tri.CreateFaceVertexIndicesAttr([0, 1, 2])
    instancer.CreatePrototypesRel().SetTargets(
        ["/World/Inst/Protos/card", "/World/Inst/Protos/tri"]
    )
    instancer.CreateProtoIndicesAttr([0, 0, 1])
    instancer.CreatePositionsAttr([(0, 0, 0), (5, 0, 0), (0, 5, 0)])
    quarter = Gf.Quath(Gf.Rotation(Gf.Vec3d(0, 0, 1), 90).GetQuat())
    instancer.CreateOrientationsAttr([Gf.Quath(1), quarter, Gf.Quath(1)])
    instancer.CreateScalesAttr([(1, 1, 1), (3, 3, 3), (1, 1, 1)])
    stage.Save()


def _world_bound(stage: Usd.Stage, path: str) -> Gf.Range3d:
    cache = UsdGeom.BBoxCache(Usd.TimeCode.Default(), [UsdGeom.Tokens.default_])
    return cache.ComputeWorldBound(stage.GetPrimAtPath(path)).ComputeAlignedRange()


def test_the_flat_meshes_are_the_instances_geometry(flat_train, tmp_path):
    scene, out = tmp_path / "scene.usda", tmp_path / "flat.usdc"
    _instanced_stage(scene)
    assert flat_train.flatten(scene, out) == 3
    original, flat = Usd.Stage.Open(str(scene)), Usd.Stage.Open(str(out))
    assert UsdGeom.GetStageUpAxis(flat) == UsdGeom.Tokens.z
    assert flat.GetMetadata("metersPerUnit") == 0.01
    # USD's own bounds of the instancer (its instances) and of the merged meshes agree
    instanced = _world_bound(original, "/World/Inst")
    merged = _world_bound(flat, "/Flat_Inst")
    assert np.allclose(instanced.GetMin(), merged.GetMin(), atol=1e-5)
    assert np.allclose(instanced.GetMax(), merged.GetMax(), atol=1e-5)
    assert list(
        UsdGeom.PointInstancer(flat.GetPrimAtPath("/World/Inst")).GetInvisibleIdsAttr().Get()
    ) == [0, 1, 2]

    card = UsdGeom.Mesh(flat.GetPrimAtPath("/Flat_Inst/Card_0"))
    points = np.asarray(card.GetPointsAttr().Get())
    # the second copy: rotated a quarter turn, scaled 3, moved to x = 5, under /World's x + 10
    # (orientations are half-precision quaternions: 1e-3 of error in the rotation)
    expected = np.array([[15, 0, 0], [15, 6, 0], [12, 6, 0], [12, 0, 0]])
    assert points[4:] == pytest.approx(expected, abs=5e-3)
    assert list(card.GetFaceVertexIndicesAttr().Get()) == [0, 1, 2, 3, 4, 5, 6, 7]
    tangents = np.asarray(UsdGeom.PrimvarsAPI(card).GetPrimvar("tangent").Get())
    assert tangents[:4] == pytest.approx(np.tile([1, 0, 0], (4, 1)))
    assert tangents[4:] == pytest.approx(np.tile([0, 1, 0], (4, 1)), abs=2e-3)
    assert np.linalg.norm(tangents, axis=1) == pytest.approx(np.ones(8), abs=1e-6)
    st = UsdGeom.PrimvarsAPI(card).GetPrimvar("st")
    assert st.GetInterpolation() == UsdGeom.Tokens.faceVarying
    assert np.asarray(st.Get()) == pytest.approx(np.array([[0, 0], [1, 1], [1, 1], [0, 0]] * 2))
    bound, _ = UsdShade.MaterialBindingAPI(card.GetPrim()).ComputeBoundMaterial()
    assert bound.GetPath() == "/World/Inst/Protos/card/Materials/M"
    assert card.GetSubdivisionSchemeAttr().Get() == "none"


def test_the_benchmark_counts_only_what_is_drawn(tmp_path):
    flat_train, bench = _load("flat_train"), _load("bench_train")
    scene, out = tmp_path / "scene.usda", tmp_path / "flat.usdc"
    _instanced_stage(scene)
    flat_train.flatten(scene, out)
    # card: 2 triangles, used twice; triangle: 1
    assert bench.triangles(scene) == (3, 5)
    assert bench.triangles(out) == (5, 5)  # the instances are hidden, the merged meshes drawn
