"""UsdLux lights → Mitsuba emitters, following the UsdLux units (OpenUSD ≥ 24.08 light docs).

Radiance of every light: ``L = intensity · 2^exposure · color · blackbody(colorTemperature)``.
``normalize`` divides area lights by their world-space area (so power stays put when they are
resized). A ``DistantLight`` with ``normalize`` takes ``intensity`` as the illuminance E on a
surface facing it (lux-like, W/m² in Mitsuba's units); without it, the radiance is ``L`` over its
disc of angular diameter ``angle``, so ``E = L · Ω``, ``Ω = 2π(1 − cos(angle/2))`` (solid angle of a
cone, sr). A sun with ``angle > 0`` is a far disc emitter of that angular size; ``angle = 0`` is
Mitsuba's delta ``directional``.

Conventions: USD lights emit along their local −Z; Mitsuba's area emitters emit along their
shape's +Z, so rect and disk lights are turned 180° about X (as hdmitsuba does).
"""

from __future__ import annotations

import math
import os

import numpy as np
from pxr import Usd, UsdGeom, UsdLux

from pavonine.render.diagnostics import Diagnostics
from pavonine.render.xform import to_mitsuba

DELTA_ANGLE_DEG = 1e-3  # below this a DistantLight is a delta directional light
FAR_SUN_DISTANCE = 1.0e3  # the sun disc sits this many scene radii away
SUPPORTED = ("DistantLight", "DomeLight", "SphereLight", "RectLight", "DiskLight")
FLIP_Z = np.diag([1.0, -1.0, -1.0, 1.0])  # rotate 180° about X


def is_light(prim: Usd.Prim) -> bool:
    """True for any UsdLux light (boundable or not)."""
    return prim.HasAPI(UsdLux.LightAPI)


def radiance(prim: Usd.Prim, time: Usd.TimeCode) -> np.ndarray:
    """``intensity · 2^exposure · color · blackbody(T)`` (linear Rec.709), before normalisation."""
    light = UsdLux.LightAPI(prim)
    intensity = float(light.GetIntensityAttr().Get(time))
    exposure = float(light.GetExposureAttr().Get(time))
    color = np.array(light.GetColorAttr().Get(time), dtype=np.float64)
    if light.GetEnableColorTemperatureAttr().Get(time):
        temperature = float(light.GetColorTemperatureAttr().Get(time))
        color = color * np.array(UsdLux.BlackbodyTemperatureAsRgb(temperature), dtype=np.float64)
    return intensity * 2.0**exposure * color


def cone_solid_angle(angle_deg: float) -> float:
    """Solid angle (sr) of a cone of full apex angle ``angle_deg``: 2π(1 − cos(θ/2))."""
    return 2.0 * math.pi * (1.0 - math.cos(math.radians(angle_deg) / 2.0))


def translate_light(
    prim: Usd.Prim,
    world_usd: np.ndarray,
    time: Usd.TimeCode,
    diag: Diagnostics,
    scene_center: np.ndarray,
    scene_radius: float,
) -> dict | None:
    """The Mitsuba scene-dict entry of one light, or ``None`` (with a warning) if unsupported."""
    kind = prim.GetTypeName()
    where = str(prim.GetPath())
    if kind not in SUPPORTED:
        diag.warn(where, f"{kind or 'light'} is not supported by the Mitsuba delegate; skipped")
        return None
    L = radiance(prim, time)
    normalize = bool(UsdLux.LightAPI(prim).GetNormalizeAttr().Get(time))
    to_world = to_mitsuba(world_usd)
    if kind == "DistantLight":
        angle = float(UsdLux.DistantLight(prim).GetAngleAttr().Get(time))
        direction = -world_usd[2, :3]
        return distant_light(L, normalize, angle, direction, scene_center, scene_radius)
    if kind == "DomeLight":
        return dome_light(prim, L, to_world, time, diag)
    if kind == "SphereLight":
        light = UsdLux.SphereLight(prim)
        r = float(light.GetRadiusAttr().Get(time))
        r_world = r * np.linalg.norm(world_usd[0, :3])
        if light.GetTreatAsPointAttr().Get(time) or r <= 0.0:
            # radiant intensity of a sphere of radiance L: I = L · π r² (W/sr); normalised: L / 4
            intensity = L / 4.0 if normalize else L * (math.pi * r_world**2 if r > 0 else 1.0)
            return {
                "type": "point",
                "position": world_usd[3, :3].tolist(),
                "intensity": _rgb(intensity),
            }
        if normalize:
            L = L / (4.0 * math.pi * r_world**2)
        return {
            "type": "sphere",
            "to_world": _transform(to_world @ np.diag([r, r, r, 1.0])),
            "emitter": {"type": "area", "radiance": _rgb(L)},
        }
    if kind == "RectLight":
        light = UsdLux.RectLight(prim)
        w, h = float(light.GetWidthAttr().Get(time)), float(light.GetHeightAttr().Get(time))
        if normalize:
            area = np.linalg.norm(np.cross(world_usd[0, :3] * w, world_usd[1, :3] * h))
            L = L / max(area, 1e-12)
        emitter: dict = {"type": "area", "radiance": _rgb(L)}
        texture = _texture_path(light.GetTextureFileAttr(), time, where, diag)
        if texture is not None:
            emitter["radiance"] = {"type": "bitmap", "filename": texture, "raw": False}
            if np.ptp(L) > 1e-6 or abs(float(np.mean(L)) - 1.0) > 1e-6:
                diag.warn(
                    where, "textured RectLight: the texture is the radiance; intensity ignored"
                )
        return {
            "type": "rectangle",
            "to_world": _transform(to_world @ FLIP_Z @ np.diag([w / 2, h / 2, 1.0, 1.0])),
            "emitter": emitter,
        }
    light = UsdLux.DiskLight(prim)
    r = float(light.GetRadiusAttr().Get(time))
    if normalize:
        r_world = r * np.linalg.norm(world_usd[0, :3])
        L = L / max(math.pi * r_world**2, 1e-12)
    return {
        "type": "disk",
        "to_world": _transform(to_world @ FLIP_Z @ np.diag([r, r, 1.0, 1.0])),
        "emitter": {"type": "area", "radiance": _rgb(L)},
    }


