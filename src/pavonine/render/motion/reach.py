"""How far the moving scene travels in the image while the shutter is open, and so how many time
slices a blurred image needs (:mod:`.blur`).

A blurred image is the mean of ``K`` time slices (:mod:`.blur`); a point that travels ``d``
pixels over the shutter is drawn at ``K`` places about ``d / K`` apart. Where that step is under
a pixel the copies merge under the pixel filter into the streak a continuous shutter makes; more
slices than that add only their cost (each is one more ``mi.render`` call, which traces the
integrator again: ``benchmarks/bench_motion.py``). So by default a frame takes
``ceil(d / SLICE_STEP_PX)`` slices, at most the samples' own bound
(:func:`.motion.slice_count`), where ``d`` is the longest image path of the moving scene:

* every time-varying prim the motion plan moves is sampled at up to :data:`POINTS_PER_PRIM` of
  its points (point-based prims, as ``UsdGeomPointBased.ComputePointsAtTime`` gives them, with
  velocities; skinned prims as the skeleton deforms them), other gprims and native instances at
  the corners of their bound; a PointInstancer's instances carry their prototype's points;
* each point is followed through :data:`PATH_TIMES` times spread over the shutter and projected
  by the frame's sensor (Mitsuba's ``Sensor.sample_direction``: film pixels); ``d`` is the
  longest sum of its steps (a swing that comes back still counts its way out and back).

The camera itself moving moves every point, the static ones too: then ``d`` is not estimated
here (``None``) and the samples' bound is used; so too when a moving point is not finite at one
of the times (a NaN time sample) or points come and go. Steps behind the camera do not count.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pxr import Usd, UsdGeom

from pavonine.render import prim_kinds as kinds

#: The largest image step, in pixels, between a point's places in consecutive slices.
SLICE_STEP_PX = 1.0
#: Times at which the moving points are followed over the shutter (its ends included).
PATH_TIMES = 5
#: Points sampled from each prim (evenly by index).
POINTS_PER_PRIM = 64
#: Purposes whose bounds are taken for prims without points.
PURPOSES = (UsdGeom.Tokens.default_, UsdGeom.Tokens.render)


def reach_pixels(plan: Any, sensor: Any, frame: float, open_: float, close: float) -> float | None:
    """The longest path, in film pixels of ``sensor``, that a sampled point of the plan's moving
    prims travels between ``frame + open_`` and ``frame + close`` (module docstring); ``None``
    when the camera moves; 0 when nothing the plan moves is seen."""
    if plan.cameras:
        return None
    base = Usd.TimeCode(frame)
    tracks = []
    for t in np.linspace(frame + open_, frame + close, PATH_TIMES):
        view = plan.delegate.at_time(Usd.TimeCode(float(t)), base)
        tracks.append(_moving_points(plan, view))
    if not tracks or tracks[0].size == 0:
        return 0.0
    if any(track.shape != tracks[0].shape for track in tracks):
        return None  # points appear or vanish within the shutter: not a path to follow
    if not all(np.isfinite(track).all() for track in tracks):
        return None  # a NaN time sample (warned by the translator): not a path to follow
    pixels = np.stack([project(sensor, track) for track in tracks])
    steps = np.linalg.norm(np.diff(pixels, axis=0), axis=-1)  # NaN behind the camera
    paths = np.nansum(steps, axis=0)
    return float(paths.max()) if paths.size else 0.0


def slices_for(reach: float | None, step: float = SLICE_STEP_PX) -> int | None:
    """Slices that keep a point's consecutive places within ``step`` pixels (at least 1);
    ``None`` when the reach is unknown."""
    if reach is None or not np.isfinite(reach):
        return None
    return max(1, int(np.ceil(reach / step - 1e-9)))


def project(sensor: Any, points: np.ndarray) -> np.ndarray:
    """Film pixel positions (N×2) of world ``points`` (N×3) through ``sensor``; NaN for points
    not in front of it."""
    import drjit as dr
    import mitsuba as mi

    if len(points) == 0:
        return np.zeros((0, 2))
    it = dr.zeros(mi.Interaction3f, len(points))
    it.p = mi.Point3f(*(mi.Float(np.ascontiguousarray(points[:, k])) for k in range(3)))
    ds, _ = sensor.sample_direction(it, mi.Point2f(0.5, 0.5))
    uv = np.stack([np.asarray(ds.uv.x), np.asarray(ds.uv.y)], axis=1).astype(np.float64)
    local = sensor.world_transform().inverse() @ it.p
    uv[np.asarray(local.z) <= 0.0] = np.nan
    return uv


def _moving_points(plan: Any, view: Any) -> np.ndarray:
    """World positions (N×3, the same N at every time) of the points followed, at the view's
    time."""
    parts: list[np.ndarray] = []
    for prim, _, _ in plan.gprims:
        parts.append(_to_world(_local_points(view, prim), view.xforms.world(prim)))
    for prim, _ in plan.natives:
        parts.append(_to_world(_bound_corners(view, prim), view.xforms.world(prim)))
    for prim in _instancers(plan):
        parts.append(_instanced_points(view, prim))
    parts = [p for p in parts if p.size]
    return np.concatenate(parts) if parts else np.zeros((0, 3))


def _instancers(plan: Any) -> list[Usd.Prim]:
    """The PointInstancers whose instances move, or whose prototypes deform."""
    roots = {str(root.GetPath()) for root, _, _ in plan.prototypes}
    found = [prim for prim, _ in plan.instancers]
    seen = {str(p.GetPath()) for p in found}
    for path, kind in plan.delegate.synced_prims:
        if kind != kinds.INSTANCER or path in seen:
            continue
        prim = plan.delegate.stage.GetPrimAtPath(path)
        targets = UsdGeom.PointInstancer(prim).GetPrototypesRel().GetForwardedTargets()
        if any(str(t) in roots for t in targets):
            found.append(prim)
            seen.add(path)
    return found


def _instanced_points(view: Any, prim: Usd.Prim) -> np.ndarray:
    """Every instance's prototype points in the world, at the view's time."""
    instancer = UsdGeom.PointInstancer(prim)
    matrices = instancer.ComputeInstanceTransformsAtTime(
        view.time,
        view.base_time or view.time,
        UsdGeom.PointInstancer.IncludeProtoXform,
        UsdGeom.PointInstancer.IgnoreMask,
    )
    indices = instancer.GetProtoIndicesAttr().Get(view.time)
    if matrices is None or indices is None or len(matrices) != len(indices):
        return np.zeros((0, 3))
    world = np.array(matrices, dtype=np.float64).reshape(-1, 4, 4) @ view.xforms.world(prim)
    stage = prim.GetStage()
    targets = instancer.GetPrototypesRel().GetForwardedTargets()
    prototypes = [_prototype_points(view, stage.GetPrimAtPath(t)) for t in targets]
    parts = []
    for matrix, index in zip(world, indices, strict=True):
        if 0 <= index < len(prototypes) and np.all(np.isfinite(matrix)):
            parts.append(_to_world(prototypes[index], matrix))
    return np.concatenate(parts) if parts else np.zeros((0, 3))


def _prototype_points(view: Any, root: Usd.Prim) -> np.ndarray:
    """Sampled points of the gprims inside a prototype, in the prototype root's space."""
    if not root:
        return np.zeros((0, 3))
    parts = []
    for prim in Usd.PrimRange(root, Usd.TraverseInstanceProxies()):
        if not prim.IsA(UsdGeom.Gprim):
            continue
        relative = np.eye(4) if prim == root else view.xforms.relative(prim, root)
        parts.append(_to_world(_local_points(view, prim), relative))
    parts = [p for p in parts if p.size]
    return np.concatenate(parts) if parts else np.zeros((0, 3))


