"""A test stage for motion blur: an emissive quad crossing the image, its shutter, and the streak
it should make, computed from the motion alone (``tests/render/test_motion.py``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdRender, UsdShade

SIZE = (64, 32)  # the image: 1/32 scene unit per pixel in the quad's plane
UNITS_PER_PIXEL = 1.0 / 32.0
QUAD = (0.375, 0.5)  # width and height: 12 × 16 pixels
SPEED = 1.0  # scene units per time code: 32 pixels per frame
EMISSION = 1.0
#: Ways of moving the quad as a PointInstancer's instance (a black quad before a glowing backdrop).
INSTANCED = ("instancer", "prototype")


def motion_stage(
    path: Path,
    shutter: tuple[float, float] | None = (-0.25, 0.25),
    how: str = "xform",
    settings: dict[str, bool] | None = None,
    samples: dict[float, float] | None = None,
) -> Usd.Stage:
    """An emissive quad whose centre is, relative to the camera, at x = SPEED · (t − 1), seen
    face-on by ``/Cam`` (20 × 10 mm aperture, 50 mm lens, 5 units away: ±1 unit across the
    image), with ``shutter`` (open, close) authored on the camera. ``how`` it moves: by its
    parent's ``xformOp`` (``xform``), its ``points`` samples (``points``), the camera moving the
    other way (``camera``), one ``points`` sample at the frame with ``velocities``
    (``velocities``), or as the one instance of a PointInstancer with one ``positions`` sample
    and ``velocities`` (``instancer``), or as the prototype of a still instance, its ``points``
    time-sampled (``prototype``); ``samples`` replace the linear motion (xform only);
    ``settings``: RenderSettings booleans (``disableMotionBlur``, ``instantaneousShutter``);
    ``samples``: time → x of the quad's centre instead of the linear motion."""
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, "Y")
    stage.SetStartTimeCode(0)
    stage.SetEndTimeCode(2)
    stage.SetTimeCodesPerSecond(24)
    cam = UsdGeom.Camera.Define(stage, "/Cam")
    cam_op = cam.AddTranslateOp()
    if how == "camera":
        cam_op.Set(Gf.Vec3d(SPEED, 0, 5), Usd.TimeCode(0))
        cam_op.Set(Gf.Vec3d(-SPEED, 0, 5), Usd.TimeCode(2))
    else:
        cam_op.Set(Gf.Vec3d(0, 0, 5))
    cam.CreateFocalLengthAttr(50.0)
    cam.CreateHorizontalApertureAttr(20.0)
    cam.CreateVerticalApertureAttr(10.0)
    if shutter is not None:
        cam.CreateShutterOpenAttr(shutter[0])
        cam.CreateShutterCloseAttr(shutter[1])
    w, h = QUAD[0] / 2, QUAD[1] / 2
    corners = np.array([(-w, -h, 0), (w, -h, 0), (w, h, 0), (-w, h, 0)], dtype=np.float64)
    UsdGeom.Xform.Define(stage, "/World")
    instanced = how in INSTANCED
    quad_path = "/World/PI/Protos/Quad" if instanced else "/World/Quad"
    mesh = UsdGeom.Mesh.Define(stage, quad_path)
    mesh.CreateFaceVertexCountsAttr([4])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    mesh.CreateSubdivisionSchemeAttr("none")
    keys = samples or {0.0: -SPEED, 2.0: SPEED}
    per_second = SPEED * stage.GetTimeCodesPerSecond()  # velocities are per second
    if how == "xform":
        mesh.CreatePointsAttr([Gf.Vec3f(*p) for p in corners])
        op = UsdGeom.Xformable(stage.GetPrimAtPath("/World")).AddTranslateOp()
        for t, x in keys.items():
            op.Set(Gf.Vec3d(x, 0, 0), Usd.TimeCode(t))
    elif how in ("points", "prototype"):
        points = mesh.CreatePointsAttr()
        for t, x in keys.items():
            points.Set([Gf.Vec3f(p[0] + x, p[1], p[2]) for p in corners], Usd.TimeCode(t))
    elif how == "velocities":
        mesh.CreatePointsAttr().Set([Gf.Vec3f(*p) for p in corners], Usd.TimeCode(1))
        mesh.CreateVelocitiesAttr().Set([Gf.Vec3f(per_second, 0, 0)] * 4, Usd.TimeCode(1))
    else:
        mesh.CreatePointsAttr([Gf.Vec3f(*p) for p in corners])
    if instanced:
        instancer = UsdGeom.PointInstancer.Define(stage, "/World/PI")
        instancer.CreatePrototypesRel().SetTargets([quad_path])
        instancer.CreateProtoIndicesAttr([0])
        if how == "prototype":
            instancer.CreatePositionsAttr([Gf.Vec3f(0, 0, 0)])
        else:
            instancer.CreatePositionsAttr().Set([Gf.Vec3f(0, 0, 0)], Usd.TimeCode(1))
            instancer.CreateVelocitiesAttr().Set([Gf.Vec3f(per_second, 0, 0)], Usd.TimeCode(1))
    glow = _material(stage, "/Looks/Glow", EMISSION)
    if instanced:  # instances cannot emit: a black quad before a glowing backdrop
        backdrop = UsdGeom.Mesh.Define(stage, "/Backdrop")
        backdrop.CreatePointsAttr([(-4, -4, -1), (4, -4, -1), (4, 4, -1), (-4, 4, -1)])
        backdrop.CreateFaceVertexCountsAttr([4])
        backdrop.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
        backdrop.CreateSubdivisionSchemeAttr("none")
        UsdShade.MaterialBindingAPI.Apply(backdrop.GetPrim()).Bind(glow)
        glow = _material(stage, "/Looks/Black", 0.0)
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(glow)
    render = UsdRender.Settings.Define(stage, "/Render/Settings")
    render.CreateResolutionAttr(Gf.Vec2i(*SIZE))
    render.CreateCameraRel().SetTargets(["/Cam"])
    for name, value in (settings or {}).items():
        render.GetPrim().GetAttribute(name).Set(value)
    stage.SetMetadata("renderSettingsPrimPath", "/Render/Settings")
    stage.Save()
    return stage


