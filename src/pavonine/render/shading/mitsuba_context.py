"""hdmitsuba's ``mitsuba`` render context: ``mitsuba_<plugin>`` shader nodes → Mitsuba dicts.

google/hdmitsuba registers every Mitsuba plugin it knows as an Sdr node ``mitsuba_<plugin>``
(``mitsuba_principled``, ``mitsuba_diffuse``, ``mitsuba_twosided``, ``mitsuba_bitmap``,
``mitsuba_normalmap``...) whose inputs are the plugin's own parameter names, and reads a material's
``outputs:mitsuba:surface`` before its universal ``outputs:surface``. Here, as there:

* each node becomes ``{"type": <plugin>, <input>: <value>...}``;
* an input connected to another ``mitsuba_*`` node nests that node's dict; connected to a
  ``UsdUVTexture`` or ``UsdPrimvarReader_*`` it takes that texture (:mod:`.network`);
* values convert by type: colours and 3-vectors → ``rgb``, float4 → ``rgb`` of its first three,
  matrices → transforms (USD's row-vector matrices transposed), assets → resolved local files
  (``mitsuba_bitmap``'s ``filename`` through ``Ar``, so ``.usdz`` members work; a file Mitsuba's
  own readers reject, such as a CMYK JPEG or a TIFF, is read with OpenImageIO instead).

Mitsuba itself checks the parameter names and types when the material is loaded; a node it rejects
makes the material grey with a warning naming Mitsuba's reason.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pxr import Gf, Sdf, UsdShade

from pavonine.base.asset_io import AssetReadError, local_file
from pavonine.base.errors import InputError
from pavonine.base.limits import check_image
from pavonine.render.shading.network import COLOR, FLOAT, VECTOR, Affine, Network, shader_identifier

PREFIX = "mitsuba_"
MISSING_TEXTURE_GREY = 0.5


def node(shader: UsdShade.Shader, net: Network) -> dict:
    """The Mitsuba dict of a ``mitsuba_<plugin>`` shader and everything connected to it."""
    plugin = shader_identifier(shader).removeprefix(PREFIX)
    where = str(shader.GetPath())
    out: dict[str, Any] = {"type": plugin}
    for shader_input in shader.GetInputs():
        name = shader_input.GetBaseName()
        source = net.source(shader_input)
        if source is not None:
            upstream = net.upstream(*source, _kind(shader_input), Affine(), f"{where}.{name}")
            if upstream is not None:
                out[name] = upstream
            continue
        value = net.constant(shader, name, None)
        if value is None:
            continue
        converted = _convert(value, shader_input.GetTypeName(), where, name, net)
        if converted is not None:
            out[name] = converted
    if plugin == "bitmap":
        bitmap = _bitmap(out.pop("filename", None), bool(out.get("raw", False)), where, net)
        if bitmap is None:
            net.warn(where, "mitsuba_bitmap has no readable filename; using grey")
            return {"type": "rgb", "value": [MISSING_TEXTURE_GREY] * 3}
        out["bitmap"] = bitmap
    return out


def _bitmap(path: str | None, raw: bool, where: str, net: Network) -> Any:
    """A ``mitsuba_bitmap``'s file as an ``mi.Bitmap``: read by Mitsuba as hdmitsuba would, or,
    for a file Mitsuba cannot read (a CMYK JPEG, a TIFF), by OpenImageIO (decoded to linear
    unless ``raw``, as Mitsuba decodes 8-bit files)."""
    import mitsuba as mi

    from pavonine.render.shading.textures import TextureError, read_texels

    if path is None:
        return None
    try:
        check_image(path)  # a regular file within the pixel budget, before Mitsuba decodes it
    except InputError as exc:
        net.warn(where, f"texture {exc}")
        return None
    try:
        return mi.Bitmap(path)
    except Exception:  # Mitsuba's readers: EXR, HDR, PFM, PPM, BMP, TGA, JPEG (RGB/grey), PNG
        pass
    try:
        rgba, _ = read_texels(path, "raw" if raw else "auto")
    except TextureError as exc:
        net.warn(where, f"{exc}")
        return None
    return mi.Bitmap(np.ascontiguousarray(rgba[..., :3], dtype=np.float32))


def _kind(shader_input: UsdShade.Input) -> str:
    type_name = shader_input.GetTypeName()
    if type_name.role == Sdf.ValueRoleNames.Color:
        return COLOR
    if type_name.scalarType in (Sdf.ValueTypeNames.Float, Sdf.ValueTypeNames.Double):
        return FLOAT
    return VECTOR if type_name.type.typeName.startswith("GfVec") else COLOR


def _convert(value: Any, type_name: Sdf.ValueTypeName, where: str, name: str, net: Network) -> Any:
    """A USD value as the Mitsuba property hdmitsuba would set from it."""
    if isinstance(value, Sdf.AssetPath):
        if not value.resolvedPath:
            net.warn(where, f"{name} {value.path!r} not found")
            return None
        try:
            return local_file(value.resolvedPath)
        except (AssetReadError, OSError) as exc:
            net.warn(where, f"{name} {value.path!r} cannot be read ({exc})")
            return None
    if isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, (Gf.Matrix4d, Gf.Matrix4f, Gf.Matrix3d, Gf.Matrix3f)):
        import mitsuba as mi

        matrix = np.array(value, dtype=np.float64).T  # USD row vectors → Mitsuba column vectors
        if matrix.shape == (4, 4):
            return mi.ScalarTransform4f(matrix.tolist())
        return mi.ScalarTransform3f(matrix.tolist())
    if hasattr(value, "__len__") and len(value) in (2, 3, 4):
        components = [float(c) for c in value]
        if len(components) == 2:
            net.warn(where, f"{name}: a 2-vector has no Mitsuba counterpart; ignored")
            return None
        return {"type": "rgb", "value": components[:3]}
    net.warn(where, f"{name}: a {type_name} value has no Mitsuba counterpart; ignored")
    return None
