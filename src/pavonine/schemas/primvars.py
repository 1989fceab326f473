"""The converter ↔ renderer contract on feather geometry: the primvars ``pavonine convert`` writes
and the renderer (and any host) reads, named once.

Names are valid identifiers: hosts paste MaterialX ``geompropvalue`` names into shader code.
docs/schema.md lists them with their units; docs/render.md, "Ribbons", says how the renderer
reads them.
"""

from __future__ import annotations

#: The feather coordinate (u across, v along the rachis, in ``[0, 1]``) where the six maps live;
#: meshes carry it as this primvar (their atlas ``st`` is for baking).
FEATHER_UV_PRIMVAR = "pavonine_featherUV"
#: The barb direction on the surface, per vertex (the angle map's zero).
BARB_TANGENT_PRIMVAR = "pavonine_barbTangent"
#: Names the converter gave these primvars before they had to be valid shading-language
#: identifiers; meshes that carry only these are read through them.
LEGACY_PRIMVARS = {
    FEATHER_UV_PRIMVAR: "pavonine:featherUV",
    BARB_TANGENT_PRIMVAR: "pavonine:barbTangent",
}

#: The data maps' primvar twins on barbs (BSDF input → vertex primvar; units: ocellar class
#: index, gradation t, structural share w, barbule angle in degrees).
INPUT_PRIMVARS = {
    "ocellar": "pavonine_ocellarClass",
    "gradation": "pavonine_gradation",
    "melanin": "pavonine_melanin",
    "angle": "pavonine_barbuleAngle",
}
#: Uniform per barb curve: the barb's id (seeds its blocks; the curve's index when unauthored).
BARB_ID_PRIMVAR = "pavonine_barbId"
#: Per vertex on barbs: the curves carry barbules (the renderer's ramus and barbule pattern),
#: reaching this share of the authored half width past the authored edge.
BARBULES_PRIMVAR = "pavonine_barbules"