def expected_streak(shutter: tuple[float, float], frame: float = 1.0) -> np.ndarray:
    """The mean coverage of each column by the quad over the open shutter (box pixel filter, the
    quad's centre at SPEED · (t − 1)): what a row through the quad's middle reads, / EMISSION."""
    width = SIZE[0]
    sub = (np.arange(width)[:, None] + (np.arange(64)[None, :] + 0.5) / 64) - width / 2
    x = sub * UNITS_PER_PIXEL  # world x of sub-pixel columns
    times = frame + shutter[0] + (np.arange(4096) + 0.5) / 4096 * (shutter[1] - shutter[0])
    centres = SPEED * (times - 1.0)
    inside = np.abs(x[..., None] - centres[None, None, :]) < QUAD[0] / 2
    return inside.mean(axis=(1, 2))


def crossings(profile: np.ndarray, level: float) -> tuple[float, float]:
    """Where ``profile`` first rises through and last falls through ``level`` (fractional
    columns, linearly interpolated)."""
    above = np.nonzero(profile >= level)[0]
    first, last = int(above[0]), int(above[-1])

    def between(i: int, j: int) -> float:
        a, b = profile[i], profile[j]
        return i + (level - a) / (b - a) * (j - i) if b != a else float(i)

    rise = between(first - 1, first) if first > 0 else 0.0
    fall = between(last, last + 1) if last + 1 < len(profile) else float(last)
    return rise, fall


def _material(stage: Usd.Stage, path: str, emission: float) -> UsdShade.Material:
    material = UsdShade.Material.Define(stage, path)
    shader = UsdShade.Shader.Define(stage, f"{path}/Surface")
    shader.CreateIdAttr("UsdPreviewSurface")
    shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(0, 0, 0))
    shader.CreateInput("emissiveColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(emission))
    material.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
    return material


def coverage(rgb: np.ndarray, how: str, level: float) -> np.ndarray:
    """The quad's coverage of each column of the middle rows, from the image (the light it emits,
    or for an instance the backdrop's light it blocks), ``level`` the unblocked radiance."""
    row = rgb[SIZE[1] // 2 - 4 : SIZE[1] // 2 + 4, :, 0].mean(axis=0) / level
    return 1.0 - row if how in INSTANCED else row


def skinned_prototype_stage(path: Path) -> Path:
    """Two instances of one prototype: a bar whose second joint bends 90° about z between time 0
    and 10 (a UsdSkel rig inside the PointInstancer's prototype, vertex normals authored), seen
    from above before a glowing backdrop (``tests/render/test_motion.py``)."""
    from skel_rig import bending_bar

    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, "Y")
    stage.SetStartTimeCode(0)
    stage.SetEndTimeCode(10)
    instancer = UsdGeom.PointInstancer.Define(stage, "/World/PI")
    root = bending_bar(stage, "/World/PI/Protos/Rig", half_width=0.2, normals=True).GetPrim()
    root = root.GetParent()
    instancer.CreatePrototypesRel().SetTargets([root.GetPath()])
    instancer.CreateProtoIndicesAttr([0, 0])
    instancer.CreatePositionsAttr([Gf.Vec3f(-2.5, -1, 0), Gf.Vec3f(0.5, -1, 0)])
    cam = UsdGeom.Camera.Define(stage, "/Cam")
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 0, 10))
    cam.CreateFocalLengthAttr(50.0)
    cam.CreateHorizontalApertureAttr(36.0)
    cam.CreateVerticalApertureAttr(36.0)
    backdrop = UsdGeom.Mesh.Define(stage, "/Backdrop")  # instances cannot emit: bars before a glow
    backdrop.CreatePointsAttr([(-6, -6, -1), (6, -6, -1), (6, 6, -1), (-6, 6, -1)])
    backdrop.CreateFaceVertexCountsAttr([4])
    backdrop.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    backdrop.CreateSubdivisionSchemeAttr("none")
    UsdShade.MaterialBindingAPI.Apply(backdrop.GetPrim()).Bind(
        _material(stage, "/Looks/Glow", EMISSION)
    )
    render = UsdRender.Settings.Define(stage, "/Render/Settings")
    render.CreateResolutionAttr(Gf.Vec2i(32, 32))
    render.CreateCameraRel().SetTargets(["/Cam"])
    stage.SetMetadata("renderSettingsPrimPath", "/Render/Settings")
    stage.GetRootLayer().Save()
    return path
