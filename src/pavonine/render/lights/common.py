"""What every light translator shares: reading attributes (and remembering which were honoured),
UsdLux radiance, light textures, and the audit that warns about every attribute left unused.

Radiance of every light: ``L = intensity · 2^exposure · color · blackbody(colorTemperature)``
(UsdLux, OpenUSD ≥ 24.08 light docs). A translator reads attributes through
:meth:`LightReader.value`, which records them as honoured; :func:`audit` then warns, naming the
attribute, about every UsdLux property of the prim (its schema and applied ``ShapingAPI``,
``ShadowAPI``... as USD's schema registry lists them) that is authored with a value other than its
fallback, or a relationship with targets, and that no translator honoured.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from pxr import Sdf, Usd, UsdLux

from pavonine.render.diagnostics import Diagnostics

FLIP_Z = np.diag([1.0, -1.0, -1.0, 1.0])  # rotate 180° about X: USD lights emit along −Z
#: properties other translators (transforms, visibility, bounds) handle
NOT_LIGHTING = {"xformOpOrder", "visibility", "purpose", "proxyPrim", "extent"}
#: viewport-only properties: no effect on a render by definition
VIEWPORT_ONLY = {"guideRadius"}
RADIANCE_INPUTS = (
    "inputs:intensity",
    "inputs:exposure",
    "inputs:color",
    "inputs:enableColorTemperature",
    "inputs:colorTemperature",
)


@dataclass
class LightReader:
    """A light prim's attributes at one time, and the names the translators honoured."""

    prim: Usd.Prim
    time: Usd.TimeCode
    diag: Diagnostics
    used: set[str] = field(default_factory=set)
    moot: dict[str, str] = field(default_factory=dict)  # attribute → why it changes nothing here

    @property
    def where(self) -> str:
        return str(self.prim.GetPath())

    def value(self, name: str, fallback: Any = None) -> Any:
        """An attribute's value (``fallback`` if absent), recorded as honoured."""
        self.used.add(name)
        return self.peek(name, fallback)

    def peek(self, name: str, fallback: Any = None) -> Any:
        """An attribute's value without recording it (read to decide, not honoured)."""
        attr = self.prim.GetAttribute(name)
        value = attr.Get(self.time) if attr else None
        return fallback if value is None else value

    def number(self, name: str, fallback: float, honour: bool = True) -> float:
        """A float attribute (honoured unless told); a NaN or wrongly typed value is warned."""
        value = self.value(name, fallback) if honour else self.peek(name, fallback)
        try:
            number = float(value)
        except (TypeError, ValueError):
            number = float("nan")
        if not math.isfinite(number):
            self.warn(f"{name} = {value!r} is not a finite number; using {fallback}")
            return fallback
        return number

    def colour(self, name: str, fallback: tuple, honour: bool = True) -> np.ndarray:
        """A colour attribute as 3 floats (honoured unless told); a wrong value is warned."""
        value = self.value(name, fallback) if honour else self.peek(name, fallback)
        try:
            rgb = np.asarray(value, dtype=np.float64).reshape(-1)
        except (TypeError, ValueError):
            rgb = np.array([])
        if rgb.size != 3 or not np.all(np.isfinite(rgb)):
            self.warn(f"{name} = {value!r} is not a colour (3 finite numbers); using {fallback}")
            return np.asarray(fallback, dtype=np.float64)
        return rgb

    def honour(self, *names: str) -> None:
        """Record attributes as honoured without reading them (e.g. no effect by definition)."""
        self.used.update(names)

    def no_effect(self, reason: str, *names: str) -> None:
        """Attributes that change nothing on this light (UsdLux says so): warned when authored."""
        for name in names:
            self.moot.setdefault(name, reason)

    def warn(self, message: str) -> None:
        self.diag.warn(self.where, message)


