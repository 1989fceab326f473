"""``PavonineFeatherAPI`` materials → the spectral feather BSDF (:mod:`pavonine.render.feather_bsdf`).

The only place, with :func:`is_feather_material`, where shading knows about feathers. Parameters
and the six maps come from :mod:`pavonine.schemas.authoring`; each map is read through
:func:`pavonine.base.asset_io.local_file` (maps inside ``.usdz`` packages work), and a map that cannot
be read gets one warning and the map's neutral value. With ``PAVONINE_IGNORE_FEATHER_SCHEMA=1``
in the environment feather materials render their UsdPreviewSurface instead, as a viewer that
knows nothing of Pavonine would. The feather's uv and barb-tangent primvars are read under their
legacy names (``pavonine:featherUV``, ``pavonine:barbTangent``) on meshes that only carry those.

The four data inputs can also come as primvars (:data:`INPUT_PRIMVARS`; barbs carry them per
vertex): a prim that has one reads it instead of the map (optional placeholders feeding the
BSDF's ``<map>_primvar`` slots). On ribbons (:func:`on_ribbon`) the alpha mask and the
displacement are left out, the barbs' geometry being the silhouette and the relief (on curves
that author ``primvars:pavonine_barbules``, the BSDF is ``pavonine_barbules``:
:mod:`pavonine.render.barbules`, the ramus and barbules under each barb); the maps of
inputs a ribbon does not carry as primvars are read at its ``pavonine_featherUV``, and without
that the inputs take the schema's neutral values (warned).
"""

from __future__ import annotations

import os
from dataclasses import replace

import numpy as np
from pxr import Usd, UsdGeom, UsdShade

from pavonine.base.asset_io import AssetReadError, local_file
from pavonine.base.errors import InputError
from pavonine.materials.parameters import ParameterError
from pavonine.render.diagnostics import Diagnostics
from pavonine.render.shading.network import FLOAT, Affine, Network
from pavonine.render.shading.primvars import placeholder
from pavonine.render.shading.spec import MaterialSpec
from pavonine.schemas.authoring import parameter_input_error
from pavonine.schemas.plugin import SCHEMA_NAME
from pavonine.schemas.primvars import (
    BARB_TANGENT_PRIMVAR,
    FEATHER_UV_PRIMVAR,
    INPUT_PRIMVARS,
    LEGACY_PRIMVARS,
)

FEATHER_API = SCHEMA_NAME
FEATHER_UV = FEATHER_UV_PRIMVAR
BARB_TANGENT = BARB_TANGENT_PRIMVAR
#: Environment variable: ``1`` renders feather materials through their UsdPreviewSurface, as a
#: viewer that knows nothing of Pavonine would (used to compare the baked preview with the
#: spectral feather).
IGNORE_FEATHER_SCHEMA = "PAVONINE_IGNORE_FEATHER_SCHEMA"


def is_feather_material(material: UsdShade.Material) -> bool:
    """True when the material carries the ``PavonineFeatherAPI`` applied schema.

    Reads the composed ``apiSchemas`` (``GetPrimTypeInfo``) so that it works whether or not the
    schema's plugin is registered in this process (``GetAppliedSchemas`` drops unknown schemas).
    """
    return FEATHER_API in material.GetPrim().GetPrimTypeInfo().GetAppliedAPISchemas()


def renders_as_feather(material: UsdShade.Material) -> bool:
    """A feather material rendered spectrally (not with :data:`IGNORE_FEATHER_SCHEMA` set)."""
    return is_feather_material(material) and os.environ.get(IGNORE_FEATHER_SCHEMA) != "1"


def feather_material(material: UsdShade.Material, time, diag: Diagnostics) -> MaterialSpec:
    """The spectral feather BSDF of a ``PavonineFeatherAPI`` material."""
    from pavonine.render import feather_bsdf as plugin
    from pavonine.schemas import authoring

    path = str(material.GetPath())
    try:
        params = authoring.read_feather_parameters(material).validate()
    except ParameterError as exc:
        raise parameter_input_error(material.GetPrim(), exc) from None
    maps = dict(authoring.resolve_maps(material))
    for name, file in list(maps.items()):
        if not file:
            continue
        try:
            maps[name] = local_file(file)
        except (AssetReadError, OSError):
            diag.warn(path, f"{name} map {file!r} not found; using the map's neutral value")
            maps[name] = None
    _check_aspects(path, maps, diag)
    plugin.register()
    _check_spectral(path)
    unit_um = UsdGeom.GetStageMetersPerUnit(material.GetPrim().GetStage()) * 1.0e6
    bsdf = plugin.feather_bsdf_dict(params, maps, barb_tangents=True, world_unit_um=unit_um)
    net = Network(path, time, diag)
    core = _feather_node(bsdf)
    for name, primvar in INPUT_PRIMVARS.items():
        core[plugin.PRIMVAR_SLOTS[name]] = placeholder(
            primvar, FLOAT, [0.0], Affine(), net, optional=True
        )
    attributes = {BARB_TANGENT: plugin.BARB_TANGENT_ATTRIBUTE}
    return MaterialSpec(
        path,
        bsdf,
        FEATHER_UV,
        attributes,
        two_sided=True,
        is_feather=True,
        primvars=tuple(net.primvars),
        displacement=_displacement(material, maps.get("displacement"), diag),
    )


