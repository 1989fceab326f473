"""``UsdPrimvarReader_*`` and ``displayColor``: primvars read by materials, per mesh.

A material is translated once, but a primvar it reads differs per mesh (constant on one,
per-vertex on another, missing on a third). So a reader becomes a *placeholder* in the material's
BSDF dict, and :func:`resolve` turns it into, for one mesh:

* a Mitsuba ``mesh_attribute`` texture named by
  :func:`~pavonine.render.primvars.mesh_attribute_name` (``vertex_<name>`` for
  vertex/varying/faceVarying primvars, ``face_<name>`` for uniform ones, ``:`` → ``_``; colour
  inputs read its colour twin ``…_color``), the attribute the mesh translator built for the
  primvars in :attr:`~.spec.MaterialSpec.primvars` (:func:`pavonine.render.mesh.build_triangle_mesh`);
* the primvar's value, when it is constant (inherited down namespace as USD says);
* the reader's ``fallback`` when the mesh has no such primvar, or it could not be built as an
  attribute (the geometry side warned why); an *optional* placeholder (the feather's primvar
  inputs, which fall back to its maps) is removed from the dict instead.

``UsdPrimvarReader_float2`` feeding a texture's ``st`` is not a placeholder: it names the mesh's
texture coordinates (:mod:`.textures`). ``_string`` and ``_matrix`` readers are warned about.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from pxr import Usd, UsdGeom, UsdShade

from pavonine.render.diagnostics import Diagnostics
from pavonine.render.primvars import COLOR_TWIN, INTERPOLATIONS, mesh_attribute_name
from pavonine.render.shading.network import COLOR, COMPONENTS, Affine, Network, as_mitsuba, coerce

PLACEHOLDER = "pavonine_primvar"  # the ``type`` of a placeholder node in a material's BSDF dict
READER_FALLBACKS = {"float": 0.0, "int": 0.0, "float2": (0.0, 0.0)}
UNSUPPORTED_READERS = ("string", "matrix")


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


def placeholder(
    name: str, kind: str, fallback: Any, affine: Affine, net: Network, *, optional: bool = False
) -> dict:
    """The placeholder node for primvar ``name`` read as ``kind`` (``optional``: the key holding
    it is dropped on a mesh without the primvar, rather than given ``fallback``)."""
    net.use_primvar(name)
    node = {
        "type": PLACEHOLDER,
        "primvar": name,
        "kind": kind,
        "fallback": np.atleast_1d(fallback).tolist(),
        "affine": (affine.a, affine.b),
    }
    if optional:
        node["optional"] = True
    return node


@dataclass(frozen=True)
class Binding:
    """How each primvar a material reads is found on one mesh (hashable: a BSDF cache key)."""

    entries: tuple[tuple[str, str, tuple[float, ...]], ...] = ()  # (name, interpolation, value)

    def lookup(self, name: str) -> tuple[str, tuple[float, ...]]:
        for entry_name, interpolation, value in self.entries:
            if entry_name == name:
                return interpolation, value
        return "missing", ()


def bind(
    names: Sequence[str],
    prim: Usd.Prim,
    time: Usd.TimeCode,
    attributes: Mapping[str, np.ndarray],
) -> Binding:
    """How each primvar in ``names`` is found on ``prim``: constant (its value), per element (the
    channel count of the mesh attribute built for it, in ``attributes``), or ``missing``.

    A non-constant primvar whose attribute was not built (too few values, not numeric, a shape
    without attributes) is ``missing``: the reader's fallback is used, and the geometry side
    warned why.
    """
    api = UsdGeom.PrimvarsAPI(prim)
    entries = []
    for name in names:
        primvar = api.FindPrimvarWithInheritance(name)
        interpolation = str(primvar.GetInterpolation()) if primvar else "missing"
        value: tuple[float, ...] = ()
        if not primvar or not primvar.HasValue() or interpolation not in INTERPOLATIONS:
            interpolation = "missing"
        elif interpolation == UsdGeom.Tokens.constant:
            value = _first_value(primvar.ComputeFlattened(time))
            if not value:
                interpolation = "missing"
        else:
            built = attributes.get(mesh_attribute_name(name, interpolation))
            if built is None:
                interpolation = "missing"
            else:
                value = (float(built.shape[1]),)  # a per-element primvar: its channel count
        entries.append((name, interpolation, value))
    return Binding(tuple(entries))


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
        resolved = {k: resolve(v, binding, where, diag) for k, v in tree.items()}
        return {k: v for k, v in resolved.items() if v is not None or tree[k] is None}
    return tree


def _resolve_one(node: dict, binding: Binding, where: str, diag: Diagnostics) -> Any:
    kind, (a, b) = node["kind"], node["affine"]
    interpolation, value = binding.lookup(node["primvar"])
    if interpolation == "missing":
        if node.get("optional"):
            return None
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
