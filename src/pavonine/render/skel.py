"""UsdSkel → skinned points at the render time code (UsdSkel's own ``Cache`` and ``SkinningQuery``).

For every ``SkelRoot``, :class:`UsdSkel.Cache` resolves the bindings; each bound skeleton's
``SkelQuery`` gives the skinning transforms at the render time (its animation source, else the rest
pose), blend shapes are applied first (``BlendShapeQuery``, as ``UsdSkelBakeSkinning`` does), then
``SkinningQuery.ComputeSkinnedPoints`` (linear blend or dual quaternion, per ``skel:skinningMethod``)
deforms the points. Skinned points are in skeleton space; they are returned in the gprim's local
space (``skel local-to-world · gprim world-to-local``) so that the mesh translator's world
transform applies unchanged. Non-point-based prims bound rigidly to a joint (an implicit sphere
riding a bone) get a world transform instead (``ComputeSkinnedTransform``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pxr import Usd, UsdGeom, UsdSkel, Vt

from pavonine.render.diagnostics import Diagnostics, first_line
from pavonine.render.xform import TransformCache, transform_points


@dataclass
class Skinning:
    """Deformed geometry by prim path: local-space points, or world transforms (USD layout)."""

    points: dict[str, np.ndarray] = field(default_factory=dict)
    transforms: dict[str, np.ndarray] = field(default_factory=dict)


def skin_stage(
    stage: Usd.Stage, time: Usd.TimeCode, xforms: TransformCache, diag: Diagnostics
) -> Skinning:
    """Skinned points (and rigid transforms) of every prim bound to a skeleton under a SkelRoot."""
    out = Skinning()
    roots = [p for p in stage.Traverse() if p.IsA(UsdSkel.Root)]
    if not roots:
        return out
    cache = UsdSkel.Cache()
    predicate = Usd.TraverseInstanceProxies()
    for prim in roots:
        root = UsdSkel.Root(prim)
        cache.Populate(root, predicate)
        for binding in cache.ComputeSkelBindings(root, predicate):
            skeleton = binding.GetSkeleton()
            query = cache.GetSkelQuery(skeleton)
            where = str(skeleton.GetPath())
            if not query:
                diag.warn(
                    where, "skeleton is invalid (joints, bind or rest transforms); not skinned"
                )
                continue
            transforms = query.ComputeSkinningTransforms(time)
            if transforms is None or len(transforms) == 0:
                diag.warn(where, "no skinning transforms at the render time; not skinned")
                continue
            skel_to_world = xforms.world(skeleton.GetPrim())
            for target in binding.GetSkinningTargets():
                _skin(target, query, transforms, skel_to_world, time, xforms, diag, out)
    return out


def _skin(
    target: UsdSkel.SkinningQuery,
    query: UsdSkel.SkeletonQuery,
    transforms,
    skel_to_world: np.ndarray,
    time: Usd.TimeCode,
    xforms: TransformCache,
    diag: Diagnostics,
    out: Skinning,
) -> None:
    prim = target.GetPrim()
    where = str(prim.GetPath())
    if not target.HasJointInfluences() and not target.HasBlendShapes():
        return
    if not prim.IsA(UsdGeom.PointBased):
        if target.IsRigidlyDeformed():
            matrix = target.ComputeSkinnedTransform(transforms, time)
            if matrix is not None:
                out.transforms[where] = np.array(matrix, dtype=np.float64) @ skel_to_world
                return
        diag.warn(where, f"{prim.GetTypeName()} bound to a skeleton cannot be skinned; rest pose")
        return
    points = UsdGeom.PointBased(prim).GetPointsAttr().Get(time)
    if points is None or len(points) == 0:
        return
    points = Vt.Vec3fArray(points)
    try:
        if target.HasBlendShapes():
            _blend_shapes(prim, query, target, time, points, diag)
        if target.HasJointInfluences() and not target.ComputeSkinnedPoints(
            transforms, points, time
        ):
            diag.warn(where, "UsdSkel could not skin the points (joint influences?); rest pose")
            return
    except Exception as exc:  # pxr raises Tf.ErrorException for malformed skinning data
        diag.warn(where, f"UsdSkel could not skin the points ({first_line(exc)}); rest pose")
        return
    skel_space = np.asarray(points, dtype=np.float64)
    to_local = skel_to_world @ np.linalg.inv(xforms.world(prim))
    out.points[where] = transform_points(skel_space, to_local)


def _blend_shapes(prim, query, target, time, points, diag: Diagnostics) -> None:
    """Blend-shape offsets at the animation's weights, in place (before skinning)."""
    anim = query.GetAnimQuery()
    if not anim:
        return
    weights = anim.ComputeBlendShapeWeights(time)
    if weights is None or len(weights) == 0:
        return
    mapper = target.GetBlendShapeMapper()
    if mapper and not mapper.IsNull():
        weights = mapper.Remap(weights)
    shapes = UsdSkel.BlendShapeQuery(UsdSkel.BindingAPI(prim))
    sub_weights, sub_indices, sub_shapes = shapes.ComputeSubShapeWeights(weights)
    if not shapes.ComputeDeformedPoints(
        sub_weights,
        sub_indices,
        sub_shapes,
        shapes.ComputeBlendShapePointIndices(),
        shapes.ComputeSubShapePointOffsets(),
        points,
    ):
        diag.warn(str(prim.GetPath()), "blend shapes could not be applied; skinned without them")