def distant_light(
    L: np.ndarray,
    normalize: bool,
    angle_deg: float,
    direction: np.ndarray,
    scene_center: np.ndarray,
    scene_radius: float,
) -> dict:
    """A sun travelling along ``direction``: delta ``directional`` or a far disc of ``angle_deg``."""
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    omega = cone_solid_angle(angle_deg)
    if angle_deg < DELTA_ANGLE_DEG:
        return {"type": "directional", "direction": d.tolist(), "irradiance": _rgb(L)}
    irradiance = L if normalize else L * omega
    distance = FAR_SUN_DISTANCE * max(scene_radius, 1e-3)
    half = math.radians(min(angle_deg, 179.0)) / 2.0
    disc_radius = distance * math.tan(half)
    origin = np.asarray(scene_center, dtype=np.float64) - d * distance
    frame = _frame(d)  # columns: x, y, z=d
    to_world = np.eye(4)
    to_world[:3, :3] = frame * disc_radius
    to_world[:3, 2] = d  # keep z unit (disk is flat)
    to_world[:3, 3] = origin
    return {
        "type": "disk",
        "to_world": _transform(to_world),
        "emitter": {"type": "area", "radiance": _rgb(irradiance / omega)},
    }


def dome_light(
    prim: Usd.Prim, L: np.ndarray, to_world: np.ndarray, time: Usd.TimeCode, diag: Diagnostics
) -> dict:
    """``DomeLight``: ``envmap`` of a lat-long texture (scaled by mean L), or ``constant`` radiance L."""
    where = str(prim.GetPath())
    light = UsdLux.DomeLight(prim)
    texture = _texture_path(light.GetTextureFileAttr(), time, where, diag)
    if texture is not None:
        fmt = light.GetTextureFormatAttr().Get(time)
        if fmt not in ("automatic", "latlong"):
            diag.warn(
                where, f"DomeLight texture format {fmt!r} is not supported; treated as latlong"
            )
        if np.ptp(L) > 1e-6:
            diag.warn(
                where,
                "DomeLight colour tint is applied as its mean (Mitsuba envmap scale is a scalar)",
            )
        up = _pole_rotation(prim, light, time)
        return {
            "type": "envmap",
            "filename": texture,
            "scale": float(np.mean(L)),
            "to_world": _transform(to_world @ up),
        }
    return {"type": "constant", "radiance": _rgb(L)}


def default_lights(
    camera_to_world: np.ndarray, up: np.ndarray, scene_center: np.ndarray, scene_radius: float
) -> dict:
    """A sun from the camera's right and a little above (as in the paper's Fig. 13) and a pale-blue sky.

    The sun is about 26° off the viewing direction, so a feather facing the camera shows its
    structural colour: the mirror lobe (crescent spread 15°) then reaches the camera. The sun's
    illuminance is π, so a white Lambertian surface facing it has radiance 1.
    """
    right = -camera_to_world[:3, 0]  # Mitsuba camera's local +X points left
    forward = camera_to_world[:3, 2]
    up = np.asarray(up, dtype=np.float64)
    toward_sun = right * 0.42 + up * 0.12 - forward * 0.9
    sun = distant_light(np.full(3, math.pi), True, 0.53, -toward_sun, scene_center, scene_radius)
    sky = {"type": "constant", "radiance": _rgb([0.06, 0.08, 0.11])}
    return {"default_sun": sun, "default_sky": sky}


def _pole_rotation(prim: Usd.Prim, light: UsdLux.DomeLight, time: Usd.TimeCode) -> np.ndarray:
    """Envmaps are +Y up in Mitsuba; a Z-up stage (poleAxis ``scene``/``Z``) turns them up to +Z."""
    pole = "scene"
    attr = light.GetPrim().GetAttribute("poleAxis")
    if attr and attr.HasAuthoredValue():
        pole = str(attr.Get(time))
    z_up = pole == "Z" or (pole == "scene" and UsdGeom.GetStageUpAxis(prim.GetStage()) == "Z")
    if not z_up:
        return np.eye(4)
    return np.array([[1, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1]], dtype=np.float64)


def _texture_path(attr, time: Usd.TimeCode, where: str, diag: Diagnostics) -> str | None:
    asset = attr.Get(time) if attr else None
    if asset is None or not asset.path:
        return None
    resolved = asset.resolvedPath
    if not resolved or not os.path.isfile(resolved):
        diag.warn(where, f"light texture {asset.path!r} not found; using the light's colour")
        return None
    return resolved


def _frame(z: np.ndarray) -> np.ndarray:
    helper = np.array([0.0, 0.0, 1.0]) if abs(z[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=1)


def _transform(matrix: np.ndarray):
    import mitsuba as mi

    return mi.ScalarTransform4f(np.asarray(matrix, dtype=np.float64).tolist())


def _rgb(value) -> dict:
    return {"type": "rgb", "value": [float(v) for v in np.broadcast_to(value, 3)]}
