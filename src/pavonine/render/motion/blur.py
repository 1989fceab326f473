"""Motion blur as USD means it, on a renderer that has none: time slices of one Mitsuba scene.

USD's camera says when its shutter is open: ``shutter:open`` and ``shutter:close``, in time codes
relative to the frame's time (``-0.25``, ``0.25``: a quarter of a frame either side).
``UsdRenderSettings``' ``disableMotionBlur`` (and the older ``instantaneousShutter``) make it an
instant. A close before the open is, by USD's own rule, no exposure at all: an error here (one
line naming the layer and the attribute), not a black image. A NaN or infinite shutter is warned
about and the frame rendered sharp.

Mitsuba 3 has no motion of its own (rays carry a time; shapes ignore it). So a blurred image is
rendered as ``K`` time slices of one scene (:data:`DEFAULT_SLICES`, at most one per sample per
pixel): slice ``i`` is at time ``t + open + (i + u_i) / K · (close − open)`` (stratified, ``u_i``
uniform from the seed: the same seed gives the same times), the scene's parameters are moved there
in place (``mi.traverse``: a mesh's ``vertex_positions`` and ``vertex_normals``, an instance's and
a sensor's ``to_world``; Embree's BVH is rebuilt, the LLVM kernel found in Dr.Jit's cache), and
``spp / K`` samples are rendered there with seed :func:`slice_seed`; the image is the
sample-weighted mean of the slices. An unblurred image is one slice at the frame's time with the
render's own seed, so it is the single-time render, bit for bit.

What moves is found the way a Hydra delegate finds dirty prims: a prim is *time-varying* when any
transform on its way to the root, or any of its own attributes, might vary
(``TransformMightBeTimeVarying``, ``ValueMightBeTimeVarying``); only those are translated again at
a slice's time (:meth:`MotionPlan.retime`), by the same translators as the frame's (so points,
normals, ``widths`` of tessellated curves, subdivision and skinning move with them), with
``velocities`` and ``angularVelocities`` applied by USD (``ComputeInstanceTransformsAtTime`` with
the frame as base time). The same plan moves a scene from one frame to the next
(:class:`pavonine.render.api.RenderSession`).

A ``PointInstancer`` prototype whose prims vary (points, skinning, blend shapes) is translated
again at the slice's time and its shape group's meshes moved in place: Mitsuba rebuilds the
group's BVH once, and every instance of it follows.

What does not move (warned once, naming the prim): lights (rendered as at the frame's time),
Mitsuba curve shapes (tubes without a varying primvar), displaced meshes, meshes inside the
prototypes of native instances (instanceable prims), and a prim whose topology changes within the
interval. A slice at which a prim's
transform or points are NaN keeps the prim where it was at the frame's time (the translator warns,
naming the attribute).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from pxr import Usd, UsdGeom

from pavonine.base.errors import InputError
from pavonine.render import instance_primvars
from pavonine.render import prim_kinds as kinds
from pavonine.render.diagnostics import Diagnostics
from pavonine.render.motion import deform

#: Time slices of a blurred image at most (by default one per MIN_SLICE_SPP samples per pixel).
DEFAULT_SLICES = 16
#: Samples per pixel of a slice by default: each slice is one ``mi.render`` call, which traces
#: the integrator again (the kernel itself is found in Dr.Jit's cache), so a slice must carry
#: enough samples for that trace not to dominate (``benchmarks/bench_motion.py``).
MIN_SLICE_SPP = 8
#: Attributes that move a prim between its time samples (UsdGeomPointBased, PointInstancer).
MOTION_ATTRIBUTES = ("velocities", "accelerations", "angularVelocities")
#: Seeds of the slices: ``seed · SLICE_STRIDE + i + 1`` (passes inside a slice add their own).
SLICE_STRIDE = 1_000_003


@dataclass(frozen=True)
class Shutter:
    """When the shutter is open, in time codes relative to the frame (``open == close``: an
    instant)."""

    open: float = 0.0
    close: float = 0.0

    @property
    def blurred(self) -> bool:
        return self.close > self.open

    def times(self, frame: float, slices: int, seed: int) -> list[float]:
        """The slices' time codes: one stratum each of the open interval, jittered by ``seed``
        (``[frame]`` for an instant)."""
        if not self.blurred:
            return [frame]
        jitter = np.random.default_rng([int(seed) & 0xFFFFFFFF, 35]).random(slices)
        width = (self.close - self.open) / slices
        return [frame + self.open + (i + float(jitter[i])) * width for i in range(slices)]


def slice_count(
    shutter: Shutter, spp: int, slices: int | None, moments: bool, needed: int | None = None
) -> int:
    """Slices of one image: 1 for an instant, else ``slices`` (default: one per
    :data:`MIN_SLICE_SPP` samples, at most :data:`DEFAULT_SLICES`, and no more than the motion
    ``needed``: :func:`pavonine.render.motion.reach.slices_for`) but no more than ``spp`` (half
    of it with ``moments``: each slice needs two passes for a variance)."""
    if not shutter.blurred:
        return 1
    if slices is None:
        wanted = min(DEFAULT_SLICES, -(-spp // MIN_SLICE_SPP))
        if needed is not None:
            wanted = min(wanted, needed)
    else:
        wanted = slices
    return max(1, min(wanted, spp // 2 if moments else spp))


def slice_spp(spp: int, slices: int) -> list[int]:
    """``spp`` split over the slices, as evenly as integers allow."""
    return [spp // slices + (1 if i < spp % slices else 0) for i in range(slices)]


def slice_seed(seed: int, index: int, slices: int) -> int:
    """Slice ``index``'s seed; one slice renders with ``seed`` itself."""
    if slices == 1:
        return int(seed)
    return (int(seed) * SLICE_STRIDE + index + 1) & 0xFFFFFFFF


