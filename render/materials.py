"""USD materials → Mitsuba: the delegate's entry point into :mod:`pavonine.render.shading`.

Kept as a module of its own so that the delegate (and scripts) can keep importing
``pavonine.render.materials``; the translators live in the :mod:`~pavonine.render.shading`
subpackage, one per module.
"""

from __future__ import annotations

from pavonine.render.shading import (
    MaterialSpec,
    default_material,
    display_color,
    fallback_material,
    is_feather_material,
    load_bsdf,
    translate_material,
)
from pavonine.render.shading.feather import BARB_TANGENT, FEATHER_API, FEATHER_UV

__all__ = [
    "BARB_TANGENT",
    "FEATHER_API",
    "FEATHER_UV",
    "MaterialSpec",
    "default_material",
    "display_color",
    "fallback_material",
    "is_feather_material",
    "load_bsdf",
    "translate_material",
]
