"""``UsdGeom.Camera`` → Mitsuba sensors, and USD's default view for stages without one.

Follows ``GfCamera``: focal length and apertures in tenths of a scene unit (mm when the scene unit
is cm), aperture offsets shift the view window, ``clippingRange`` → near/far clip, ``fStop`` and
``focusDistance`` → ``thinlens``, ``orthographic`` projection → Mitsuba ``orthographic``.
The aperture is conformed to the image's aspect ratio by ``aspectRatioConformPolicy``
(``expandAperture`` by default, as in ``UsdRenderSettings``).

USD cameras look down their local −Z with +Y up; Mitsuba's look down +Z with +X to the left, so
the camera frame is turned 180° about Y.

A stage without a camera is seen the way USD's own tools see it (:func:`usd_view_camera`:
``usdrecord``'s ``UsdAppUtilsFrameRecorder`` and usdview's free camera), so that images can be set
beside theirs; :func:`portrait_camera` is Pavonine's framing of a flat asset (a feather) face-on,
long axis up, chosen explicitly (``framing="portrait"``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pxr import Gf, Usd, UsdGeom

from pavonine.render.diagnostics import Diagnostics
from pavonine.render.xform import to_mitsuba

APERTURE_UNIT = 0.1  # GfCamera: apertures and focal length are in tenths of a scene unit
TURN_Y = np.diag([-1.0, 1.0, -1.0, 1.0])  # rotate 180° about Y
DEFAULT_FOV_DEG = 30.0


@dataclass
class Sensor:
    """A Mitsuba sensor dict (without film/sampler) and its camera-to-world matrix (Mitsuba layout)."""

    sensor: dict
    to_world: np.ndarray
    path: str | None
    rfilter: str = "box"  # the film's reconstruction filter (hdmitsuba's pixel_filter setting)


def translate_camera(
    prim: Usd.Prim,
    world_usd: np.ndarray,
    time: Usd.TimeCode,
    resolution: tuple[int, int],
    pixel_aspect: float,
    conform: str,
    diag: Diagnostics,
    lens_only: bool = False,
) -> Sensor:
    """A USD camera as a Mitsuba ``perspective``/``thinlens``/``orthographic`` sensor, or (hdmitsuba's
    ``mitsuba:sensor:type``, unless ``lens_only``) an ``irradiancemeter`` to attach to a mesh
    (:mod:`.sensors`); the film filter is hdmitsuba's ``pixel_filter`` setting."""
    from pavonine.render import sensors

    check_camera(prim, world_usd, time)
    rfilter = sensors.pixel_filter(prim, diag)
    if not lens_only and sensors.sensor_type(prim, diag) == "irradiancemeter":
        frame = to_mitsuba(_without_scale(world_usd)) @ TURN_Y
        return Sensor({"type": "irradiancemeter"}, frame, str(prim.GetPath()), rfilter)
    camera = UsdGeom.Camera(prim).GetCamera(time)
    sensor = gf_camera_sensor(
        camera, world_usd, resolution, pixel_aspect, conform, diag, str(prim.GetPath())
    )
    sensor.rfilter = rfilter
    return sensor


def gf_camera_sensor(
    camera: Gf.Camera,
    world_usd: np.ndarray,
    resolution: tuple[int, int],
    pixel_aspect: float,
    conform: str,
    diag: Diagnostics,
    where: str | None,
) -> Sensor:
    """A ``GfCamera`` placed by ``world_usd`` (USD row-vector layout) as a Mitsuba sensor."""
    label = where or "(USD default view)"
    width, height = resolution
    image_aspect = width * pixel_aspect / height
    ha, va = camera.horizontalAperture, camera.verticalAperture
    if ha <= 0 or va <= 0 or camera.focalLength <= 0:
        lens = ", ".join(
            f"{name} = {value:g}"
            for name, value in (
                ("focalLength", camera.focalLength),
                ("horizontalAperture", ha),
                ("verticalAperture", va),
            )
        )
        raise ValueError(f"{label}: {lens}: focalLength and apertures must be positive")
    fit_horizontal = _fits_horizontally(ha / va, image_aspect, conform, label, diag)
    window_w = ha if fit_horizontal else va * image_aspect
    window_h = ha / image_aspect if fit_horizontal else va
    frame = to_mitsuba(_without_scale(world_usd)) @ TURN_Y
    near, far = camera.clippingRange.min, camera.clippingRange.max
    sensor: dict = {"near_clip": float(max(near, 1e-6)), "far_clip": float(far)}
    if camera.projection == Gf.Camera.Orthographic:
        half = window_w * APERTURE_UNIT / 2.0
        sensor.update(type="orthographic", to_world=_mi(frame @ np.diag([half, half, 1.0, 1.0])))
        return Sensor(sensor, frame, where)
    # Mitsuba's pixels are square: the caller renders round(width · pixelAspectRatio) columns
    # and resamples them to ``width`` (see api._pixel_aspect_resampler).
    to_world = frame
    half_w = window_w / (2.0 * camera.focalLength)
    sensor.update(
        type="perspective",
        fov_axis="x",
        fov=math.degrees(2.0 * math.atan(half_w)),
        principal_point_offset_x=float(camera.horizontalApertureOffset / window_w),
        principal_point_offset_y=float(-camera.verticalApertureOffset / window_h),
        to_world=_mi(to_world),
    )
    if camera.fStop > 0 and camera.focusDistance > 0:
        sensor["type"] = "thinlens"
        sensor["aperture_radius"] = camera.focalLength * APERTURE_UNIT / (2.0 * camera.fStop)
        sensor["focus_distance"] = float(camera.focusDistance)
        for key in ("principal_point_offset_x", "principal_point_offset_y"):
            if abs(sensor.pop(key)) > 1e-9:
                diag.warn(label, "aperture offsets are ignored with depth of field (thinlens)")
    return Sensor(sensor, to_world, where)


