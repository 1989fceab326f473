"""Area lights → Mitsuba shapes with ``area`` emitters: ``SphereLight`` (with a radius),
``RectLight`` (optionally textured), ``DiskLight``, ``CylinderLight``.

``normalize`` divides the radiance by the light's world-space area (UsdLux). USD lights emit along
their local −Z; Mitsuba's ``rectangle`` and ``disk`` emit along +Z, so they are turned 180° about X
(as hdmitsuba does). A RectLight's ``texture:file`` multiplies its radiance (colour, intensity and
exposure included); the image's s runs along the light's +X and t along +Y. A CylinderLight lies
along its X axis, centred, and emits from its curved side only (Mitsuba's ``cylinder`` has no caps).

Shaping: these lights already emit into a hemisphere (or all around, for spheres and cylinders), so
a cone of 90° or more (180° for spheres and cylinders) changes nothing. Narrower cones, focus and
IES profiles (``ShapingAPI``) scale the radiance by the direction the light leaves in, relative to
the light's −Z axis (:func:`.shaping.shaping_table`), through the ``pavonine_ies_area`` emitter
(:mod:`.ies_emitter`).
"""

from __future__ import annotations

import math

import numpy as np

from pavonine.render.lights import ies_emitter
from pavonine.render.lights.common import (
    FLIP_Z,
    LightReader,
    bitmap,
    light_texture,
    radiance,
    rgb,
    transform,
)
from pavonine.render.lights.shaping import shaping_table
from pavonine.render.shading.network import COLOR
from pavonine.render.shading.textures import bitmap_dict
from pavonine.render.xform import to_mitsuba


def _axis_lengths(world_usd: np.ndarray) -> np.ndarray:
    """World-space lengths of the light's local unit X, Y, Z axes."""
    return np.linalg.norm(np.asarray(world_usd, dtype=np.float64)[:3, :3], axis=1)


def sphere(reader: LightReader, world_usd: np.ndarray, radius: float) -> dict:
    """A SphereLight with a radius: a Mitsuba ``sphere`` with an area emitter."""
    r_world = radius * float(np.mean(_axis_lengths(world_usd)))
    L = _radiance(reader, 4.0 * math.pi * r_world**2)
    to_world = to_mitsuba(world_usd) @ np.diag([radius, radius, radius, 1.0])
    return {
        "type": "sphere",
        "to_world": transform(to_world),
        "emitter": _area(reader, L, 180.0, world_usd),
    }


def rect(reader: LightReader, world_usd: np.ndarray) -> dict:
    """A RectLight: a Mitsuba ``rectangle`` (radiance textured by ``texture:file``)."""
    w = reader.number("inputs:width", 1.0)
    h = reader.number("inputs:height", 1.0)
    area = float(np.linalg.norm(np.cross(world_usd[0, :3] * w, world_usd[1, :3] * h)))
    L = _radiance(reader, area)
    texels = light_texture(reader, "inputs:texture:file")
    radiance_texture = None
    if texels is not None:
        radiance_texture = bitmap_dict(texels * L, COLOR, "clamp", np.eye(3))
    emitter = _area(reader, L, 90.0, world_usd, radiance_texture)
    to_world = to_mitsuba(world_usd) @ FLIP_Z @ np.diag([w / 2, h / 2, 1.0, 1.0])
    return {"type": "rectangle", "to_world": transform(to_world), "emitter": emitter}


def disk(reader: LightReader, world_usd: np.ndarray) -> dict:
    """A DiskLight: a Mitsuba ``disk``."""
    r = reader.number("inputs:radius", 0.5)
    axes = _axis_lengths(world_usd)
    L = _radiance(reader, math.pi * r * r * axes[0] * axes[1])
    to_world = to_mitsuba(world_usd) @ FLIP_Z @ np.diag([r, r, 1.0, 1.0])
    return {
        "type": "disk",
        "to_world": transform(to_world),
        "emitter": _area(reader, L, 90.0, world_usd),
    }


def cylinder(reader: LightReader, world_usd: np.ndarray) -> dict:
    """A CylinderLight along local X: a Mitsuba ``cylinder`` (unit radius and length, along +Z)."""
    length = reader.number("inputs:length", 1.0)
    r = reader.number("inputs:radius", 0.5)
    if bool(reader.value("treatAsLine", False)):
        reader.warn("treatAsLine is not supported; rendered as a cylinder of its radius")
    axes = _axis_lengths(world_usd)
    L = _radiance(reader, 2.0 * math.pi * r * math.sqrt(axes[1] * axes[2]) * length * axes[0])
    # Mitsuba's canonical cylinder: radius 1 around +Z, z from 0 to 1 → USD: along X, centred
    local = np.array(
        [[0, 0, length, -length / 2], [r, 0, 0, 0], [0, r, 0, 0], [0, 0, 0, 1]], dtype=np.float64
    )
    return {
        "type": "cylinder",
        "to_world": transform(to_mitsuba(world_usd) @ local),
        "emitter": _area(reader, L, 180.0, world_usd),
    }


def _radiance(reader: LightReader, world_area: float) -> np.ndarray:
    """The light's radiance, ÷ its world area when ``normalize`` is on."""
    L = radiance(reader)
    if bool(reader.value("inputs:normalize", False)):
        L = L / max(world_area, 1e-12)
    return L


def _area(
    reader: LightReader,
    L: np.ndarray,
    widest: float,
    world_usd: np.ndarray,
    texture: dict | None = None,
) -> dict:
    """The area emitter of radiance ``L`` (or ``texture``), shaped (``pavonine_ies_area``) when the
    light's shaping narrows an emission that spans ``widest`` degrees off its axis."""
    table = shaping_table(reader, widest)
    if table is None:
        return {"type": "area", "radiance": texture or rgb(L)}
    ies_emitter.register()
    return {
        "type": ies_emitter.AREA_PLUGIN,
        "radiance": ies_emitter.emissive(texture or rgb(L)),
        "light_to_world": transform(_rotation(world_usd)),
        "profile": bitmap(table[..., None]),
    }


def _rotation(world_usd: np.ndarray) -> np.ndarray:
    """The light's frame (Mitsuba layout) with unit axes and no translation: its −Z is its axis."""
    m = to_mitsuba(np.asarray(world_usd, dtype=np.float64))
    m[:3, 3] = 0.0
    m[:3, :3] /= np.maximum(np.linalg.norm(m[:3, :3], axis=0), 1e-12)
    return m
