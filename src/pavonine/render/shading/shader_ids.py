"""Which translator a shader goes to, by its ``info:id``: the shading's dispatch tables, one for
surface shaders (a material's terminal) and one for the nodes that feed an input.

Each table is a list of ``(ids or prefixes, translator)``, tried in order; a shader that no row
takes is warned about by the caller, naming its ``info:id``. The translators live in their own
modules (:mod:`.preview_surface`, :mod:`.materialx`, :mod:`.mitsuba_context`, :mod:`.textures`,
:mod:`.primvars`); a new shader is one row here and one function there.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from pxr import UsdShade

from pavonine.render.shading import materialx, mitsuba_context, preview_surface, primvars, textures
from pavonine.render.shading.network import Affine, Network
from pavonine.render.shading.preview_surface import PREVIEW_SURFACES

#: A surface translator: ``(shader, info:id, network)`` → the material's fields (``bsdf``, ...).
Surface = Callable[[UsdShade.Shader, str, Network], dict]
#: A node translator: ``(shader, info:id, output, kind, affine, network)`` → its Mitsuba value.
Node = Callable[[UsdShade.Shader, str, str, str, Affine, Network], Any]


def _mitsuba_surface(shader, shader_id, net):
    return {"bsdf": mitsuba_context.node(shader, net)}


def _preview_surface(shader, shader_id, net):
    return preview_surface.preview_surface(shader, net)


def _uv_texture(shader, shader_id, output, kind, affine, net):
    return textures.uv_texture(shader, output, kind, affine, net)


def _mtlx_image(shader, shader_id, output, kind, affine, net):
    return materialx.image(shader, shader_id, kind, affine, net)


def _primvar_reader(shader, shader_id, output, kind, affine, net):
    return primvars.reader(shader, shader_id, kind, affine, net)


def _mitsuba_node(shader, shader_id, output, kind, affine, net):
    return mitsuba_context.node(shader, net)


#: Surface shaders: ``(ids, by prefix, translator)``.
SURFACES: list[tuple[tuple[str, ...], bool, Surface]] = [
    ((mitsuba_context.PREFIX,), True, _mitsuba_surface),
    (PREVIEW_SURFACES, False, _preview_surface),
    (tuple(materialx.SURFACES), False, materialx.surface),
]
#: Nodes feeding an input: ``(ids, by prefix, translator)``.
NODES: list[tuple[tuple[str, ...], bool, Node]] = [
    (("UsdUVTexture",), False, _uv_texture),
    (materialx.IMAGE_PREFIXES, True, _mtlx_image),
    (("UsdPrimvarReader_",), True, _primvar_reader),
]


def _find(table: list, shader_id: str):
    for ids, by_prefix, translator in table:
        if shader_id.startswith(ids) if by_prefix else shader_id in ids:
            return translator
    return None


def surface_translator(shader_id: str) -> Surface | None:
    """The translator of a surface shader with ``info:id`` ``shader_id`` (``None``: unsupported)."""
    return _find(SURFACES, shader_id)


def node_translator(shader_id: str, affine: Affine) -> Node | None:
    """The translator of a node with ``info:id`` ``shader_id`` feeding an input through
    ``affine`` (``None``: unsupported). A ``mitsuba_*`` node feeds an input as it is, never
    through a scale or offset."""
    found = _find(NODES, shader_id)
    if found is None and shader_id.startswith(mitsuba_context.PREFIX) and affine.identity:
        return _mitsuba_node
    return found