def read_shutter(
    camera: Usd.Prim | None, time: Usd.TimeCode, disabled: bool, diag: Diagnostics
) -> Shutter:
    """The camera's shutter at ``time`` (an instant without a camera, or when the product's
    settings disable motion blur)."""
    if camera is None or not camera.IsA(UsdGeom.Camera) or disabled:
        return Shutter()
    cam = UsdGeom.Camera(camera)
    opened = cam.GetShutterOpenAttr().Get(time)
    closed = cam.GetShutterCloseAttr().Get(time)
    opened = 0.0 if opened is None else float(opened)
    closed = 0.0 if closed is None else float(closed)
    where = str(camera.GetPath())
    if not (math.isfinite(opened) and math.isfinite(closed)):
        diag.warn(
            where,
            f"shutter:open = {opened:g}, shutter:close = {closed:g} is not a finite interval; "
            "rendered without motion blur",
        )
        return Shutter()
    if closed < opened:
        attr = cam.GetShutterCloseAttr()
        stack = attr.GetPropertyStack(time)
        layer = stack[0].layer if stack else camera.GetStage().GetRootLayer()
        raise InputError(
            f"{layer.realPath or layer.identifier}: {where}.shutter:close",
            f"{closed:g} is before shutter:open {opened:g}: no exposure (USD: a renderer makes a "
            "black image); author close ≥ open",
        )
    return Shutter(opened, closed)


# -- what varies ---------------------------------------------------------------------------------


class Variation:
    """Whether prims might vary in time (a cache over the stage; USD's own might-vary tests)."""

    def __init__(self) -> None:
        self._xforms: dict[str, bool] = {}

    def transform(self, prim: Usd.Prim) -> bool:
        """Some transform from ``prim`` up to the root might vary."""
        chain = []
        found = False
        while prim and not prim.IsPseudoRoot():
            key = str(prim.GetPath())
            if key in self._xforms:
                found = self._xforms[key]
                break
            chain.append((key, prim))
            prim = prim.GetParent()
        for key, p in reversed(chain):
            xformable = UsdGeom.Xformable(p)
            found = found or bool(xformable and xformable.TransformMightBeTimeVarying())
            self._xforms[key] = found
        return found

    @staticmethod
    def attributes(prim: Usd.Prim) -> bool:
        """Some attribute of ``prim`` itself might vary (xformOps included), or it has
        ``velocities``, ``accelerations`` or ``angularVelocities`` (motion within one sample)."""
        for attr in prim.GetAttributes():
            if attr.ValueMightBeTimeVarying():
                return True
            if attr.GetName() in MOTION_ATTRIBUTES and attr.HasAuthoredValue():
                return True
        return False

    def prim(self, prim: Usd.Prim) -> bool:
        return self.transform(prim) or self.attributes(prim)

    def subtree(self, root: Usd.Prim, skinned: Any = None, with_root: bool = False) -> bool:
        """Anything below ``root`` (instance proxies included; ``root`` too ``with_root``) might
        vary, or is deformed by a skeleton (``skinned``: the delegate's
        :class:`pavonine.render.skel.Skinning`)."""
        for prim in Usd.PrimRange(root, Usd.TraverseInstanceProxies()):
            if prim == root and not with_root:
                continue
            if self.attributes(prim):
                return True
            path = str(prim.GetPath())
            if skinned is not None and (path in skinned.points or path in skinned.transforms):
                return True
        return False


