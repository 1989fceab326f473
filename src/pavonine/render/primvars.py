"""Primvars of a gprim: read, validated, spread to face-vertex corners, named as Mitsuba attributes.

Every numeric primvar (``float``, ``float2``, ``float3``, ``color3f``, ``normal3f``,
``texCoord2f``, ``point3f``, ``vector3f``, ... and their indexed forms) is read flattened, with its
interpolation. The contract with the shading side (:func:`mesh_attribute_name`): a primvar with
``vertex``, ``varying`` or ``faceVarying`` interpolation reaches the Mitsuba mesh as the vertex
attribute ``vertex_<name>``, one with ``uniform`` interpolation as the face attribute
``face_<name>`` (``:`` in the name becomes ``_``); ``constant`` primvars are not attributes (the
shading side reads them from USD). Attributes are built for the primvars a material reads
(``MaterialSpec.primvars``), with 1 or 3 channels (:func:`attribute_values`); a 3-channel one also
gets a *colour twin* named ``<attribute>_color`` (:data:`COLOR_TWIN`), because Mitsuba upsamples
an RGB attribute to a spectrum only when its name ends in ``color``: colour inputs read the twin,
data inputs (vectors) the attribute as authored.

Anything that cannot be used warns once, naming the prim and the primvar: non-numeric types, an
``elementSize`` above 1, out-of-range indices, too few values for the interpolation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pxr import Usd, UsdGeom, Vt

from pavonine.render.attributes import authored_type
from pavonine.render.diagnostics import Diagnostics

PER_VERTEX = ("vertex", "varying")
#: suffix of a 3-channel attribute's twin that Mitsuba stores as spectral coefficients
COLOR_TWIN = "_color"
INTERPOLATIONS = ("constant", "uniform", "vertex", "varying", "faceVarying")
#: primvar namespaces consumed by other translators (UsdSkel's joint influences)
RESERVED = ("skel:",)
NUMERIC_ARRAYS = tuple(
    getattr(Vt, f"{kind}Array")
    for kind in (
        "Float",
        "Double",
        "Half",
        "Int",
        "UInt",
        "Int64",
        "Vec2f",
        "Vec2d",
        "Vec2h",
        "Vec2i",
        "Vec3f",
        "Vec3d",
        "Vec3h",
        "Vec3i",
        "Vec4f",
        "Vec4d",
        "Vec4h",
        "Vec4i",
    )
)


@dataclass
class Primvar:
    """A primvar's flattened values (N × components, float64), interpolation and role."""

    values: np.ndarray
    interpolation: str
    role: str = ""  # the type's role: Point, Normal, Vector, Color, TextureCoordinate or ""


def mesh_attribute_name(primvar_name: str, interpolation: str) -> str | None:
    """The Mitsuba mesh attribute carrying a primvar; ``None`` for ``constant`` primvars.

    ``vertex``/``varying``/``faceVarying`` → ``vertex_<name>``, ``uniform`` → ``face_<name>``;
    ``primvars:`` is dropped and ``:`` becomes ``_`` (``displayColor`` → ``vertex_displayColor``,
    ``pavonine:featherUV`` → ``vertex_pavonine_featherUV``).
    """
    name = primvar_name.removeprefix("primvars:").replace(":", "_")
    if interpolation == "constant":
        return None
    if interpolation == "uniform":
        return f"face_{name}"
    if interpolation in (*PER_VERTEX, "faceVarying"):
        return f"vertex_{name}"
    raise ValueError(f"unknown primvar interpolation {interpolation!r}")


def attribute_values(values: np.ndarray) -> np.ndarray:
    """(N, k) primvar values as a Mitsuba attribute's float32 (N, 1) or (N, 3).

    Mitsuba's ``mesh_attribute`` texture evaluates 1- or 3-channel attributes: 2 components are
    padded with 0 (a ``float2`` read as a ``float3``), 4 or more cut to the first 3.
    """
    values = np.asarray(values, dtype=np.float64).reshape(len(values), -1)
    if values.shape[1] == 2:
        values = np.pad(values, ((0, 0), (0, 1)))
    elif values.shape[1] > 3:
        values = values[:, :3]
    return values.astype(np.float32)


