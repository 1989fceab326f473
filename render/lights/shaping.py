"""Point lights and UsdLux ``ShapingAPI``: a ``SphereLight`` with ``treatAsPoint`` (or no radius)
becomes Mitsuba's ``point`` light, or its ``spot`` light when shaped by a cone.

The shaping follows the UsdLux definitions (OpenUSD's usdLux clarification): with θ the angle
between the emission direction and the light's −Z axis,

* cone: ``1 − smoothstep(θ, θ_cutoff·(1 − softness), θ_cutoff)``, ``θ_cutoff = shaping:cone:angle``;
* focus: ``lerp(|cos θ|^focus, focusTint, 1)`` (per channel; a black tint is plain falloff).

Mitsuba's ``spot`` projects a texture over its cone through ``uv = ½ + ½ · tan θ_{x,y} / tan
θ_cutoff``; that texture carries the whole profile above (the spot's own linear falloff is switched
off, ``beam_width = cutoff_angle``), so the image is exactly the UsdLux profile, sampled on a
256² grid (coarser near the axis for cones close to 90°). Mitsuba's spot cannot exceed 90°: a
cone between 90° and 180° and focus without a cone are warned about, and IES profiles are not
supported (warned).

Intensity of a point light: a sphere of radiance L and radius r seen from afar has radiant
intensity ``I = L · π r²``; normalised (L / 4π r²) that is ``L / 4``. Without a radius, I = L.
"""

from __future__ import annotations

import math

import numpy as np
from pxr import UsdLux

from pavonine.render.lights.common import (
    FLIP_Z,
    LightReader,
    bitmap,
    cone_has_no_effect,
    radiance,
    rgb,
    transform,
)
from pavonine.render.xform import to_mitsuba

PROFILE_SIZE = 256
MAX_CUTOFF_DEG = 89.9  # the spot's texture projection goes through tan(cutoff)
CONE_INPUTS = ("inputs:shaping:cone:angle", "inputs:shaping:cone:softness")
FOCUS_INPUTS = ("inputs:shaping:focus", "inputs:shaping:focusTint")


def point(reader: LightReader, world_usd: np.ndarray, radius: float) -> dict:
    """A point-like SphereLight: Mitsuba ``point``, or ``spot`` when a cone under 90° shapes it."""
    L = radiance(reader)
    scale = float(np.mean(np.linalg.norm(world_usd[:3, :3], axis=1)))
    r_world = max(radius, 0.0) * scale
    if bool(reader.value("inputs:normalize", False)):
        intensity = L / 4.0
    else:
        intensity = L * (math.pi * r_world**2 if r_world > 0 else 1.0)
    angle = reader.number("inputs:shaping:cone:angle", 90.0, honour=False)
    focus = reader.number("inputs:shaping:focus", 0.0, honour=False)
    shaped = reader.prim.HasAPI(UsdLux.ShapingAPI) or any(
        reader.prim.GetAttribute(name).HasAuthoredValue() for name in CONE_INPUTS
    )
    if shaped and angle <= 90.0:
        reader.honour(*CONE_INPUTS, *FOCUS_INPUTS)
        softness = float(np.clip(reader.number("inputs:shaping:cone:softness", 0.0), 0.0, 1.0))
        tint = reader.colour("inputs:shaping:focusTint", (0.0, 0.0, 0.0))
        cutoff = min(angle, MAX_CUTOFF_DEG)
        frame = _unit_axes(to_mitsuba(world_usd)) @ FLIP_Z  # the spot shines along its +Z
        return {
            "type": "spot",
            "to_world": transform(frame),
            "intensity": rgb(intensity),
            "cutoff_angle": cutoff,
            "beam_width": cutoff,
            "texture": {
                "type": "bitmap",
                "bitmap": bitmap(profile(cutoff, angle, softness, focus, tint)),
                "raw": False,
                "wrap_mode": "clamp",
            },
        }
    cone_has_no_effect(reader, 180.0)
    if focus > 0.0:
        reader.honour(*FOCUS_INPUTS)
        reader.warn(
            "inputs:shaping:focus needs inputs:shaping:cone:angle below 90° on a point light; ignored"
        )
    return {"type": "point", "position": world_usd[3, :3].tolist(), "intensity": rgb(intensity)}


def profile(
    texture_cutoff_deg: float, cone_deg: float, softness: float, focus: float, tint: np.ndarray
) -> np.ndarray:
    """The UsdLux cone × focus profile as Mitsuba's spot texture (N×N×3, see module doc)."""
    n = PROFILE_SIZE
    tan_cutoff = math.tan(math.radians(texture_cutoff_deg))
    centres = (np.arange(n) + 0.5) / n * 2.0 - 1.0
    x, y = np.meshgrid(centres * tan_cutoff, centres * tan_cutoff)
    theta = np.arctan(np.hypot(x, y))
    return cone_factor(theta, math.radians(cone_deg), softness)[..., None] * focus_colour(
        theta, focus, tint
    )


def cone_factor(theta: np.ndarray, cutoff: float, softness: float) -> np.ndarray:
    """``1 − smoothstep(θ, cutoff·(1 − softness), cutoff)`` (a hard edge when softness is 0)."""
    start = cutoff * (1.0 - softness)
    if cutoff - start <= 1e-9:
        return (theta <= cutoff).astype(np.float64)
    t = np.clip((theta - start) / (cutoff - start), 0.0, 1.0)
    return 1.0 - t * t * (3.0 - 2.0 * t)


def focus_colour(theta: np.ndarray, focus: float, tint: np.ndarray) -> np.ndarray:
    """``tint + |cos θ|^focus · (1 − tint)`` per channel; focus ≤ 0 is no focus."""
    factor = np.abs(np.cos(theta)) ** max(focus, 0.0)
    tint = np.broadcast_to(np.asarray(tint, dtype=np.float64), 3)
    return tint + factor[..., None] * (1.0 - tint)


def _unit_axes(matrix: np.ndarray) -> np.ndarray:
    """A column-vector transform with its axes normalised (a spot has no size)."""
    m = np.array(matrix, dtype=np.float64)
    for i in range(3):
        n = np.linalg.norm(m[:3, i])
        if n > 0:
            m[:3, i] /= n
    return m