#: Camera attributes that must be finite numbers (the image is made through them: an unusable
#: value is an error, not a warning, since no fallback would be the camera the stage names).
LENS_NUMBERS = (
    "focalLength",
    "horizontalAperture",
    "verticalAperture",
    "horizontalApertureOffset",
    "verticalApertureOffset",
    "clippingRange",
    "fStop",
    "focusDistance",
)


def check_camera(prim: Usd.Prim, world_usd: np.ndarray, time: Usd.TimeCode) -> None:
    """``ValueError`` naming the attribute when a camera value or its transform is NaN, infinite
    or (transform) beyond :data:`~pavonine.render.limits.MAX_COORDINATE`."""
    from pavonine.render.limits import MAX_COORDINATE
    from pavonine.render.xform import transform_source, usable_transform

    where = str(prim.GetPath())
    for name in LENS_NUMBERS:
        attr = prim.GetAttribute(name)
        value = attr.Get(time) if attr else None
        if value is None:
            continue
        try:
            array = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError):
            continue
        if not np.all(np.isfinite(array)):
            raise ValueError(f"{where}: {name} = {value} is not a finite number")
    clipping = UsdGeom.Camera(prim).GetClippingRangeAttr().Get(time)
    if clipping is not None and not clipping[1] > max(clipping[0], 1e-6):
        raise ValueError(
            f"{where}: clippingRange = {tuple(clipping)}: far must be beyond near (and near > 0)"
        )
    if not usable_transform(world_usd, MAX_COORDINATE):
        source = transform_source(prim, time, MAX_COORDINATE)
        raise ValueError(
            f"{where}: transform is NaN, infinite or beyond ±{MAX_COORDINATE:g} (from {source})"
        )


def usd_view_matrix(bounds: tuple[np.ndarray, np.ndarray], up_axis: str) -> np.ndarray:
    """Where ``UsdAppUtilsFrameRecorder`` puts its camera for a stage without one (USD row-vector
    layout): usdAppUtils/frameRecorder.cpp, ``_ComputeCameraToFrameStage``.

    The default ``GfCamera`` looks down −Z (Y up) or, on a Z-up stage, is turned 90° about X to
    look along +Y; its focal plane passes through the bounds' centre at the distance where the
    bounds' half diagonal in that plane fills half the horizontal field of view, backed up by half
    the bounds' depth (and by the near clip, 1, when closer than it).
    """
    lo, hi = (np.asarray(b, dtype=np.float64) for b in bounds)
    centre, dim = (lo + hi) / 2.0, hi - lo
    camera = Gf.Camera()
    corner = dim[[0, 1]] / 2.0 if up_axis == "Y" else dim[[0, 2]] / 2.0
    half_fov = math.radians(camera.GetFieldOfView(Gf.Camera.FOVHorizontal) / 2.0)
    distance = float(np.linalg.norm(corner)) / math.tan(half_fov)
    distance += dim[2] / 2.0 if up_axis == "Y" else dim[1] / 2.0
    if distance < camera.clippingRange.min:
        distance += camera.clippingRange.min
    matrix = np.eye(4)
    if up_axis == "Y":
        matrix[3, :3] = centre + np.array([0.0, 0.0, distance])
    else:
        matrix[:3, :3] = [[1, 0, 0], [0, 0, 1], [0, -1, 0]]  # 90° about X (row-vector layout)
        matrix[3, :3] = centre + np.array([0.0, -distance, 0.0])
    return matrix


def usd_view_camera(
    bounds: tuple[np.ndarray, np.ndarray],
    up_axis: str,
    resolution: tuple[int, int],
    pixel_aspect: float,
    conform: str,
    diag: Diagnostics,
) -> Sensor:
    """USD's default view of a stage without a camera: ``GfCamera``'s 50 mm lens and 35 mm academy
    aperture (20.955 × 15.2908 mm), clipping 1 to 10⁶, placed by :func:`usd_view_matrix`; the
    aperture is conformed to the image like an authored camera's."""
    return gf_camera_sensor(
        Gf.Camera(), usd_view_matrix(bounds, up_axis), resolution, pixel_aspect, conform, diag, None
    )


def usd_view_resolution(width: int) -> tuple[int, int]:
    """The image usdrecord makes of that view, ``width`` wide: height = width / aperture aspect."""
    return width, max(1, int(width / Gf.Camera().aspectRatio))


