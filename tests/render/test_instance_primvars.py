"""Per-instance primvars: recorded per Mitsuba instance, bound to the feather BSDF, visible."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux

from pavonine.base.backend import select_variant
from pavonine.render.delegate import StageDelegate, render_time
from pavonine.render.diagnostics import Diagnostics, StageWarning

EYE = Path(__file__).parents[2] / "assets" / "feathers" / "eye_feather" / "eye_feather.usd"


@pytest.fixture(scope="module", autouse=True)
def _variant():
    select_variant()


def delegate_for(stage):
    diag = Diagnostics()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        delegate = StageDelegate(stage, render_time(stage, None), diag)
        delegate.sync()
    return delegate, diag


def feather_pair(path: Path, primvar: str, values: list[float], lod: str = "low") -> Path:
    """Two eye feathers side by side through one PointInstancer, ``primvar`` per instance."""
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, "Y")
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    instancer = UsdGeom.PointInstancer.Define(stage, "/Pair")
    proto = stage.DefinePrim("/Pair/Prototypes/Eye", "Xform")
    proto.GetReferences().AddReference(str(EYE))
    proto.GetVariantSets().GetVariantSet("lod").SetVariantSelection(lod)
    instancer.CreatePrototypesRel().SetTargets([proto.GetPath()])
    instancer.CreateProtoIndicesAttr([0, 0])
    instancer.CreatePositionsAttr([(-8.5, 0, 0), (8.5, 0, 0)])
    UsdGeom.PrimvarsAPI(instancer).CreatePrimvar(
        primvar, Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.vertex
    ).Set(values)
    # Orthographic, 34 cm across 96 pixels: the instances, 17 cm apart, are exactly 48 pixels
    # apart, so the image's halves are pixel-aligned views of the two instances.
    camera = UsdGeom.Camera.Define(stage, "/Camera")
    camera.CreateProjectionAttr(UsdGeom.Tokens.orthographic)
    camera.CreateHorizontalApertureAttr(340.0)
    camera.CreateVerticalApertureAttr(255.0)
    camera.AddTranslateOp().Set(Gf.Vec3d(0, 18, 100))
    sun = UsdLux.DistantLight.Define(stage, "/Sun")  # 25° from the right: no shadow on the other
    sun.CreateIntensityAttr(3.14159)
    sun.CreateNormalizeAttr(True)
    sun.AddRotateYOp().Set(25.0)
    stage.GetRootLayer().Save()
    return path


def test_point_instancer_primvars_are_recorded_per_instance(tmp_path):
    stage = Usd.Stage.Open(
        str(feather_pair(tmp_path / "p.usda", "pavonine:gradationOffset", [-0.2, 0.3]))
    )
    delegate, diag = delegate_for(stage)
    assert diag.messages == []
    assert delegate.table.primvars == {
        "instance_0": {"pavonine:gradationOffset": pytest.approx(-0.2)},
        "instance_1": {"pavonine:gradationOffset": pytest.approx(0.3)},
    }
    assert len(delegate.table.groups) == 1  # one prototype: memory stays that of the prototype
    assert len(delegate.feather_bsdfs) == 1


def test_unsupported_and_miscounted_instance_primvars_warn(tmp_path):
    stage = Usd.Stage.Open(
        str(feather_pair(tmp_path / "p.usda", "pavonine:gradationOffset", [0.1]))
    )
    instancer = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/Pair"))
    instancer.CreatePrimvar(
        "displayColor", Sdf.ValueTypeNames.Color3fArray, UsdGeom.Tokens.vertex
    ).Set([(1, 0, 0), (0, 1, 0)])
    delegate, diag = delegate_for(stage)
    text = "\n".join(diag.messages)
    assert "per-instance primvar displayColor is not supported" in text
    assert "pavonine:gradationOffset (vertex) has 1 values for 2 instances; ignored" in text
    assert delegate.table.primvars == {}


def test_native_instances_inherit_constant_primvars(tmp_path):
    stage = Usd.Stage.CreateInMemory()
    for i, offset in enumerate((0.1, -0.1)):
        prim = stage.DefinePrim(f"/Train/F{i}", "Xform")
        prim.GetReferences().AddReference(str(EYE))
        prim.GetVariantSets().GetVariantSet("lod").SetVariantSelection("low")
        prim.SetInstanceable(True)
        UsdGeom.Xformable(prim).AddTranslateOp().Set(Gf.Vec3d(20.0 * i, 0, 0))
        UsdGeom.PrimvarsAPI(prim).CreatePrimvar(
            "pavonine:gradationOffset", Sdf.ValueTypeNames.Float
        ).Set(offset)
    delegate, _ = delegate_for(stage)
    values = sorted(v["pavonine:gradationOffset"] for v in delegate.table.primvars.values())
    assert values == [pytest.approx(-0.1), pytest.approx(0.1)]


def half_difference(rgb: np.ndarray) -> float:
    """Mean absolute difference between the image's two halves (the two instances), relative,
    over 12×12-pixel block means (so that pixel noise averages out and colour shifts stay)."""
    width = rgb.shape[1] // 2
    blocks = [
        half.reshape(half.shape[0] // 12, 12, half.shape[1] // 12, 12, 3).mean(axis=(1, 3))
        for half in (rgb[:, :width], rgb[:, width : 2 * width])
    ]
    left, right = blocks
    return float(np.abs(left - right).mean() / (0.5 * (left + right)).mean())


@pytest.mark.render
def test_per_instance_primvars_visibly_change_the_feather(tmp_path):
    """Two instances of one prototype: alike without variation, different with it."""
    from pavonine.render.api import render_stage

    def render(primvar, values):
        stage = feather_pair(tmp_path / f"{primvar[9:]}{values}.usda", primvar, values)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", StageWarning)
            return render_stage(stage, spp=16, resolution=(96, 72), progress=False).rgb

    alike = half_difference(render("pavonine:gradationOffset", [0.0, 0.0]))  # noise only
    graded = half_difference(render("pavonine:gradationOffset", [-0.5, 0.5]))
    worn = half_difference(render("pavonine:structuralScale", [0.3, 1.0]))
    assert graded > 4 * alike, (alike, graded)
    assert worn > 4 * alike, (alike, worn)


@pytest.mark.render
def test_an_instanced_feather_renders_like_the_feather_in_place(tmp_path):
    """Mesh attributes (the barb tangent) read through a rotated instance are the prototype's."""
    from pavonine.render.api import render_stage

    instanced = Usd.Stage.Open(str(feather_pair(tmp_path / "i.usda", "pavonine:x", [0.0, 0.0])))
    instancer = UsdGeom.PointInstancer(instanced.GetPrimAtPath("/Pair"))
    instancer.GetProtoIndicesAttr().Set([0])
    instancer.GetPositionsAttr().Set([(-8.5, 0, 0)])
    turn = Gf.Rotation(Gf.Vec3d(0, 0, 1), 20.0).GetQuat()
    instancer.CreateOrientationsAttr([Gf.Quath(turn)])
    instanced.GetPrimAtPath("/Pair").RemoveProperty("primvars:pavonine:x")
    instanced.Save()
    in_place = Usd.Stage.Open(str(tmp_path / "i.usda"))
    in_place.RemovePrim("/Pair")
    feather = in_place.DefinePrim("/Feather", "Xform")
    feather.GetReferences().AddReference(str(EYE))
    feather.GetVariantSets().GetVariantSet("lod").SetVariantSelection("low")
    xform = UsdGeom.Xformable(feather)
    xform.AddTranslateOp().Set(Gf.Vec3d(-8.5, 0, 0))
    xform.AddRotateZOp().Set(20.0)
    in_place.Export(str(tmp_path / "p.usda"))
    a, b = (
        render_stage(tmp_path / name, spp=16, resolution=(96, 72), progress=False).rgb[:, :48]
        for name in ("i.usda", "p.usda")
    )
    assert np.abs(a - b).mean() / b.mean() < 1e-3


