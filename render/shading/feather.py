"""``PavonineFeatherAPI`` materials → the spectral feather BSDF (:mod:`pavonine.render.feather_bsdf`).

The only place, with :func:`is_feather_material`, where shading knows about feathers. Parameters
and the six maps come from :mod:`pavonine.schemas.authoring`; each map is read through
:func:`pavonine.asset_io.local_file` (maps inside ``.usdz`` packages work), and a map that cannot
be read gets one warning and the map's neutral value.
"""

from __future__ import annotations

from pxr import UsdShade

from pavonine.asset_io import AssetReadError, local_file
from pavonine.render.diagnostics import Diagnostics
from pavonine.render.shading.spec import MaterialSpec

FEATHER_API = "PavonineFeatherAPI"
FEATHER_UV = "pavonine:featherUV"
BARB_TANGENT = "pavonine:barbTangent"


def is_feather_material(material: UsdShade.Material) -> bool:
    """True when the material carries the ``PavonineFeatherAPI`` applied schema.

    Reads the composed ``apiSchemas`` (``GetPrimTypeInfo``) so that it works whether or not the
    schema's plugin is registered in this process (``GetAppliedSchemas`` drops unknown schemas).
    """
    return FEATHER_API in material.GetPrim().GetPrimTypeInfo().GetAppliedAPISchemas()


def feather_material(material: UsdShade.Material, time, diag: Diagnostics) -> MaterialSpec:
    """The spectral feather BSDF of a ``PavonineFeatherAPI`` material."""
    from pavonine.render import feather_bsdf as plugin
    from pavonine.schemas import authoring

    path = str(material.GetPath())
    params = authoring.read_feather_parameters(material)
    maps = dict(authoring.resolve_maps(material))
    for name, file in list(maps.items()):
        if not file:
            continue
        try:
            maps[name] = local_file(file)
        except (AssetReadError, OSError):
            diag.warn(path, f"{name} map {file!r} not found; using the map's neutral value")
            maps[name] = None
    plugin.register()
    bsdf = plugin.feather_bsdf_dict(params, maps, barb_tangents=True)
    attributes = {BARB_TANGENT: plugin.BARB_TANGENT_ATTRIBUTE}
    return MaterialSpec(path, bsdf, FEATHER_UV, attributes, two_sided=True, is_feather=True)
