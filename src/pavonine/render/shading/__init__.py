"""USD materials → Mitsuba BSDFs and emitters, one translator per module.

* :mod:`.network` follows connections through ``NodeGraph``\\ s to each source node;
* :mod:`.shader_ids` — which translator a shader goes to, by its ``info:id`` (one table each
  for surfaces and for the nodes feeding inputs);
* :mod:`.preview_surface` — ``UsdPreviewSurface`` (and MaterialX's ``ND_UsdPreviewSurface``);
* :mod:`.textures` — ``UsdUVTexture`` and ``UsdTransform2d``;
* :mod:`.primvars` — ``UsdPrimvarReader_*`` and ``displayColor``/``displayOpacity`` per mesh;
* :mod:`.mitsuba_context` — hdmitsuba's ``outputs:mitsuba:surface`` networks of ``mitsuba_*`` nodes;
* :mod:`.materialx` — MaterialX ``standard_surface`` / ``open_pbr_surface`` (approximated by
  ``principled``) and ``image`` / ``tiledimage`` nodes;
* :mod:`.feather` — ``PavonineFeatherAPI`` materials;
* :mod:`.displacement` — the displacement terminal (applied by :mod:`pavonine.render.displacement`);
* :mod:`.spec` — what a mesh receives (:class:`MaterialSpec`), sidedness, opacity and emission.

The surface is looked up in the render contexts ``mitsuba``, universal, then ``mtlx``; any other
shader is warned about (naming it) and rendered grey.
"""

from __future__ import annotations

from pxr import Usd, UsdShade

from pavonine.render.diagnostics import Diagnostics
from pavonine.render.shading import feather
from pavonine.render.shading.feather import (
    BARB_TANGENT,
    FEATHER_UV,
    IGNORE_FEATHER_SCHEMA,
    is_feather_material,
)
from pavonine.render.shading.network import Network, shader_identifier
from pavonine.render.shading.spec import (
    MaterialSpec,
    default_material,
    fallback_material,
    load_bsdf,
)

MITSUBA_CONTEXT = "mitsuba"

__all__ = [
    "BARB_TANGENT",
    "FEATHER_UV",
    "IGNORE_FEATHER_SCHEMA",
    "MaterialSpec",
    "default_material",
    "fallback_material",
    "is_feather_material",
    "load_bsdf",
    "translate_material",
]


def translate_material(
    material: UsdShade.Material, time: Usd.TimeCode, diag: Diagnostics
) -> MaterialSpec:
    """The :class:`MaterialSpec` of a bound USD material (feather, mitsuba, preview, or grey)."""
    from pavonine.render.shading import displacement as displacement_terminal
    from pavonine.render.shading.shader_ids import surface_translator

    path = str(material.GetPath())
    if feather.renders_as_feather(material):
        return feather.feather_material(material, time, diag)
    shader = surface_shader(material, diag)
    if shader is None:
        diag.warn(path, "material has no surface shader; rendering grey diffuse")
        return default_material()
    shader_id = shader_identifier(shader)
    net = Network(path, time, diag)
    translate = surface_translator(shader_id)
    if translate is None:
        diag.warn(
            path,
            f"surface shader {shader_id or '(no info:id)'!r} is not supported; rendering grey diffuse",
        )
        return default_material()
    fields = translate(shader, shader_id, net)
    fields["bsdf"], displacement = displacement_terminal.translate(
        material, shader, fields["bsdf"], net
    )
    if len(net.uv_names) > 1:
        diag.warn(
            path,
            f"textures read several uv sets ({', '.join(net.uv_names)}); Mitsuba meshes carry one, "
            f"so all read {net.uv_names[0]}",
        )
    uv = net.uv_names[0] if net.uv_names else "st"
    return MaterialSpec(
        path, uv_primvar=uv, primvars=tuple(net.primvars), displacement=displacement, **fields
    )


def surface_shader(material: UsdShade.Material, diag: Diagnostics) -> UsdShade.Shader | None:
    """The surface shader for this renderer: ``mitsuba`` context, universal, then ``mtlx``."""
    for context in (MITSUBA_CONTEXT, "mtlx"):  # ``mitsuba`` falls back to the universal output
        source = material.ComputeSurfaceSource(context)
        shader = source[0] if isinstance(source, tuple) else source
        if shader and shader.GetPrim().IsValid():
            return shader
    others = [o.GetBaseName() for o in material.GetSurfaceOutputs()]
    if others:
        diag.warn(
            str(material.GetPath()),
            f"only render contexts this renderer does not read ({', '.join(others)}) have a surface",
        )
    return None