def as_matrix(values: object) -> np.ndarray | None:
    """A numeric Vt array as an (N, k) float64 matrix, a single number or vector as one row;
    ``None`` for anything else (strings, tokens, assets, booleans, matrices)."""
    if isinstance(values, NUMERIC_ARRAYS):
        array = np.asarray(values, dtype=np.float64)
        return array.reshape(len(array), -1) if len(array) else array.reshape(0, 1)
    if isinstance(values, (int, float)) and not isinstance(values, bool):
        return np.array([[float(values)]])
    if type(values).__name__.startswith("Vec") and type(values).__module__ == "pxr.Gf":
        return np.asarray(values, dtype=np.float64).reshape(1, -1)
    return None


def read_primvar(
    prim: Usd.Prim, name: str, time: Usd.TimeCode, diag: Diagnostics
) -> Primvar | None:
    """One primvar, flattened (indexed primvars expanded); ``None`` if absent or unusable."""
    primvar = UsdGeom.PrimvarsAPI(prim).GetPrimvar(name)
    if not primvar or not primvar.HasValue():
        return None
    return _read(primvar, time, diag)


def read_primvars(prim: Usd.Prim, time: Usd.TimeCode, diag: Diagnostics) -> dict[str, Primvar]:
    """Every usable primvar of ``prim`` by name (without ``primvars:``), ``normals`` excluded."""
    out: dict[str, Primvar] = {}
    for primvar in UsdGeom.PrimvarsAPI(prim).GetPrimvarsWithValues():
        name = primvar.GetPrimvarName()
        if name == "normals" or name.startswith(RESERVED):
            continue
        read = _read(primvar, time, diag)
        if read is not None:
            out[str(name)] = read
    return out


def _read(primvar: UsdGeom.Primvar, time: Usd.TimeCode, diag: Diagnostics) -> Primvar | None:
    where = str(primvar.GetAttr().GetPrim().GetPath())
    name = primvar.GetName()
    interpolation = str(primvar.GetInterpolation())
    if interpolation not in INTERPOLATIONS:
        diag.warn(where, f"{name} has unknown interpolation {interpolation!r}; ignored")
        return None
    raw = primvar.Get(time)
    if raw is None:
        return None
    values = as_matrix(raw)
    if values is None:
        diag.warn(
            where,
            f"{name} of type {authored_type(primvar.GetAttr())} is not numeric; ignored",
        )
        return None
    if primvar.GetElementSize() > 1:
        diag.warn(where, f"{name} has elementSize {primvar.GetElementSize()}; ignored")
        return None
    if primvar.IsIndexed():
        indices = np.asarray(primvar.GetIndices(time), dtype=np.int64)
        bad = (indices < 0) | (indices >= len(values))
        if np.any(bad):
            diag.warn(
                where,
                f"{name}: {int(bad.sum())} indices out of range (0..{len(values) - 1}); ignored",
            )
            return None
        values = values[indices]
    if len(values) == 0:
        return None
    if not np.all(np.isfinite(values)):
        diag.warn(where, f"{name} has NaN or infinite values; those read as 0")
        values = np.nan_to_num(values, nan=0.0, posinf=0.0, neginf=0.0)
    return Primvar(values, interpolation, str(primvar.GetTypeName().role))


def per_corner(
    primvar: Primvar,
    face_vertex_indices: np.ndarray,
    corner_face: np.ndarray,
    point_count: int,
    face_count: int,
    where: str,
    name: str,
    diag: Diagnostics,
) -> np.ndarray | None:
    """Primvar values for every face-vertex corner, whatever its interpolation."""
    values, interpolation = primvar.values, primvar.interpolation
    n_corners = len(face_vertex_indices)
    needed = {
        "constant": 1,
        "uniform": face_count,
        "vertex": point_count,
        "varying": point_count,
        "faceVarying": n_corners,
    }[interpolation]
    if len(values) < needed:
        what = {"uniform": "faces", "faceVarying": "face-vertices"}.get(interpolation, "points")
        diag.warn(
            where,
            f"{interpolation} primvar {name} has {len(values)} values for {needed} {what}; ignored",
        )
        return None
    if interpolation == "constant":
        return np.repeat(values[:1], n_corners, axis=0)
    if interpolation == "uniform":
        return values[corner_face]
    if interpolation in PER_VERTEX:
        return values[face_vertex_indices]
    return values[:n_corners]
