"""A material's displacement terminal → a :class:`~pavonine.render.displacement.Displacement`.

The terminal is looked up as the surface is: ``outputs:mitsuba:displacement``, the universal
``outputs:displacement``, then ``outputs:mtlx:displacement``. What it connects to:

=================================  ==============================================================
source                             displacement (object units, along the normal)
=================================  ==============================================================
``UsdPreviewSurface``              its ``displacement`` input (a texture, with UsdUVTexture's
                                   scale, bias, wrap and st; or a constant)
``ND_displacement_float``          ``displacement · scale`` (MaterialX ``displacementshader``)
a texture (``mitsuba`` context)    ``t − 0.5``: hdmitsuba's convention (``usd_mitsuba/mesh.py``
                                   displaces by the texture's value minus one half)
=================================  ==============================================================

A textured displacement also wraps the surface in a ``bumpmap`` of the same texture: what a
mesh renders with when it cannot be tessellated (:mod:`pavonine.render.displacement`'s
ceiling, no texture coordinates). Anything else (a vector displacement, an unknown node, a
primvar reader) is warned about by name and not applied. A UsdPreviewSurface whose
``displacement`` is set but which no displacement terminal reaches is warned about too (USD
displaces only through the material's terminal).
"""

from __future__ import annotations

from typing import Any

from pxr import UsdShade

from pavonine.render.displacement import Displacement, from_texture
from pavonine.render.shading.network import FLOAT, Affine, Network, shader_identifier
from pavonine.render.shading.preview_surface import PREVIEW_SURFACES

CONTEXTS = ("mitsuba", "", "mtlx")
MTLX_DISPLACEMENT = "ND_displacement_float"
#: hdmitsuba's ``mitsuba:displacement`` texture is centred on one half.
HDMITSUBA_OFFSET = -0.5


def terminal(material: UsdShade.Material) -> tuple[UsdShade.Shader, str, str] | None:
    """(shader, output name, render context) of the material's displacement terminal."""
    for context in CONTEXTS:
        output = material.GetDisplacementOutput(context)
        if not output or not output.HasConnectedSource():
            continue
        source = material.ComputeDisplacementSource(context)
        shader = source[0] if isinstance(source, tuple) else source
        if shader and shader.GetPrim().IsValid():
            return shader, str(source[1]) if isinstance(source, tuple) else "", context
    return None


def translate(
    material: UsdShade.Material, surface: UsdShade.Shader, bsdf: dict, net: Network
) -> tuple[dict, Displacement | None]:
    """(the surface BSDF, wrapped in its bump-map fallback when textured; the displacement)."""
    found = terminal(material)
    if found is None:
        if shader_identifier(surface) in PREVIEW_SURFACES and net.differs(
            surface, "displacement", 0.0
        ):
            net.warn(
                str(surface.GetPath()),
                "displacement is not applied: no displacement output of the material connects "
                "to this shader",
            )
        return bsdf, None
    shader, output, context = found
    value, scale, offset = _source(shader, output, context, net)
    if value is None:
        return bsdf, None
    where = str(shader.GetPath())
    try:
        displacement = from_texture(where, value, scale, offset)
    except ValueError as exc:
        net.warn(where, f"displacement is not applied: {exc} (got {_kind(value)})")
        return bsdf, None
    if displacement.texels is None:
        return bsdf, (displacement if displacement.offset != 0.0 else None)
    return {"type": "bumpmap", "height": value, "scale": scale, "bsdf": bsdf}, displacement


def _source(
    shader: UsdShade.Shader, output: str, context: str, net: Network
) -> tuple[Any, float, float]:
    """(value, scale, offset) of the shader feeding the terminal; value ``None`` (warned) when
    it cannot displace."""
    where = str(shader.GetPath())
    shader_id = shader_identifier(shader)
    if shader_id in PREVIEW_SURFACES:
        if not net.differs(shader, "displacement", 0.0):
            return None, 1.0, 0.0
        return net.value(shader, "displacement", FLOAT, 0.0), 1.0, 0.0
    if shader_id == MTLX_DISPLACEMENT:
        if net.source(shader.GetInput("scale")) is not None:
            net.warn(where, "a connected scale is not supported; using 1")
            scale = 1.0
        else:
            scale = float(net.setting(shader, "scale", 1.0))
        return net.value(shader, "displacement", FLOAT, 0.0), scale, 0.0
    if context == "mitsuba":
        value = net.upstream(shader, output, FLOAT, Affine(), f"{where}.outputs:{output}")
        return value, 1.0, HDMITSUBA_OFFSET
    net.warn(
        where,
        f"displacement shader {shader_id or '(no info:id)'!r} is not supported (only "
        f"UsdPreviewSurface and {MTLX_DISPLACEMENT}); the surface is rendered undisplaced",
    )
    return None, 1.0, 0.0


def _kind(value: Any) -> str:
    return value.get("type", "a texture") if isinstance(value, dict) else type(value).__name__
