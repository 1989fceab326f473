"""Point lights and UsdLux ``ShapingAPI``: a ``SphereLight`` with ``treatAsPoint`` (or no radius)
becomes Mitsuba's ``point`` light, or its ``spot`` light when shaped by a cone.

The shaping follows the UsdLux definitions (OpenUSD's usdLux clarification): with θ the angle
between the emission direction and the light's −Z axis,

* cone: ``1 − smoothstep(θ, θ_cutoff·(1 − softness), θ_cutoff)``, ``θ_cutoff = shaping:cone:angle``;
* focus: ``lerp(|cos θ|^focus, focusTint, 1)`` (per channel; a black tint is plain falloff).

Mitsuba's ``spot`` projects a texture over its cone through ``uv = ½ + ½ · tan θ_{x,y} / tan
θ_cutoff``; that texture carries the whole profile above (the spot's own linear falloff is switched
off, ``beam_width = cutoff_angle``), so the image is exactly the UsdLux profile, sampled on a
256² grid (coarser near the axis for cones close to 90°).

What the spot cannot do (an IES profile, ``shaping:ies:file``; a cone between 90° and 180°; focus
without a cone) goes through :func:`shaping_table`: the whole UsdLux shaping, IES profile × cone ×
focus, as a θ×φ table of factors that the profile emitters (:mod:`.ies_emitter`) read per
direction, for point lights and for the area lights alike (:mod:`.area`). The IES profile is
sampled as UsdLux says (``ShapingAPI``: θ from the light's −Z axis through
``shaping:ies:angleScale``, and ``shaping:ies:normalize`` dividing by the profile's mean
intensity; :mod:`.ies`).

Intensity of a point light: a sphere of radiance L and radius r seen from afar has radiant
intensity ``I = L · π r²``; normalised (L / 4π r²) that is ``L / 4``. Without a radius, I = L.
"""

from __future__ import annotations

import math

import numpy as np
from pxr import UsdLux

from pavonine.render.lights import ies, ies_emitter
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
IES_FILE = "inputs:shaping:ies:file"
IES_INPUTS = ("inputs:shaping:ies:angleScale", "inputs:shaping:ies:normalize")
NO_IES = f"there is no {IES_FILE} to scale or normalise"
#: the shaping table's rows over θ = 0..180° (0.25° each) and columns over φ (one when the
#: shaping is the same all around the axis)
TABLE_THETA, TABLE_PHI = 720, 128


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
    shaped = is_shaped(reader)
    has_ies = bool(getattr(reader.peek(IES_FILE), "path", ""))
    if not has_ies:
        reader.no_effect(NO_IES, *IES_INPUTS)
    wide_cone = shaped and 90.0 < angle and not cone_has_no_effect(reader, 180.0)
    if has_ies or wide_cone or (focus > 0.0 and not (shaped and angle <= 90.0)):
        table = shaping_table(reader, 180.0)
        if table is not None:
            return profile_point(world_usd, intensity, table)
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
    return {"type": "point", "position": world_usd[3, :3].tolist(), "intensity": rgb(intensity)}


def is_shaped(reader: LightReader) -> bool:
    """``ShapingAPI`` is applied (its fallbacks hold: a 90° cone) or a cone or focus is authored."""
    return reader.prim.HasAPI(UsdLux.ShapingAPI) or any(
        reader.prim.GetAttribute(name).HasAuthoredValue() for name in CONE_INPUTS + FOCUS_INPUTS
    )


def profile_point(world_usd: np.ndarray, intensity: np.ndarray, table: np.ndarray) -> dict:
    """A point light whose intensity ``table`` shapes per direction (``pavonine_ies_point``)."""
    ies_emitter.register()
    return {
        "type": ies_emitter.POINT_PLUGIN,
        "inner": {
            "type": "point",
            "position": world_usd[3, :3].tolist(),
            "intensity": rgb(intensity),
        },
        "light_to_world": transform(_unit_axes(to_mitsuba(world_usd))),
        "profile": bitmap(table[..., None]),
    }


def ies_profile(reader: LightReader) -> ies.IesProfile | None:
    """The light's ``shaping:ies:file`` profile, or ``None``: none authored, or unusable (warned,
    and the light is rendered unshaped by it)."""
    from pavonine.base.asset_io import local_file

    asset = reader.value(IES_FILE, None)
    if not getattr(asset, "path", ""):
        reader.no_effect(NO_IES, *IES_INPUTS)
        return None
    reader.honour(*IES_INPUTS)
    if not asset.resolvedPath:
        reader.warn(f"{IES_FILE} {asset.path!r} not found; the light is not shaped by it")
        return None
    try:
        profile = ies.read_ies(local_file(asset.resolvedPath))
    except (ies.IesError, OSError) as exc:
        reader.warn(f"{IES_FILE}: {exc}; the light is not shaped by it")
        return None
    if profile.photometric_type != 1:
        kind = ies.PHOTOMETRIC_TYPES[profile.photometric_type]
        reader.warn(
            f"{IES_FILE} {asset.path!r}: photometric type {kind} is not supported (UsdLux "
            "shapes by type C profiles, vertical angles from the light's axis); not shaped by it"
        )
        return None
    return profile


def shaping_table(reader: LightReader, widest: float) -> np.ndarray | None:
    """The light's whole UsdLux shaping, IES profile × cone × focus, as ``TABLE_THETA`` rows of θ
    (from the light's −Z axis) by 1 or ``TABLE_PHI`` columns of φ; ``None`` when nothing shapes
    an emitter whose own emission spans ``widest`` degrees off its axis."""
    profile = ies_profile(reader)
    cone_free = not is_shaped(reader) or cone_has_no_effect(reader, widest)
    focus = max(reader.number("inputs:shaping:focus", 0.0), 0.0)
    if profile is None and cone_free and focus == 0.0:
        reader.honour("inputs:shaping:focusTint")
        return None
    around = profile is None or len(profile.horizontal_deg) == 1
    n_phi = 1 if around else TABLE_PHI
    theta, _ = ies.texel_angles(TABLE_THETA, n_phi)
    if profile is None:
        table = np.ones((TABLE_THETA, n_phi))
    else:
        scale = reader.number("inputs:shaping:ies:angleScale", 0.0)
        normalize = bool(reader.value("inputs:shaping:ies:normalize", False))
        table = ies.profile_table(profile, scale, normalize, TABLE_THETA, n_phi)
    if not cone_free:
        angle = reader.number("inputs:shaping:cone:angle", 90.0)
        softness = float(np.clip(reader.number("inputs:shaping:cone:softness", 0.0), 0.0, 1.0))
        table = table * cone_factor(theta, math.radians(angle), softness)
    tint = reader.colour("inputs:shaping:focusTint", (0.0, 0.0, 0.0))
    if focus > 0.0:
        if np.ptp(tint) > 1e-6:
            reader.warn(
                f"inputs:shaping:focusTint = {tuple(float(t) for t in tint)} is coloured; the "
                "shaping table holds one factor per direction, so its mean is used"
            )
        table = table * focus_colour(theta, focus, np.full(3, tint.mean()))[..., 0]
    return np.ascontiguousarray(table, dtype=np.float64)


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
