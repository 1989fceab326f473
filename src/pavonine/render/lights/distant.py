"""``DistantLight`` → a delta ``directional`` light or a far disc of the sun's angular size.

A normalised DistantLight takes ``intensity`` as the illuminance E on a surface facing it; without
``normalize`` the radiance is ``L`` over its disc of angular diameter ``angle``, so ``E = L · Ω``,
``Ω = 2π(1 − cos(angle/2))`` (solid angle of a cone, sr). ``angle = 0`` is Mitsuba's delta
``directional``. Shaping (cone, focus) has no effect on a light travelling along its own axis; an
authored cone or focus is reported as such.
"""

from __future__ import annotations

import math

import numpy as np

from pavonine.render.lights.common import (
    LightReader,
    cone_has_no_effect,
    cone_solid_angle,
    frame,
    radiance,
    rgb,
    transform,
)

DELTA_ANGLE_DEG = 1e-3  # below this a DistantLight is a delta directional light
FAR_SUN_DISTANCE = 1.0e3  # the sun disc sits this many scene radii away


def translate(
    reader: LightReader, world_usd: np.ndarray, scene_center: np.ndarray, scene_radius: float
) -> dict:
    """The Mitsuba emitter of a DistantLight."""
    L = radiance(reader)
    normalize = bool(reader.value("inputs:normalize", False))
    angle = reader.number("inputs:angle", 0.53)
    cone_has_no_effect(reader, 180.0)  # a 180° cone: no shaping, not worth a word
    reader.no_effect(
        "a DistantLight's light travels along its axis, where cones and focus do not attenuate",
        "inputs:shaping:cone:angle",
        "inputs:shaping:cone:softness",
        "inputs:shaping:focus",
        "inputs:shaping:focusTint",
    )
    return distant_light(L, normalize, angle, -world_usd[2, :3], scene_center, scene_radius)


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
        return {"type": "directional", "direction": d.tolist(), "irradiance": rgb(L)}
    irradiance = L if normalize else L * omega
    distance = FAR_SUN_DISTANCE * max(scene_radius, 1e-3)
    half = math.radians(min(angle_deg, 179.0)) / 2.0
    disc_radius = distance * math.tan(half)
    origin = np.asarray(scene_center, dtype=np.float64) - d * distance
    to_world = np.eye(4)
    to_world[:3, :3] = frame(d) * disc_radius
    to_world[:3, 2] = d  # keep z unit (the disk is flat)
    to_world[:3, 3] = origin
    return {
        "type": "disk",
        "to_world": transform(to_world),
        "emitter": {"type": "area", "radiance": rgb(irradiance / omega)},
    }


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
    sky = {"type": "constant", "radiance": rgb([0.06, 0.08, 0.11])}
    return {"default_sun": sun, "default_sky": sky}
