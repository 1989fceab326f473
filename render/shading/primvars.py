"""``UsdPrimvarReader_*`` and ``displayColor``: primvars read by materials, per mesh.

A material is translated once, but a primvar it reads differs per mesh (constant on one,
per-vertex on another, missing on a third). So a reader becomes a *placeholder* in the material's
BSDF dict, and :func:`resolve` turns it into, for one mesh:

* a Mitsuba ``mesh_attribute`` texture named :func:`mesh_attribute_name` (``vertex_<name>`` for
  vertex/varying/faceVarying primvars, ``face_<name>`` for uniform ones, ``:`` → ``_``), the
  attribute the mesh translator attaches (:func:`mesh_attributes`);
* the primvar's value, when it is constant (inherited down namespace as USD says);
* the reader's ``fallback`` when the mesh has no such primvar.

``UsdPrimvarReader_float2`` feeding a texture's ``st`` is not a placeholder: it names the mesh's
texture coordinates (:mod:`.textures`). ``_string`` and ``_matrix`` readers are warned about.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from pxr import Usd, UsdGeom, UsdShade

from pavonine.render.diagnostics import Diagnostics
from pavonine.render.shading.network import COLOR, COMPONENTS, Affine, Network, as_mitsuba, coerce

PLACEHOLDER = "pavonine_primvar"  # the ``type`` of a placeholder node in a material's BSDF dict
#: Mitsuba upsamples a 3-channel attribute to a spectrum only when its name ends in "color", so
#: colour consumers read a twin of the attribute with this suffix (the plain one stays as authored)
COLOR_TWIN = "_color"
READER_FALLBACKS = {"float": 0.0, "int": 0.0, "float2": (0.0, 0.0)}
UNSUPPORTED_READERS = ("string", "matrix")


def mesh_attribute_name(primvar_name: str, interpolation: str) -> str:
    """The Mitsuba mesh attribute carrying a primvar (the delegate-wide naming contract)."""
    prefix = "face_" if interpolation == UsdGeom.Tokens.uniform else "vertex_"
    return prefix + primvar_name.replace(":", "_")


def reader(
    shader: UsdShade.Shader, shader_id: str, kind: str, affine: Affine, net: Network
) -> dict | None:
    """A ``UsdPrimvarReader_<type>`` feeding an input of ``kind``: a placeholder dict."""
    where = str(shader.GetPath())
    net.audit(shader)
    value_type = shader_id.removeprefix("UsdPrimvarReader_")
    if value_type in UNSUPPORTED_READERS:
        net.warn(where, f"{shader_id} is not supported by the Mitsuba delegate; using the fallback")
        return None
    name = str(net.constant(shader, "varname", "") or "")
    if not name:
        net.warn(where, f"{shader_id} has no varname; using its fallback")
        return None
    fallback = net.constant(shader, "fallback", READER_FALLBACKS.get(value_type, (0.0, 0.0, 0.0)))
    return placeholder(name, kind, coerce(fallback, kind, 0.0), affine, net)


def placeholder(name: str, kind: str, fallback: Any, affine: Affine, net: Network) -> dict:
    """The placeholder node for primvar ``name`` read as ``kind``."""
    net.use_primvar(name)
    return {
        "type": PLACEHOLDER,
        "primvar": name,
        "kind": kind,
        "fallback": np.atleast_1d(fallback).tolist(),
        "affine": (affine.a, affine.b),
    }


@dataclass(frozen=True)
class Binding:
    """How each primvar a material reads is found on one mesh (hashable: a BSDF cache key)."""

    entries: tuple[tuple[str, str, tuple[float, ...]], ...] = ()  # (name, interpolation, value)

    def lookup(self, name: str) -> tuple[str, tuple[float, ...]]:
        for entry_name, interpolation, value in self.entries:
            if entry_name == name:
                return interpolation, value
        return "missing", ()


def bind(names: Sequence[str], prim: Usd.Prim, time: Usd.TimeCode) -> Binding:
    """The interpolation (or constant value) of each primvar on ``prim``, ``missing`` if absent."""
    api = UsdGeom.PrimvarsAPI(prim)
    entries = []
    for name in names:
        primvar = api.FindPrimvarWithInheritance(name)
        if not primvar or not primvar.HasValue():
            entries.append((name, "missing", ()))
            continue
        interpolation = str(primvar.GetInterpolation())
        value: tuple[float, ...] = ()
        if interpolation == UsdGeom.Tokens.constant:
            value = _first_value(primvar.ComputeFlattened(time))
            if not value:
                interpolation = "missing"
        else:
            value = (float(_width(primvar)),)  # a per-element primvar: its channel count
        entries.append((name, interpolation, value))
    return Binding(tuple(entries))


def _width(primvar: UsdGeom.Primvar) -> int:
    """Channels of a primvar's elements as a mesh attribute (1 or 3)."""
    default = primvar.GetTypeName().scalarType.defaultValue
    width = len(default) if hasattr(default, "__len__") and not isinstance(default, str) else 1
    return 1 if width == 1 else 3


