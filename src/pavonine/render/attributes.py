"""Reading geometry attributes defensively: the type USD says, finite values, or a warning.

USD lets any layer author an attribute with a type other than its schema's (``int normals = 7``,
``color3f[] points``, ``double radius`` as ``int``). Hydra's typed reads then either succeed (the
same C++ value type under another role: ``float3[]`` for ``point3f[]``) or fail and fall back.
These helpers do the same, and say so: each problem gives one warning naming the prim and the
attribute, and the caller gets ``None`` (or the fallback) instead of an exception.
"""

from __future__ import annotations

import math

import numpy as np
from pxr import Sdf, Usd, Vt

from pavonine.render.diagnostics import Diagnostics
from pavonine.render.limits import MAX_COORDINATE

VEC3_ARRAYS = (Vt.Vec3fArray, Vt.Vec3dArray, Vt.Vec3hArray)
INT_ARRAYS = (Vt.IntArray, Vt.Int64Array, Vt.UIntArray, Vt.UInt64Array)
FLOAT_ARRAYS = (Vt.FloatArray, Vt.DoubleArray, Vt.HalfArray)


def authored_type(attr: Usd.Attribute) -> str:
    """The attribute's type as its strongest opinion authors it (the schema's type if none)."""
    for spec in attr.GetPropertyStack(Usd.TimeCode.Default()):
        if spec.typeName:
            return str(spec.typeName)
    return str(attr.GetTypeName())


def _schema_type(attr: Usd.Attribute) -> str:
    return str(attr.GetTypeName())


def vec3_array(attr: Usd.Attribute, time: Usd.TimeCode, diag: Diagnostics) -> np.ndarray | None:
    """An array of 3-vectors of the schema's value type as (N, 3) float64; ``None`` if unauthored.

    As USD's typed reads: the same C++ value type under another role (``color3f[]`` or ``float3[]``
    for ``point3f[]``) is read, with a warning; another type (``double3[]``, ``int[]``, a single
    ``point3f``) warns and gives ``None``.
    """
    if not attr:
        return None
    value = attr.Get(time)
    if value is None:
        return None
    where, name = str(attr.GetPrim().GetPath()), attr.GetName()
    authored, expected = authored_type(attr), _schema_type(attr)
    authored_value = Sdf.ValueTypeNames.Find(authored)
    same_value_type = not authored_value or authored_value.type == attr.GetTypeName().type
    if not isinstance(value, VEC3_ARRAYS) or not same_value_type:
        diag.warn(where, f"{name} has type {authored}, expected {expected}; ignored")
        return None
    if authored != expected:
        diag.warn(where, f"{name} is authored as {authored}, not {expected}; read as {expected}")
    return np.asarray(value, dtype=np.float64).reshape(-1, 3)


def int_array(attr: Usd.Attribute, time: Usd.TimeCode, diag: Diagnostics) -> np.ndarray | None:
    """An integer array as int64; another type warns and gives ``None``."""
    if not attr:
        return None
    value = attr.Get(time)
    if value is None:
        return None
    if not isinstance(value, INT_ARRAYS):
        diag.warn(
            str(attr.GetPrim().GetPath()),
            f"{attr.GetName()} has type {authored_type(attr)}, expected {_schema_type(attr)}; ignored",
        )
        return None
    return np.asarray(value, dtype=np.int64)


def float_array(attr: Usd.Attribute, time: Usd.TimeCode, diag: Diagnostics) -> np.ndarray | None:
    """A float/double/half array as float64; another type warns and gives ``None``."""
    if not attr:
        return None
    value = attr.Get(time)
    if value is None:
        return None
    if not isinstance(value, FLOAT_ARRAYS):
        diag.warn(
            str(attr.GetPrim().GetPath()),
            f"{attr.GetName()} has type {authored_type(attr)}, expected {_schema_type(attr)}; ignored",
        )
        return None
    return np.asarray(value, dtype=np.float64)


def real(
    prim: Usd.Prim,
    name: str,
    time: Usd.TimeCode,
    diag: Diagnostics,
    fallback: float,
    *,
    minimum: float | None = None,
    positive: bool = False,
) -> float | None:
    """A real scalar attribute (the schema fallback when unauthored).

    Wrong type → warning, ``fallback``. Non-finite, beyond
    :data:`~pavonine.render.limits.MAX_COORDINATE`, below ``minimum`` or (``positive``) not > 0 →
    warning, ``None`` (the caller skips the prim: there is nothing sensible to draw).
    """
    attr = prim.GetAttribute(name)
    value = attr.Get(time) if attr else None
    where = str(prim.GetPath())
    if value is None:
        return fallback
    if isinstance(value, bool) or not isinstance(value, float):
        diag.warn(
            where,
            f"{name} has type {authored_type(attr)}, expected {_schema_type(attr)}; "
            f"using the fallback {fallback:g}",
        )
        return fallback
    if not math.isfinite(value):
        diag.warn(where, f"{name} is {value}; skipped")
        return None
    if abs(value) > MAX_COORDINATE:
        diag.warn(where, f"{name} = {value:g} is beyond ±{MAX_COORDINATE:g}; skipped")
        return None
    if positive and value <= 0.0:
        diag.warn(where, f"{name} = {value:g} must be positive; skipped")
        return None
    if minimum is not None and value < minimum:
        diag.warn(where, f"{name} = {value:g} is below {minimum:g}; skipped")
        return None
    return float(value)


def token(
    prim: Usd.Prim, name: str, time: Usd.TimeCode, diag: Diagnostics, allowed: tuple[str, ...]
) -> str:
    """A token attribute restricted to ``allowed`` (the first is the fallback, used with a warning)."""
    attr = prim.GetAttribute(name)
    value = attr.Get(time) if attr else None
    if value is None:
        return allowed[0]
    if str(value) not in allowed:
        diag.warn(
            str(prim.GetPath()),
            f"{name} = {value!r} is not one of {', '.join(allowed)}; using {allowed[0]!r}",
        )
        return allowed[0]
    return str(value)


def check_extent(prim: Usd.Prim, points: np.ndarray, time: Usd.TimeCode, diag: Diagnostics) -> None:
    """Warn when an authored ``extent`` is malformed or does not contain the points.

    The extent is a bounds hint (viewers cull with it); the points are what is rendered, so a bad
    extent changes nothing here but is reported, naming the prim.
    """
    attr = prim.GetAttribute("extent")
    if not attr or not attr.HasAuthoredValue():
        return
    value = attr.Get(time)
    where = str(prim.GetPath())
    if not isinstance(value, VEC3_ARRAYS) or len(value) != 2:
        diag.warn(where, f"extent of type {authored_type(attr)} is not two points; ignored")
        return
    lo, hi = np.asarray(value, dtype=np.float64)
    finite = points[np.all(np.isfinite(points), axis=1)]
    if np.any(lo > hi):
        diag.warn(where, f"extent {lo.tolist()}..{hi.tolist()} is inverted (min > max); ignored")
    elif len(finite):
        tolerance = 1e-4 * max(float(np.ptp(finite, axis=0).max()), 1e-12)
        if np.any(finite.min(axis=0) < lo - tolerance) or np.any(
            finite.max(axis=0) > hi + tolerance
        ):
            diag.warn(
                where, "extent does not contain the points; ignored (the points are rendered)"
            )