@pytest.mark.parametrize("glitter_b, feathers", [(None, 1), (0.5, 2)])
def test_copies_of_one_material_share_one_feather_bsdf(glitter_b, feathers):
    """Two prototypes that each reference the eye feather carry two copies of its material (two
    paths, one content): they share one loaded feather BSDF (a Python BSDF is traced at every
    render call, once per object; the rattle shot's 16 phase-shifted prototypes made 16 of them).
    A copy whose content differs (its glitter) gets its own."""
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    instancer = UsdGeom.PointInstancer.Define(stage, "/Pair")
    targets = []
    for name in ("A", "B"):
        proto = stage.DefinePrim(f"/Pair/Prototypes/{name}", "Xform")
        proto.GetReferences().AddReference(str(EYE))
        proto.GetVariantSets().GetVariantSet("lod").SetVariantSelection("low")
        targets.append(proto.GetPath())
    if glitter_b is not None:
        material = stage.OverridePrim("/Pair/Prototypes/B/Materials/Feather")
        material.CreateAttribute("pavonine:glitter", Sdf.ValueTypeNames.Float).Set(glitter_b)
    instancer.CreatePrototypesRel().SetTargets(targets)
    instancer.CreateProtoIndicesAttr([0, 1])
    instancer.CreatePositionsAttr([(-8.5, 0, 0), (8.5, 0, 0)])
    delegate, _ = delegate_for(stage)
    assert len(delegate.table.groups) == 2
    assert len(delegate.feather_bsdfs) == feathers