def _local_points(view: Any, prim: Usd.Prim) -> np.ndarray:
    """Up to :data:`POINTS_PER_PRIM` of a gprim's points in its own space at the view's time:
    skinned, else with velocities, else the corners of its bound."""
    skinned = view.skinning.points.get(str(prim.GetPath()))
    if skinned is not None:
        points = np.asarray(skinned, dtype=np.float64)
    elif prim.IsA(UsdGeom.PointBased):
        based = UsdGeom.PointBased(prim)
        computed = based.ComputePointsAtTime(view.time, view.base_time or view.time)
        points = np.asarray(computed if computed is not None else [], dtype=np.float64)
    else:
        return _bound_corners(view, prim)
    points = points.reshape(-1, 3)
    if len(points) > POINTS_PER_PRIM:
        points = points[np.linspace(0, len(points) - 1, POINTS_PER_PRIM).astype(int)]
    return points


def _bound_corners(view: Any, prim: Usd.Prim) -> np.ndarray:
    """The eight corners of ``prim``'s bound at the view's time, in its own space."""
    cache = UsdGeom.BBoxCache(view.time, list(PURPOSES))
    aligned = cache.ComputeUntransformedBound(prim).ComputeAlignedRange()
    if aligned.IsEmpty():
        return np.zeros((0, 3))
    lo, hi = np.array(aligned.GetMin()), np.array(aligned.GetMax())
    return np.array(
        [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    )


def _to_world(points: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """Row-vector points through a USD-layout 4×4 ``matrix``."""
    if points.size == 0:
        return np.zeros((0, 3))
    return points @ matrix[:3, :3] + matrix[3, :3]