@dataclass
class MotionPlan:
    """The time-varying part of a synced scene and how to move it to another time."""

    delegate: Any  # the StageDelegate that synced the scene (its time is the frame's)
    gprims: list[tuple[Usd.Prim, str, dict[str, str]]] = field(default_factory=list)
    instancers: list[tuple[Usd.Prim, list[tuple[str, int]]]] = field(default_factory=list)
    #: a PointInstancer prototype whose prims vary: (its root, its shape group's id, and per
    #: varying prim inside it, the prim, the indices of its meshes in the group and, when a
    #: skeleton alone deforms it, how its meshes follow its points: :mod:`.deform`)
    prototypes: list[tuple[Usd.Prim, str, list[tuple[Usd.Prim, list[int], Any]]]] = field(
        default_factory=list
    )
    natives: list[tuple[Usd.Prim, str]] = field(default_factory=list)
    cameras: list[tuple[Usd.Prim, str, Any]] = field(default_factory=list)  # prim, sensor id, job
    #: prims that vary but are not moved (what :attr:`complete` is false for)
    fixed: list[str] = field(default_factory=list)
    time: float | None = None  # where the scene is now (None: the delegate's time)
    retimes: int = 0
    #: the Mitsuba scene moved (its feather BSDFs follow their instances' frames)
    scene: Any = None

    @property
    def static(self) -> bool:
        return not (
            self.gprims or self.instancers or self.prototypes or self.natives or self.cameras
        )

    @property
    def complete(self) -> bool:
        """Everything that varies is moved by :meth:`retime` (else a new frame needs a full
        sync)."""
        return not self.fixed

    def retime(self, params, time: float, diag: Diagnostics, base: float | None = None) -> float:
        """Move the scene's time-varying objects to ``time`` (``base``: the time velocities are
        applied from, the frame's); returns the seconds it took."""
        import time as clock

        started = clock.perf_counter()
        if self.time == time:
            return 0.0
        if self.static or params is None:  # nothing varies: the scene is the same at any time
            self.time = time
            return clock.perf_counter() - started
        base_code = Usd.TimeCode(time if base is None else base)
        view = self.delegate.at_time(Usd.TimeCode(time), base_code)
        for prim, kind, keys in self.gprims:
            self._move_gprim(params, view, prim, kind, keys, diag)
        for prim, instances in self.instancers:
            self._move_instancer(params, view, prim, instances, base_code)
        for root, group, moving in self.prototypes:
            self._move_prototype(params, view, root, group, moving, diag)
        for prim, key in self.natives:
            world = view.xforms.world(prim)
            if np.all(np.isfinite(world)):
                params[f"{key}.to_world"] = _transform(world.T)
        for prim, sensor_id, job in self.cameras:
            to_world = job(prim, view, Usd.TimeCode(time))
            if to_world is not None:
                params[f"{sensor_id}.to_world"] = _transform(to_world)
        params.update()
        if self.scene is not None and (self.instancers or self.natives):
            instance_primvars.refresh_frames(
                self.scene, self.delegate.table, self.delegate.feather_bsdfs, params
            )
        self.time = time
        self.retimes += 1
        return clock.perf_counter() - started

    def _move_gprim(self, params, view, prim, kind, keys, diag) -> None:
        shapes = view.translate_prim(prim, kind)
        for name, key in keys.items():
            new = shapes.get(name)
            if new is None:  # NaN at this time (warned by the translator): stays put
                continue
            _move_mesh(params, key, new, prim, diag)

    def _move_prototype(self, params, view, root, group, moving, diag) -> None:
        """Translate a PointInstancer prototype's varying prims again at the view's time
        (skinning, blend shapes and points as at any time) and move their meshes in the shape
        group in place; Mitsuba rebuilds the group's BVH, and every instance follows."""
        for prim, indices, fast in moving:
            if fast is not None and _move_points(params, view, prim, group, indices, fast):
                continue
            shapes = view.prototype_prim_shapes(root, prim)
            if len(shapes) != len(indices):
                if shapes:  # none: unusable at this time (warned by the translator), stays put
                    diag.warn(
                        str(prim.GetPath()),
                        "topology changes within the time rendered; not moved (as at the first "
                        "time)",
                    )
                continue
            for index, new in zip(indices, shapes, strict=True):
                _move_mesh(params, f"{group}.shape_{index}", new, prim, diag)

    def _move_instancer(self, params, view, prim, instances, base) -> None:
        instancer = UsdGeom.PointInstancer(prim)
        matrices = instancer.ComputeInstanceTransformsAtTime(
            view.time,
            base,
            UsdGeom.PointInstancer.IncludeProtoXform,
            UsdGeom.PointInstancer.IgnoreMask,
        )
        if matrices is None:
            return
        world = np.array(matrices, dtype=np.float64).reshape(-1, 4, 4) @ view.xforms.world(prim)
        for key, index in instances:
            if index < len(world) and np.all(np.isfinite(world[index])):
                params[f"{key}.to_world"] = _transform(world[index].T)


