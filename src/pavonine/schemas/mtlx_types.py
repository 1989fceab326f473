"""MaterialX types as USD types: the one table for every place that writes a MaterialX node's
inputs as UsdShade attributes (the asset's ``mtlx`` networks, the schema's feather shader, the
renderer's translation of ``.mtlx`` documents, the Sdr shader definitions).

Following usdMtlx (``UsdMtlxGetUsdType``): MaterialX ``float`` → ``float``, ``color3`` →
``color3f``, ``vector2`` → ``float2``, ``filename`` → ``asset``, ...
"""

from __future__ import annotations

from typing import Any

from pxr import Gf, Sdf

#: MaterialX type → USD value type of an input.
SDF_TYPES = {
    "float": Sdf.ValueTypeNames.Float,
    "integer": Sdf.ValueTypeNames.Int,
    "boolean": Sdf.ValueTypeNames.Bool,
    "string": Sdf.ValueTypeNames.String,
    "filename": Sdf.ValueTypeNames.Asset,
    "color3": Sdf.ValueTypeNames.Color3f,
    "color4": Sdf.ValueTypeNames.Color4f,
    "vector2": Sdf.ValueTypeNames.Float2,
    "vector3": Sdf.ValueTypeNames.Float3,
    "vector4": Sdf.ValueTypeNames.Float4,
}
#: MaterialX vector and colour types → their ``Gf`` value types.
GF_TYPES = {
    "color3": Gf.Vec3f,
    "vector3": Gf.Vec3f,
    "vector2": Gf.Vec2f,
    "color4": Gf.Vec4f,
    "vector4": Gf.Vec4f,
}


def usd_value(mtlx_type: str, value: Any) -> Any:
    """``value`` of a MaterialX input of ``mtlx_type`` as USD holds it (vectors and colours as
    their ``Gf`` types, the rest as it is)."""
    if mtlx_type in GF_TYPES:
        return GF_TYPES[mtlx_type](*[float(v) for v in value])
    return value


def mtlx_input_value(inp) -> Any:
    """The USD value of a MaterialX input ``inp`` (a ``filename`` as a relative
    ``Sdf.AssetPath``, vectors and colours as their ``Gf`` types, the rest as it is)."""
    value = inp.getValue()
    kind = inp.getType()
    if kind == "filename":
        path = str(value)
        return Sdf.AssetPath(path if path.startswith(("./", "../", "/")) else f"./{path}")
    return usd_value(kind, value)