def stage_bounds(stage: Usd.Stage, time: Usd.TimeCode, purposes: tuple[str, ...]):
    """The stage's world bounds as usdrecord computes them (``UsdGeomBBoxCache`` with extents
    hints) for the rendered ``purposes``; ``None`` when empty. On a deep stack
    (:func:`pavonine.base.nesting.deep_call`)."""
    from pavonine.base.nesting import deep_call

    cache = UsdGeom.BBoxCache(time, list(purposes), useExtentsHint=True)
    # recurses once per level of nesting (3000 levels overflowed the main thread's stack)
    box = deep_call(cache.ComputeWorldBound, stage.GetPseudoRoot()).ComputeAlignedRange()
    if box.IsEmpty():
        return None
    return np.array(box.GetMin(), dtype=np.float64), np.array(box.GetMax(), dtype=np.float64)


def default_view(
    stage: Usd.Stage,
    time: Usd.TimeCode,
    synced,
    framing: str,
    resolution: tuple[int, int],
    aspect: tuple[float, str],
    diag: Diagnostics,
) -> Sensor:
    """The sensor of a stage without a camera: USD's default view of the stage's bounds (as
    usdrecord computes them, else the ``synced`` scene's), or Pavonine's ``"portrait"`` of the
    built geometry. ``aspect``: the product's pixel aspect ratio and conform policy."""
    from pavonine.render.settings import RENDERED_PURPOSES

    fallback = (np.full(3, -1.0), np.full(3, 1.0))
    if framing == "portrait":
        return portrait_camera(synced.bounds or fallback, synced.up_axis)
    bounds = stage_bounds(stage, time, RENDERED_PURPOSES) or synced.bounds or fallback
    return usd_view_camera(bounds, synced.up_axis, resolution, *aspect, diag)


def portrait_camera(bounds: tuple[np.ndarray, np.ndarray], up_axis: str) -> Sensor:
    """Pavonine's framing of a flat asset: seen face-on along its thin axis, long axis up (any other
    asset from the front, 20° above); a 30° field of view on the image's smaller side."""
    lo, hi = (np.asarray(b, dtype=np.float64) for b in bounds)
    center = (lo + hi) / 2.0
    extent = np.maximum(hi - lo, 1e-9)
    radius = max(float(np.linalg.norm(extent)) / 2.0, 1e-3)
    up = np.eye(3)[2 if up_axis == "Z" else 1]
    thin = int(np.argmin(extent))
    if extent[thin] < 0.25 * extent.max():
        view = -np.eye(3)[thin]  # look along the thin axis, from its + side
        others = [i for i in range(3) if i != thin]
        up = np.eye(3)[max(others, key=lambda i: extent[i])] if abs(up[thin]) > 0.5 else up
    else:
        front = np.array([0.0, 1.0, 0.0]) if up_axis == "Z" else np.array([0.0, 0.0, -1.0])
        view = front * math.cos(math.radians(20)) - up * math.sin(math.radians(20))
    fov = DEFAULT_FOV_DEG
    half = math.radians(fov) / 2.0
    distance = 1.1 * radius / math.sin(half)
    origin = center - view * distance
    to_world = _look_at(origin, center, up)
    sensor = {
        "type": "perspective",
        "fov": fov,
        "fov_axis": "smaller",
        "near_clip": float(max(distance - 2 * radius, distance * 1e-3)),
        "far_clip": float(distance + 4 * radius),
        "to_world": _mi(to_world),
    }
    return Sensor(sensor, to_world, None)


def _fits_horizontally(
    aperture_aspect: float, image_aspect: float, conform: str, where: str, diag: Diagnostics
) -> bool:
    if conform == "adjustApertureWidth":
        return False
    if conform == "adjustApertureHeight":
        return True
    if conform == "cropAperture":
        return aperture_aspect <= image_aspect
    if conform not in ("expandAperture", "adjustPixelAspectRatio"):
        diag.warn(where, f"unknown aspectRatioConformPolicy {conform!r}; using expandAperture")
    elif conform == "adjustPixelAspectRatio":
        diag.warn(
            where,
            "aspectRatioConformPolicy adjustPixelAspectRatio is not supported; using expandAperture",
        )
    return aperture_aspect >= image_aspect


def _look_at(origin: np.ndarray, target: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Mitsuba's look_at: columns (left, up, forward, origin)."""
    forward = target - origin
    forward /= np.linalg.norm(forward)
    left = np.cross(up, forward)
    left /= np.linalg.norm(left)
    new_up = np.cross(forward, left)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = left, new_up, forward, origin
    return m


def _without_scale(world_usd: np.ndarray) -> np.ndarray:
    m = np.array(world_usd, dtype=np.float64)
    for i in range(3):
        n = np.linalg.norm(m[i, :3])
        if n > 0:
            m[i, :3] /= n
    return m


def _mi(matrix: np.ndarray):
    import mitsuba as mi

    return mi.ScalarTransform4f(np.asarray(matrix, dtype=np.float64).tolist())