def _move_points(params, view, prim: Usd.Prim, group: str, indices: list[int], fast) -> bool:
    """Move a skinned prim's meshes in the shape group ``group`` by its points alone
    (:class:`pavonine.render.motion.deform.PointsMove`); false when it cannot (then it is
    translated)."""
    import mitsuba as mi

    points = view.skinning.points.get(str(prim.GetPath()))
    arrays = None if points is None else fast.arrays(points)
    if arrays is None or len(arrays) != len(indices):
        return False
    keys = [f"{group}.shape_{index}" for index in indices]
    for key, (positions, _) in zip(keys, arrays, strict=True):
        if f"{key}.vertex_positions" not in params:
            return False
        if dr_width(params[f"{key}.vertex_positions"]) != positions.size:
            return False
    for key, (positions, normals) in zip(keys, arrays, strict=True):
        params[f"{key}.vertex_positions"] = mi.Float(positions.ravel())
        if normals is not None and f"{key}.vertex_normals" in params:
            params[f"{key}.vertex_normals"] = mi.Float(normals.ravel())
    return True


def _move_mesh(params, key: str, new, prim: Usd.Prim, diag: Diagnostics) -> None:
    """Set the scene mesh ``key``'s vertices (and normals) to those of the mesh ``new``; a mesh of
    another vertex count stays as it is (warned, naming ``prim``)."""
    import mitsuba as mi

    if not isinstance(new, mi.Mesh):
        return
    name_in_scene = f"{key}.vertex_positions"
    current = params[name_in_scene] if name_in_scene in params else None
    moved = mi.traverse(new)
    positions = moved["vertex_positions"]
    if current is None or dr_width(current) != dr_width(positions):
        diag.warn(
            str(prim.GetPath()),
            "topology changes within the time rendered; not moved (as at the first time)",
        )
        return
    params[name_in_scene] = positions
    if f"{key}.vertex_normals" in params and new.has_vertex_normals():
        params[f"{key}.vertex_normals"] = moved["vertex_normals"]


def dr_width(value) -> int:
    import drjit as dr

    return dr.width(value)


def _transform(matrix_mitsuba: np.ndarray):
    import mitsuba as mi

    return mi.Transform4f(np.asarray(matrix_mitsuba, dtype=np.float64))


