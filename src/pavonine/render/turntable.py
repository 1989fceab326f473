"""Turntables: N cameras orbiting a stage's bounds, written as a small USD layer over the stage.

``write_turntable_layer`` writes ``OUT.usda``, which sublayers the stage and adds
``/Turntable/Camera_0000`` … ``Camera_{N−1}``: camera ``i`` is the start camera turned by
``360° · i / N`` about the stage's up axis through the centre of its world bounds (so frame N
would repeat frame 0, and the sequence loops). The start camera is the one the render would
use (``camera``, else the RenderSettings camera, else the first camera), keeping its lens;
a stage without a camera gets a 35 mm lens 15° above the front, distanced so the bounding
sphere fits the frame. Frame ``i`` is rendered through ``Camera_i`` at one time code, so an
animated stage holds still while the camera turns; the layer can be opened in any USD viewer to
see the orbit.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdRender

from pavonine.base.errors import InputError
from pavonine.base.nesting import deep_call
from pavonine.render.camera import LENS_NUMBERS

ROOT = "/Turntable"
ELEVATION_DEG = 15.0
FOCAL_LENGTH = 35.0  # tenths of a scene unit (mm in a centimetre stage), as UsdGeom.Camera
APERTURE = (36.0, 24.0)
_LENS_ATTRIBUTES = (*LENS_NUMBERS, "projection")


def camera_name(index: int) -> str:
    """``Camera_0007``: the prim name of turntable frame ``index``."""
    return f"Camera_{index:04d}"


def world_bounds(stage: Usd.Stage, time: Usd.TimeCode) -> tuple[np.ndarray, np.ndarray]:
    """World-space bounds of the stage's renderable geometry (default and render purposes)."""
    cache = UsdGeom.BBoxCache(
        time, [UsdGeom.Tokens.default_, UsdGeom.Tokens.render], useExtentsHint=True
    )
    # recurses once per level of nesting: on a deep stack (base.nesting)
    box = deep_call(cache.ComputeWorldBound, stage.GetPseudoRoot()).ComputeAlignedRange()
    if box.IsEmpty():
        raise InputError(str(stage.GetRootLayer().realPath), "no geometry to orbit (empty bounds)")
    return np.array(box.GetMin(), dtype=np.float64), np.array(box.GetMax(), dtype=np.float64)


def start_camera(stage: Usd.Stage, camera: str | None) -> Usd.Prim | None:
    """The camera a render of ``stage`` would use: ``camera``, RenderSettings', or the first."""
    if camera is not None:
        prim = stage.GetPrimAtPath(camera)
        if not prim or not prim.IsA(UsdGeom.Camera):
            raise InputError("--camera", f"no camera at {camera}")
        return prim
    settings = UsdRender.Settings.GetStageRenderSettings(stage)
    if settings:
        targets = settings.GetCameraRel().GetForwardedTargets()
        if targets and stage.GetPrimAtPath(targets[0]).IsA(UsdGeom.Camera):
            return stage.GetPrimAtPath(targets[0])
    cameras = sorted(
        (p for p in stage.Traverse() if p.IsA(UsdGeom.Camera)), key=lambda p: str(p.GetPath())
    )
    return cameras[0] if cameras else None


def orbit(start: np.ndarray, center: np.ndarray, up: np.ndarray, frames: int) -> list[np.ndarray]:
    """``frames`` camera-to-world matrices (USD row-vector layout): ``start`` turned about the
    axis ``up`` through ``center`` by ``360° · i / frames``."""
    out = []
    for i in range(frames):
        turn = Gf.Matrix4d().SetRotate(Gf.Rotation(Gf.Vec3d(*up), 360.0 * i / frames))
        pivot = np.array(Gf.Matrix4d().SetTranslate(Gf.Vec3d(*(-center))), dtype=np.float64)
        back = np.array(Gf.Matrix4d().SetTranslate(Gf.Vec3d(*center)), dtype=np.float64)
        out.append(start @ pivot @ np.array(turn, dtype=np.float64) @ back)
    return out