def _displacement(material: UsdShade.Material, file: str | None, diag: Diagnostics):
    """The displacement of a feather authored undisplaced (``pavonine:displacementHeight`` > 0):
    its map, read raw, times the height; the BSDF keeps its bump map, as on a baked mesh."""
    from pavonine.base.map_files import read_map
    from pavonine.render.displacement import Displacement
    from pavonine.schemas import authoring

    try:
        height = authoring.displacement_height(material)
    except ParameterError as exc:
        raise parameter_input_error(material.GetPrim(), exc) from None
    if height <= 0.0:
        return None
    path = str(material.GetPath())
    if not file:
        diag.warn(path, f"{authoring.DISPLACEMENT_HEIGHT_ATTR} is set without a displacement map")
        return None
    try:
        grey = read_map(file, authoring.MAP_ATTRS["displacement"])  # as convert reads it
    except InputError as exc:
        diag.warn(path, f"{exc}; the feather is rendered undisplaced")
        return None
    return Displacement(path, grey, np.eye(3), "clamp", height, keep_bump=True)


def on_ribbon(spec: MaterialSpec, prim: Usd.Prim, diag: Diagnostics) -> MaterialSpec:
    """A feather material as it shades ``prim``'s ribbons: the ``pavonine_feather`` node alone
    (no alpha mask, no displacement); without ``pavonine_featherUV`` on the prim its maps are
    dropped too, and each mapped input the prim lacks as a primvar is warned about."""
    from pavonine.render.feather_encoding import DATA_MAPS

    api = UsdGeom.PrimvarsAPI(prim)

    def carried(name: str) -> bool:
        primvar = api.FindPrimvarWithInheritance(name)
        return bool(primvar) and primvar.HasValue()

    from pavonine.render import barbules
    from pavonine.render.feather_encoding import BARB_COORDINATE_ATTRIBUTE
    from pavonine.render.mesh import BARB_COORDINATE, BARB_HALF_WIDTH

    core = dict(_feather_node(spec.bsdf), barb_coordinates=True)  # glitter follows the barbs
    attributes = {**spec.attributes, BARB_COORDINATE: BARB_COORDINATE_ATTRIBUTE}
    suffix = "ribbon"
    if barbules.carries_barbules(prim):  # the barbs' ramus and barbules (render.barbules)
        barbules.register()
        core["type"] = barbules.PLUGIN_NAME
        attributes[BARB_HALF_WIDTH] = barbules.HALF_WIDTH_ATTRIBUTE
        suffix = "barbules"
    spec = replace(spec, attributes=attributes)
    if carried(FEATHER_UV) or carried(LEGACY_PRIMVARS[FEATHER_UV]):
        return replace(spec, key=f"{spec.key}#{suffix}", bsdf=core, displacement=None)
    lacking = [
        INPUT_PRIMVARS[name]
        for name in DATA_MAPS
        if name in core and not carried(INPUT_PRIMVARS[name])
    ]
    if lacking:
        diag.warn(
            str(prim.GetPath()),
            f"feather material {spec.key}: the ribbons have no primvars:{FEATHER_UV} to place its "
            f"maps and no primvars:{', primvars:'.join(lacking)}; those inputs take their neutral "
            "values",
        )
    core = {k: v for k, v in core.items() if k not in DATA_MAPS}
    return replace(
        spec, key=f"{spec.key}#{suffix}-no-uv", bsdf=core, uv_primvar="st", displacement=None
    )


def _feather_node(bsdf: dict) -> dict:
    """The ``pavonine_feather`` node inside a feather material's wrappers (mask, bumpmap)."""
    from pavonine.render.feather_encoding import PLUGIN_NAME

    node = bsdf
    while node.get("type") != PLUGIN_NAME:
        node = node["bsdf"]
    return node


def _check_aspects(path: str, maps: dict[str, str | None], diag: Diagnostics) -> None:
    """Warn about each map whose width:height differs from the alpha map's (else the first
    map's): every map spans the feather's uv square, so such a map is stretched over it
    (``convert`` refuses it). Only headers are read."""
    from pavonine.base.limits import check_image, odd_aspects
    from pavonine.schemas.authoring import MAP_ATTRS

    sizes: dict[str, tuple[int, int]] = {}
    for name, file in maps.items():
        try:
            size = check_image(file) if file else (0, 0)
        except InputError:
            continue  # not an image, or beyond the pixel budget: the bitmap's load says so
        if min(size) > 0:
            sizes[name] = size
    ref, odd = odd_aspects(sizes)
    for name in odd:
        (w, h), (ref_w, ref_h) = sizes[name], sizes[ref]
        diag.warn(
            path,
            f"{MAP_ATTRS[name]} {maps[name]!r} is {w}x{h}, not the width:height of the "
            f"{ref} map's {ref_w}x{ref_h}; it is stretched over the feather",
        )


def _check_spectral(path: str) -> None:
    """The feather BSDF evaluates spectra: an RGB or monochrome Mitsuba variant cannot render it.

    Refused with one line naming ``--variant`` (rendering the feather as something else would be
    a different picture passed off as this one).
    """
    import mitsuba as mi

    variant = mi.variant() or ""
    if "spectral" not in variant:
        raise InputError(
            "--variant",
            f"{variant} is not a spectral variant, and the feather material {path} is rendered "
            "spectrally; use llvm_ad_spectral or scalar_spectral",
        )