def _first_value(values: Any) -> tuple[float, ...]:
    """The (first) element of a constant primvar as floats; () when it is not numeric."""
    if values is None:
        return ()
    try:
        array = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        return ()
    if array.ndim == 0:
        return (float(array),)
    if array.size == 0:
        return ()
    first = array[0] if array.ndim > 1 or len(array) > 0 else array
    return tuple(float(v) for v in np.atleast_1d(first))


def resolve(tree: Any, binding: Binding, where: str, diag: Diagnostics) -> Any:
    """A copy of a BSDF dict tree with every placeholder resolved for one mesh."""
    if isinstance(tree, dict):
        if tree.get("type") == PLACEHOLDER:
            return _resolve_one(tree, binding, where, diag)
        return {k: resolve(v, binding, where, diag) for k, v in tree.items()}
    return tree


def _resolve_one(node: dict, binding: Binding, where: str, diag: Diagnostics) -> Any:
    kind, (a, b) = node["kind"], node["affine"]
    interpolation, value = binding.lookup(node["primvar"])
    if interpolation == "missing":
        return as_mitsuba(np.asarray(node["fallback"]) * a + b, kind)
    if interpolation == UsdGeom.Tokens.constant:
        return as_mitsuba(coerce(value, kind, node["fallback"]) * np.float64(a) + b, kind)
    if value and int(value[0]) != COMPONENTS[kind]:
        diag.warn(
            where,
            f"primvar {node['primvar']} has {int(value[0])} channel(s) but is read as {kind}; "
            "using the reader's fallback",
        )
        return as_mitsuba(np.asarray(node["fallback"]) * a + b, kind)
    if (a, b) != (1.0, 0.0):
        diag.warn(
            where,
            f"primvar {node['primvar']} cannot be remapped per vertex in Mitsuba; read as authored",
        )
    name = mesh_attribute_name(node["primvar"], interpolation)
    return {"type": "mesh_attribute", "name": name + (COLOR_TWIN if kind == COLOR else "")}


def mesh_attributes(
    primvars: dict[str, Any],
    topology: Any,
    triangle_mask: np.ndarray,
    corner_of_vertex: np.ndarray,
    where: str,
    diag: Diagnostics,
) -> dict[str, np.ndarray]:
    """Mitsuba attributes (named by :func:`mesh_attribute_name`) of non-constant primvars.

    ``primvars``: name → ``mesh.Primvar``; per-vertex values are taken at each output vertex's
    corner, uniform values at each triangle's polygon. 2-component values are padded to 3 and
    4-component ones cut to 3 (Mitsuba's attributes have 1 or 3 channels). 3-channel attributes
    also get their colour twin (``COLOR_TWIN``), which Mitsuba stores as spectral coefficients.
    """
    from pavonine.render.mesh import per_corner

    out: dict[str, np.ndarray] = {}
    for name, primvar in primvars.items():
        values = np.asarray(primvar.values, dtype=np.float64)
        values = values.reshape(len(values), -1)
        if values.shape[1] not in (1, 3):
            values = np.resize(values, (len(values), 3)) if values.shape[1] < 3 else values[:, :3]
        if primvar.interpolation == UsdGeom.Tokens.uniform:
            faces = topology.triangle_face[triangle_mask]
            if len(values) < topology.face_count:
                diag.warn(where, f"uniform primvar {name} has too few values; ignored")
                continue
            _add(out, mesh_attribute_name(name, primvar.interpolation), values[faces])
            continue
        corners = per_corner(
            type(primvar)(values, primvar.interpolation), topology, where, name, diag
        )
        if corners is not None:
            _add(out, mesh_attribute_name(name, primvar.interpolation), corners[corner_of_vertex])
    return out


def _add(out: dict[str, np.ndarray], name: str, values: np.ndarray) -> None:
    out[name] = values.astype(np.float32)
    if values.shape[1] == 3:
        out[name + COLOR_TWIN] = out[name]