def cone_has_no_effect(reader: LightReader, widest: float) -> bool:
    """True (and the cone honoured) when a ``ShapingAPI`` cone cannot narrow an emitter whose own
    emission spans ``widest`` degrees off its axis (90 for one-sided, 180 for all-round emitters).

    The cone attenuates from ``angle · (1 − softness)`` on (UsdLux), so it changes nothing when that
    angle is at least ``widest``: a 180° cone without softness is no shaping at all, for any light.
    """
    angle = reader.number("inputs:shaping:cone:angle", 90.0, honour=False)
    softness = float(
        np.clip(reader.number("inputs:shaping:cone:softness", 0.0, honour=False), 0, 1)
    )
    if angle * (1.0 - softness) >= widest:
        reader.honour("inputs:shaping:cone:angle", "inputs:shaping:cone:softness")
        return True
    return False


def radiance(reader: LightReader) -> np.ndarray:
    """``intensity · 2^exposure · color · blackbody(T)`` (linear Rec.709), before normalisation."""
    intensity = reader.number("inputs:intensity", 1.0)
    exposure = reader.number("inputs:exposure", 0.0)
    color = reader.colour("inputs:color", (1.0, 1.0, 1.0))
    if bool(reader.value("inputs:enableColorTemperature", False)):
        temperature = reader.number("inputs:colorTemperature", 6500.0)
        color = color * np.asarray(UsdLux.BlackbodyTemperatureAsRgb(temperature), dtype=np.float64)
    else:
        reader.honour("inputs:colorTemperature")  # no effect unless enabled (UsdLux)
    return intensity * 2.0**exposure * color


#: The largest RGB emission Mitsuba's float32 spectra hold: an RGB emitter's spectrum is
#: ``2 · max(rgb)`` times a D65-shaped curve (``RGBIlluminantSpectrum``) whose peak is 1.19
#: times its mean, so a component above FLT_MAX / 2.38 = 1.43e38 evaluates to NaN at some
#: wavelengths (measured with llvm_ad_spectral, 471 wavelengths 360–830 nm: 1.43e38 finite,
#: 1.6e38 NaN at 500 nm) and the light renders black.
MAX_EMISSION = float(np.finfo(np.float32).max) / 2.4


def largest_emission(entry: Any) -> float:
    """The largest emitted value in a Mitsuba emitter entry (its ``rgb`` values and bitmaps, in
    the float32 Mitsuba receives); ``inf`` when one is NaN or infinite."""
    if isinstance(entry, dict):
        values = [largest_emission(v) for v in entry.values()]
        if entry.get("type") == "rgb":
            values.append(float(np.max(np.abs(np.asarray(entry["value"], np.float64)))))
        return max(values, default=0.0)
    if type(entry).__name__ == "Bitmap":
        pixels = np.abs(np.asarray(entry, dtype=np.float32))
        return float(np.max(pixels)) if np.all(np.isfinite(pixels)) else math.inf
    return 0.0


def audit(reader: LightReader) -> None:
    """Warn about every authored UsdLux property of the prim that no translator honoured."""
    definition = reader.prim.GetPrimDefinition()
    names = lux_property_names(reader.prim)
    for attr in reader.prim.GetAuthoredAttributes():
        if (
            f"inputs:{attr.GetName()}" in names and attr.HasAuthoredValue()
        ):  # pre-21.05 UsdLux spelling, read by nothing
            reader.warn(
                f"{attr.GetName()} is the old UsdLux name of inputs:{attr.GetName()}; "
                "USD reads only inputs:…, so it is ignored"
            )
    for name in sorted(names):
        if name in reader.used or name in NOT_LIGHTING or name in VIEWPORT_ONLY:
            continue
        prop = reader.prim.GetProperty(name)
        if isinstance(prop, Usd.Relationship):
            if prop.GetTargets():
                reader.warn(f"{name} is not supported by the Mitsuba delegate; ignored")
            continue
        if not isinstance(prop, Usd.Attribute) or not prop.HasAuthoredValue():
            continue
        value = prop.Get(reader.time)
        fallback = definition.GetAttributeFallbackValue(name)
        if _same(value, fallback):
            continue
        if name in reader.moot:
            reader.warn(f"{name} = {_show(value)} changes nothing: {reader.moot[name]}")
        else:
            reader.warn(
                f"{name} = {_show(value)} is not supported by the Mitsuba delegate; ignored"
            )


