"""The ``pavonine_feather`` plugin's scene description: parameters ↔ properties, maps → textures.

:func:`encode_parameters` turns a :class:`~pavonine.materials.parameters.FeatherParameters` into
the plugin's scalar properties (class tables as comma-separated strings) and
:func:`decode_parameters` reads them back. :func:`feather_bsdf_dict` builds the ``mi.load_dict``
description of a feather material: its data maps as raw bilinear bitmaps (the ocellar map as its
smooth class field), the displacement map as a ``bumpmap`` wrapper and the alpha map as a ``mask``
wrapper. :func:`load_with_feathers` loads that nesting and keeps a handle on the feather nodes.
The BSDF itself (what the properties mean per shading point) is :mod:`pavonine.render.feather_bsdf`.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from pavonine.materials import glitter, ocellus
from pavonine.materials.dispersion import Dispersion
from pavonine.materials.parameters import STACK_QUANTITIES, FeatherParameters

PLUGIN_NAME = "pavonine_feather"
#: The feather BSDF and the plugins built on it (the barbs' ``pavonine_barbules``): the nodes
#: :func:`load_with_feathers` keeps a handle on.
FEATHER_PLUGINS = (PLUGIN_NAME, "pavonine_barbules")
DISPERSIONS = ("melanin", "keratin")
DATA_MAPS = ("ocellar", "gradation", "angle", "melanin")
PRIMVAR_SLOTS = {name: f"{name}_primvar" for name in DATA_MAPS}
#: Micrometres per scene unit unless told (Pavonine's assets: centimetres).
WORLD_UNIT_UM = 1.0e4
#: The mesh attribute of the barb direction (``barb_tangents`` set).
BARB_TANGENT_ATTRIBUTE = "vertex_barb_tangent"
#: Tessellated barbs' (length along, place across, barb id): ``barb_coordinates`` set.
BARB_COORDINATE_ATTRIBUTE = "vertex_barb_coordinate"
#: The wavelength (nm) whose lobe widths the BSDF's importance sampling uses.
SAMPLING_WAVELENGTH_NM = 550.0
#: Each data map's value where it is not bound (its neutral grey).
MAP_DEFAULTS = {"ocellar": 1.0, "gradation": 0.0, "angle": 0.0, "melanin": 1.0}
#: Per-instance frame table: world→instance 3×4 (row-major) then instance→world linear 3×3.
INSTANCE_FRAME = "instance_frame"
FRAME_FLOATS = 21


def encode_parameters(params: FeatherParameters) -> dict:
    """The plugin's scalar properties for a material (class tables as comma-separated strings)."""
    arrays = params.class_arrays()
    props: dict = {
        key: ",".join(repr(float(v)) for v in value.ravel()) for key, value in arrays.items()
    }
    props.update(
        {
            f"{name}_dispersion": ",".join(
                repr(float(v)) for v in vars(getattr(params, name)).values()
            )
            for name in DISPERSIONS
        }
    )
    props.update(
        lattice=params.lattice,
        n_classes=len(params.classes),
        melanin_index=params.melanin_index,
        medium_index=params.medium_index,
        crescent_sigma_deg=params.crescent_sigma_deg,
        block_sigma_deg=params.block_sigma_deg,
        rod_length_um=params.rod_length_um,
        interference=params.interference,
        melanin_color=",".join(repr(c) for c in params.melanin_color),
        glitter=params.glitter,
        glitter_seed=params.glitter_seed,
        block_length_um=params.block_length_um,
        barbule_width_um=params.barbule_width_um,
    )
    return props