def plan_motion(
    delegate,
    shape_keys: dict[str, str],
    cameras: list[tuple[Usd.Prim, str, Any]],
    diag: Diagnostics,
    warn: bool = True,
) -> MotionPlan:
    """What of the synced scene varies in time, and how each piece is moved (module docstring).

    ``shape_keys``: the scene-dict key of each shape name (``/prim#0``); ``cameras``: (camera
    prim, sensor id, a function ``(prim, view, time) → to_world`` in Mitsuba's layout or None).
    With ``warn``, what varies but cannot move is warned about, naming the prim.
    """
    import mitsuba as mi

    plan = MotionPlan(delegate)
    variation = Variation()
    learner = None  # a recording view, made once a skinned prototype prim is met

    def fixed(prim: Usd.Prim, why: str) -> None:
        plan.fixed.append(str(prim.GetPath()))
        if warn:
            diag.warn(str(prim.GetPath()), f"{why}; not moved within the time rendered")

    by_prim: dict[str, dict[str, str]] = {}
    for name, key in shape_keys.items():
        if "#" in name and name.startswith("/"):
            by_prim.setdefault(name.rsplit("#", 1)[0], {})[name] = key
    for path, kind in delegate.synced_prims:
        prim = delegate.stage.GetPrimAtPath(path)
        skinned = path in delegate.skinning.points or path in delegate.skinning.transforms
        if kind in (kinds.GPRIM, kinds.CURVES):
            if not (skinned or variation.prim(prim)):
                continue
            keys = by_prim.get(path, {})
            shapes = [delegate.scene.shapes.get(name) for name in keys]
            if any(not isinstance(s, mi.Mesh) for s in shapes):
                why = "Mitsuba curves" if kind == kinds.CURVES else "a displaced mesh"
                fixed(prim, f"time-varying {why} (motion is rendered on meshes)")
                continue
            if keys:
                plan.gprims.append((prim, kind, keys))
        elif kind == kinds.INSTANCER:
            instancer = UsdGeom.PointInstancer(prim)
            for target in instancer.GetPrototypesRel().GetForwardedTargets():
                root = prim.GetStage().GetPrimAtPath(target)
                if not root or not variation.subtree(root, delegate.skinning, with_root=True):
                    continue
                group = _prototype_group(delegate, f"{path}:{target}")
                if group is None:
                    fixed(root, "time-varying prims inside a prototype that are not meshes")
                elif group:
                    owners = delegate.subtree_owners.get(target.pathString, [])
                    moving = []
                    for p, indices, only_skinned in _varying_owners(
                        root, owners, variation, delegate.skinning
                    ):
                        if only_skinned and learner is None:
                            learner = deform.learner(delegate)
                        fast = deform.learn(learner, root, p) if only_skinned else None
                        moving.append((p, indices, fast))
                    plan.prototypes.append((root, group, moving))
            if instancer.GetProtoIndicesAttr().ValueMightBeTimeVarying():
                fixed(prim, "protoIndices vary (instances appear or vanish)")
            elif variation.prim(prim):
                instances = delegate.table.sources_of(path)
                plan.instancers.append((prim, instances))
        elif kind == "instance":
            if variation.subtree(prim):
                fixed(prim, "time-varying prims inside an instance's prototype")
            if variation.transform(prim):
                plan.natives.extend((prim, key) for key, _ in delegate.table.sources_of(path))
        elif kind == kinds.LIGHT and variation.prim(prim):
            fixed(prim, "a time-varying light (lights are rendered as at the frame's time)")
    for prim, sensor_id, to_world in cameras:
        if variation.transform(prim):
            plan.cameras.append((prim, sensor_id, to_world))
        lens = ("focalLength", "horizontalAperture", "verticalAperture", "fStop", "focusDistance")
        if any(
            prim.GetAttribute(n) and prim.GetAttribute(n).ValueMightBeTimeVarying() for n in lens
        ):
            fixed(prim, "a time-varying lens (the lens of the first time is used)")
    plan.time = frame_time(delegate.time)
    return plan


def _prototype_group(delegate, key: str) -> str | None:
    """The shape group of the PointInstancer prototype ``key`` (``instancer:target``) when every
    shape in it is a mesh (``None`` otherwise: Mitsuba curves cannot be moved in place; ``""``
    for a prototype that made no shapes)."""
    import mitsuba as mi

    proto = delegate.table.prototypes.get(key)
    if proto is None or not proto.group_id:
        return ""
    shapes = [v for k, v in delegate.table.groups[proto.group_id].items() if k != "type"]
    if not all(isinstance(shape, mi.Mesh) for shape in shapes):
        return None
    return proto.group_id


def _varying_owners(
    root: Usd.Prim, owners: list[str], variation: Variation, skinned: Any
) -> list[tuple[Usd.Prim, list[int], bool]]:
    """The prims of a prototype whose meshes (indices into ``owners``, the group's shapes in
    order) move: their own attributes, or an ancestor's up to ``root``, might vary, or a
    skeleton deforms them; and whether the skeleton is all that moves them."""
    stage = root.GetStage()
    moving: dict[str, tuple[list[int], bool]] = {}
    for index, path in enumerate(owners):
        if path in moving:
            moving[path][0].append(index)
            continue
        prim = stage.GetPrimAtPath(path)
        by_skeleton = path in skinned.points
        by_attributes = False
        walk = prim
        while not by_attributes and walk and walk != root.GetParent():
            by_attributes = variation.attributes(walk)
            walk = walk.GetParent()
        if by_skeleton or by_attributes or path in skinned.transforms:
            moving[path] = ([index], by_skeleton and not by_attributes)
    return [(stage.GetPrimAtPath(p), idx, only) for p, (idx, only) in moving.items()]


def frame_time(time: Usd.TimeCode) -> float | None:
    """The time code as a number (``None`` for USD's default and earliest times)."""
    if time.IsDefault() or time.IsEarliestTime():
        return None
    return float(time.GetValue())