def framing_matrix(
    lo: np.ndarray, hi: np.ndarray, up_axis: str, vertical_fov_deg: float
) -> np.ndarray:
    """A camera 15° above the stage's front (+Z for Y-up, −Y for Z-up), fitting the bounds."""
    center = (lo + hi) / 2.0
    radius = max(float(np.linalg.norm(hi - lo)) / 2.0, 1e-6)
    distance = 1.1 * radius / math.sin(math.radians(vertical_fov_deg) / 2.0)
    up = np.array([0.0, 0.0, 1.0]) if up_axis == "Z" else np.array([0.0, 1.0, 0.0])
    front = np.array([0.0, -1.0, 0.0]) if up_axis == "Z" else np.array([0.0, 0.0, 1.0])
    e = math.radians(ELEVATION_DEG)
    eye = center + distance * (front * math.cos(e) + up * math.sin(e))
    view = Gf.Matrix4d().SetLookAt(Gf.Vec3d(*eye), Gf.Vec3d(*center), Gf.Vec3d(*up))
    return np.array(view.GetInverse(), dtype=np.float64)


def write_turntable_layer(
    stage_path: str | os.PathLike,
    out_path: str | os.PathLike,
    frames: int,
    *,
    camera: str | None = None,
    time: float | None = None,
) -> list[str]:
    """Write the turntable layer (module docstring); returns the camera prim paths in order."""
    from pavonine.base.commit import atomic_path
    from pavonine.render.delegate import open_stage, render_time
    from pavonine.render.diagnostics import Diagnostics

    if frames < 1:
        raise InputError("--turntable", f"needs at least 1 frame, got {frames}")
    stage_path = Path(stage_path).resolve()
    stage = open_stage(stage_path, Diagnostics())
    code = render_time(stage, time)
    lo, hi = world_bounds(stage, code)
    up_axis = str(UsdGeom.GetStageUpAxis(stage))
    up = np.array([0.0, 0.0, 1.0]) if up_axis == "Z" else np.array([0.0, 1.0, 0.0])
    source = start_camera(stage, camera)
    if source is not None:
        start = np.array(
            UsdGeom.Xformable(source).ComputeLocalToWorldTransform(code), dtype=np.float64
        )
    else:
        fov = 2.0 * math.degrees(math.atan(APERTURE[1] / (2.0 * FOCAL_LENGTH)))
        start = framing_matrix(lo, hi, up_axis, fov)
    matrices = orbit(start, (lo + hi) / 2.0, up, frames)

    out_path = Path(out_path)
    edit = Usd.Stage.CreateInMemory()
    UsdGeom.Scope.Define(edit, ROOT)
    paths = []
    for i, matrix in enumerate(matrices):
        cam = UsdGeom.Camera.Define(edit, f"{ROOT}/{camera_name(i)}")
        cam.MakeMatrixXform().Set(Gf.Matrix4d(matrix.tolist()))
        if source is not None:
            for name in _LENS_ATTRIBUTES:
                value = source.GetAttribute(name).Get(code)
                if value is not None:
                    cam.GetPrim().GetAttribute(name).Set(value)
        else:
            cam.CreateFocalLengthAttr(FOCAL_LENGTH)
            cam.CreateHorizontalApertureAttr(APERTURE[0])
            cam.CreateVerticalApertureAttr(APERTURE[1])
            near = max(1e-3, float(np.linalg.norm(hi - lo)) * 1e-3)
            cam.CreateClippingRangeAttr(Gf.Vec2f(near, float(np.linalg.norm(hi - lo)) * 20.0))
        paths.append(str(cam.GetPath()))
    # A detached copy gets the sublayer: it is never composed here, where a relative path
    # would not resolve.
    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.TransferContent(edit.GetRootLayer())
    root = stage.GetRootLayer()
    try:
        layer.subLayerPaths.append(os.path.relpath(stage_path, out_path.resolve().parent))
    except ValueError:  # another drive
        layer.subLayerPaths.append(stage_path.as_posix())
    for key in ("upAxis", "metersPerUnit", "renderSettingsPrimPath", "timeCodesPerSecond"):
        if root.pseudoRoot.HasInfo(key):
            layer.pseudoRoot.SetInfo(key, root.pseudoRoot.GetInfo(key))
    layer.documentation = (
        f"Turntable of {stage_path.name}: {frames} cameras orbiting its bounds "
        f"(pavonine render --turntable {frames})."
    )
    with atomic_path(out_path) as tmp:
        if not layer.Export(str(tmp), args={"format": "usda"}):
            raise InputError(str(out_path), "cannot write the turntable layer")
    return paths
