"""UsdLux lights → Mitsuba emitters, one translator per light family.

* :mod:`.distant` — ``DistantLight`` (and the default sun and sky);
* :mod:`.dome` — ``DomeLight`` / ``DomeLight_1`` (pole axis, latlong textures);
* :mod:`.area` — ``SphereLight`` with a radius, ``RectLight``, ``DiskLight``, ``CylinderLight``;
* :mod:`.shaping` — point-like ``SphereLight`` → ``point``/``spot`` (``ShapingAPI`` cones, focus),
  and the whole ``ShapingAPI`` (IES × cone × focus) as a table of factors per direction;
* :mod:`.ies` — IES LM-63 files → luminous-intensity profiles (UsdLux ``angleScale``, ``normalize``);
* :mod:`.ies_emitter` — the Mitsuba emitters that read that table (point and area lights);
* :mod:`.common` — radiance, attribute reading and the audit that warns about every UsdLux
  attribute no translator honoured (from USD's schema registry, so new attributes are covered).

``MeshLightAPI`` meshes are emitters the delegate builds on the mesh itself
(:func:`mesh_light_radiance`).
"""

from __future__ import annotations

import numpy as np
from pxr import Usd, UsdLux

from pavonine.render.diagnostics import Diagnostics
from pavonine.render.lights import area, distant, dome, shaping
from pavonine.render.lights.common import (
    MAX_EMISSION,
    LightReader,
    audit,
    cone_has_no_effect,
    cone_solid_angle,
    largest_emission,
)
from pavonine.render.lights.common import radiance as _radiance
from pavonine.render.lights.distant import default_lights, distant_light

__all__ = [
    "cone_solid_angle",
    "default_lights",
    "distant_light",
    "is_dark",
    "is_light",
    "mesh_light_radiance",
    "radiance",
    "translate_light",
]

SUPPORTED = (
    "DistantLight",
    "DomeLight",
    "DomeLight_1",
    "SphereLight",
    "RectLight",
    "DiskLight",
    "CylinderLight",
)
NO_EMISSION = {
    "PortalLight": "PortalLight only guides a dome light's sampling, which Mitsuba does not need; ignored",
}


def is_light(prim: Usd.Prim) -> bool:
    """True for any UsdLux light (boundable or not)."""
    return prim.HasAPI(UsdLux.LightAPI)


def radiance(prim: Usd.Prim, time: Usd.TimeCode) -> np.ndarray:
    """``intensity · 2^exposure · color · blackbody(T)`` (linear Rec.709), before normalisation."""
    return _radiance(LightReader(prim, time, Diagnostics()))


def is_dark(prim: Usd.Prim, time: Usd.TimeCode) -> bool:
    """The light emits nothing Mitsuba can sample: its radiance is zero, negative or not finite
    (Mitsuba refuses such emitters: "no probability mass found")."""
    emitted = radiance(prim, time)
    finite = np.all(np.isfinite(emitted)) and np.max(np.abs(emitted)) <= MAX_EMISSION
    return not (finite and np.all(emitted >= 0) and np.any(emitted > 0))


def _overflow(largest: float) -> str:
    return (
        f"inputs:intensity × 2^inputs:exposure × inputs:color (with its normalisation and "
        f"texture) emits {largest:.3g}, beyond the {MAX_EMISSION:.3g} Mitsuba's float32 spectra "
        "hold (it would render black); skipped (it still counts as the stage's lighting)"
    )


def mesh_light_radiance(prim: Usd.Prim, time: Usd.TimeCode, diag: Diagnostics) -> np.ndarray:
    """A ``MeshLightAPI`` mesh's radiance; its other UsdLux attributes are audited (warned)."""
    reader = LightReader(prim, time, diag)
    L = _radiance(reader)
    reader.honour("inputs:normalize")  # the delegate divides by the mesh's world area
    cone_has_no_effect(reader, 90.0)
    audit(reader)
    return L


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
    reader = LightReader(prim, time, diag)
    if kind in NO_EMISSION:
        reader.warn(NO_EMISSION[kind])
        return None
    if kind not in SUPPORTED:
        reader.warn(f"{kind or 'light'} is not supported by the Mitsuba delegate; skipped")
        return None
    if is_dark(prim, time):
        emitted = radiance(prim, time)
        if np.all(np.isfinite(emitted)) and np.max(np.abs(emitted)) > MAX_EMISSION:
            reader.warn(_overflow(float(np.max(np.abs(emitted)))))
            return None
        reader.warn(
            f"inputs:intensity × 2^inputs:exposure × inputs:color = {emitted.tolist()}: the light "
            "emits nothing (zero, negative or not finite); skipped (it still counts as the "
            "stage's lighting: no default sun and sky)"
        )
        return None
    if kind == "DistantLight":
        entry = distant.translate(reader, world_usd, scene_center, scene_radius)
    elif kind in ("DomeLight", "DomeLight_1"):
        entry = dome.translate(reader, world_usd)
    elif kind == "SphereLight":
        radius = reader.number("inputs:radius", 0.5)
        if bool(reader.value("treatAsPoint", False)) or radius <= 0.0:
            entry = shaping.point(reader, world_usd, radius)
        else:
            entry = area.sphere(reader, world_usd, radius)
    elif kind == "RectLight":
        entry = area.rect(reader, world_usd)
    elif kind == "DiskLight":
        entry = area.disk(reader, world_usd)
    else:
        entry = area.cylinder(reader, world_usd)
    audit(reader)
    if not largest_emission(entry) <= MAX_EMISSION:
        reader.warn(_overflow(largest_emission(entry)))
        return None
    return entry
