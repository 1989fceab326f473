"""A small UsdSkel rig for tests: a bar whose second joint bends 90° about z between time 0 and 10
(``tests/render/test_geometry.py``, and inside a PointInstancer's prototype in
``tests/motion_scene.py``)."""

from __future__ import annotations

from pxr import Gf, Usd, UsdGeom


def bending_bar(
    stage: Usd.Stage, root_path: str = "/Rig", half_width: float = 0.1, normals: bool = False
) -> UsdGeom.Mesh:
    """A SkelRoot at ``root_path`` with a two-joint skeleton (its animation bends joint ``a/b``
    90° about z from time 0 to 10) and a bar of six points bound rigidly: the first two points
    (and the last two) to joint 0, the tip points to joint 1; ``normals``: +z vertex normals
    authored. Returns the bar."""
    from pxr import UsdSkel, Vt

    root = UsdSkel.Root.Define(stage, root_path)
    skeleton = UsdSkel.Skeleton.Define(stage, f"{root_path}/Skel")
    joints = ["a", "a/b"]
    skeleton.CreateJointsAttr(joints)
    bind = [Gf.Matrix4d(1), Gf.Matrix4d(1).SetTranslate(Gf.Vec3d(1, 0, 0))]
    skeleton.CreateRestTransformsAttr(bind)
    skeleton.CreateBindTransformsAttr(bind)
    anim = UsdSkel.Animation.Define(stage, f"{root_path}/Skel/Anim")
    anim.CreateJointsAttr(joints)
    anim.CreateTranslationsAttr(Vt.Vec3fArray([(0, 0, 0), (1, 0, 0)]))
    anim.CreateScalesAttr(Vt.Vec3hArray([(1, 1, 1), (1, 1, 1)]))
    rotations = anim.CreateRotationsAttr()
    rotations.Set(Vt.QuatfArray([Gf.Quatf(1), Gf.Quatf(1)]), 0)
    turn = Gf.Rotation(Gf.Vec3d(0, 0, 1), 90).GetQuat()
    rotations.Set(Vt.QuatfArray([Gf.Quatf(1), Gf.Quatf(turn)]), 10)
    UsdSkel.BindingAPI.Apply(skeleton.GetPrim()).CreateAnimationSourceRel().SetTargets(
        [anim.GetPath()]
    )
    bar = UsdGeom.Mesh.Define(stage, f"{root_path}/Bar")
    w = half_width
    bar.CreatePointsAttr([(0, -w, 0), (1, -w, 0), (2, -w, 0), (2, w, 0), (1, w, 0), (0, w, 0)])
    bar.CreateFaceVertexCountsAttr([4, 4])
    bar.CreateFaceVertexIndicesAttr([0, 1, 4, 5, 1, 2, 3, 4])
    bar.CreateSubdivisionSchemeAttr("none")
    if normals:
        bar.CreateNormalsAttr([(0, 0, 1)] * 6)
        bar.SetNormalsInterpolation("vertex")
    binding = UsdSkel.BindingAPI.Apply(bar.GetPrim())
    binding.CreateSkeletonRel().SetTargets([skeleton.GetPath()])
    binding.CreateJointIndicesPrimvar(False, 1).Set([0, 0, 1, 1, 0, 0])
    binding.CreateJointWeightsPrimvar(False, 1).Set([1.0] * 6)
    UsdSkel.BindingAPI.Apply(root.GetPrim())
    return bar