def lux_property_names(prim: Usd.Prim) -> set[str]:
    """The properties UsdLux schemas give ``prim`` (its light type and applied UsdLux APIs)."""
    registry = Usd.SchemaRegistry()
    names: set[str] = set()
    if _is_lux(prim.GetTypeName()):
        names.update(registry.FindConcretePrimDefinition(prim.GetTypeName()).GetPropertyNames())
    for schema in prim.GetAppliedSchemas():
        base = schema.split(":")[0]
        if _is_lux(base):
            definition = registry.FindAppliedAPIPrimDefinition(base)
            if definition:
                names.update(definition.GetPropertyNames())
    return names


def _is_lux(schema_name: str) -> bool:
    schema_type = Usd.SchemaRegistry.GetTypeFromSchemaTypeName(schema_name)
    return bool(schema_name) and schema_type.typeName.startswith("UsdLux")


def _same(value: Any, fallback: Any) -> bool:
    if isinstance(value, Sdf.AssetPath) or isinstance(fallback, Sdf.AssetPath):
        return _asset(value) == _asset(fallback)
    if value is None or fallback is None:
        return value is fallback or (value in ("", 0) and fallback is None)
    try:
        return bool(np.allclose(np.asarray(value, dtype=float), np.asarray(fallback, dtype=float)))
    except (TypeError, ValueError):
        return str(value) == str(fallback)


def _asset(value: Any) -> str:
    return value.path if isinstance(value, Sdf.AssetPath) else str(value or "")


def _show(value: Any) -> str:
    if isinstance(value, Sdf.AssetPath):
        return repr(value.path)
    if isinstance(value, (list, tuple)) or (
        hasattr(value, "__len__") and not isinstance(value, str)
    ):
        try:
            return "(" + ", ".join(f"{float(v):g}" for v in value) + ")"
        except (TypeError, ValueError):
            return repr(value)
    return repr(value)


def light_texture(reader: LightReader, name: str) -> np.ndarray | None:
    """H×W×3 linear RGB of a light's texture attribute (read through ``Ar``), or ``None`` (warned)."""
    from pavonine.render.shading.textures import TextureError, read_texels

    asset = reader.value(name, None)
    if not isinstance(asset, Sdf.AssetPath) or not asset.path:
        return None
    if not asset.resolvedPath:
        reader.warn(f"{name} {asset.path!r} not found; using the light's colour")
        return None
    try:
        rgba, _ = read_texels(asset.resolvedPath, "auto")
    except TextureError as exc:
        reader.warn(f"{exc}; using the light's colour")
        return None
    return rgba[..., :3]


def cone_solid_angle(angle_deg: float) -> float:
    """Solid angle (sr) of a cone of full apex angle ``angle_deg``: 2π(1 − cos(θ/2))."""
    return 2.0 * math.pi * (1.0 - math.cos(math.radians(angle_deg) / 2.0))


def frame(z: np.ndarray) -> np.ndarray:
    """An orthonormal frame (columns x, y, z) around the unit vector ``z``."""
    helper = np.array([0.0, 0.0, 1.0]) if abs(z[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=1)


def transform(matrix: np.ndarray):
    """A Mitsuba transform of a 4×4 column-vector matrix."""
    import mitsuba as mi

    return mi.ScalarTransform4f(np.asarray(matrix, dtype=np.float64).tolist())


def rgb(value) -> dict:
    """An ``rgb`` dict (a scalar is broadcast)."""
    return {"type": "rgb", "value": [float(v) for v in np.broadcast_to(value, 3)]}


def bitmap(values: np.ndarray, raw: bool = False) -> Any:
    """A float32 ``mi.Bitmap`` of H×W×C values."""
    import mitsuba as mi

    with np.errstate(over="ignore"):  # beyond float32: inf, warned by name (largest_emission)
        pixels = np.ascontiguousarray(values, dtype=np.float32)
    return mi.Bitmap(pixels)