def decode_parameters(props) -> FeatherParameters:
    """Inverse of :func:`encode_parameters` (from a ``mi.Properties`` or a dict)."""
    n = int(props["n_classes"])
    keys = [f"{axis}_{q}" for axis in ("long", "short") for q in STACK_QUANTITIES] + ["cortex"]
    arrays = {
        key: np.array([float(v) for v in str(props[key]).split(",")]).reshape(n, 2) for key in keys
    }
    dispersions = {
        name: Dispersion(*(float(v) for v in str(props[f"{name}_dispersion"]).split(",")))
        for name in DISPERSIONS
    }
    return FeatherParameters.from_class_arrays(
        arrays,
        lattice=str(props["lattice"]),
        **dispersions,
        melanin_index=float(props["melanin_index"]),
        medium_index=float(props["medium_index"]),
        crescent_sigma_deg=float(props["crescent_sigma_deg"]),
        block_sigma_deg=float(props["block_sigma_deg"]),
        rod_length_um=float(props["rod_length_um"]),
        interference=str(props["interference"]),
        melanin_color=tuple(float(c) for c in str(props["melanin_color"]).split(",")),
        glitter=float(props.get("glitter", 0.0)),
        glitter_seed=int(props.get("glitter_seed", 0)),
        block_length_um=float(props.get("block_length_um", glitter.BLOCK_LENGTH_UM)),
        barbule_width_um=float(props.get("barbule_width_um", glitter.BARBULE_WIDTH_UM)),
    )


def _bitmap(path: str) -> dict:
    return {
        "type": "bitmap",
        "filename": str(path),
        "raw": True,
        "filter_type": "bilinear",
        "wrap_mode": "clamp",
    }


def _class_bitmap(path: str) -> dict:
    """The ocellar map as its smooth class field (:func:`ocellus.smooth_class_field`)."""
    import mitsuba as mi

    from pavonine.base.map_files import read_map

    field = ocellus.smooth_class_field(read_map(path, "ocellar"))
    return {
        "type": "bitmap",
        "data": mi.TensorXf(field[..., None]),
        "raw": True,
        "filter_type": "bilinear",
        "wrap_mode": "clamp",
    }


def feather_bsdf_dict(
    params: FeatherParameters,
    maps: Mapping[str, str | None] | None = None,
    *,
    bump_scale: float = 0.002,
    barb_tangents: bool = False,
    world_unit_um: float = WORLD_UNIT_UM,
) -> dict:
    """A ``mi.load_dict`` description of the feather material with its maps (missing = uniform).

    ``barb_tangents``: read the barb direction from the mesh attribute ``vertex_barb_tangent``
    (every mesh using the material must carry it); otherwise the barb runs along ``dp/du``.
    ``world_unit_um``: micrometres per scene unit (the blocks of ``glitter`` are sized in µm).
    """
    maps = dict(maps or {})
    bsdf: dict = {"type": PLUGIN_NAME, **encode_parameters(params.validate())}
    bsdf["barb_tangents"] = barb_tangents
    bsdf["world_unit_um"] = float(world_unit_um)
    for name in DATA_MAPS:
        if maps.get(name):
            bsdf[name] = _class_bitmap(maps[name]) if name == "ocellar" else _bitmap(maps[name])
    if maps.get("displacement"):
        bsdf = {
            "type": "bumpmap",
            "arbitrary": _bitmap(maps["displacement"]),
            "scale": bump_scale,
            "bsdf": bsdf,
        }
    if maps.get("alpha"):
        bsdf = {"type": "mask", "opacity": _bitmap(maps["alpha"]), "bsdf": bsdf}
    return bsdf


def load_with_feathers(bsdf: dict) -> tuple[object, list]:
    """``mi.load_dict(bsdf)``, and the ``pavonine_feather`` objects inside its wrappers.

    The feather nodes are loaded first and nested as objects, so the caller keeps a handle on
    them (per-instance primvar tables are bound after the scene is built).
    """
    import mitsuba as mi

    feathers: list = []

    def load(node):
        if isinstance(node, dict) and node.get("type") in FEATHER_PLUGINS:
            feathers.append(mi.load_dict(node))
            return feathers[-1]
        if isinstance(node, dict):
            return {k: load(v) for k, v in node.items()}
        return node

    loaded = load(bsdf)
    return (loaded if not isinstance(loaded, dict) else mi.load_dict(loaded)), feathers
