"""Which translator a USD prim goes to: the delegate's one dispatch point (hdMitsuba's prim-type
switch), read by the stage walk and the prototype walk alike so they support the same prims.

A prim's kind comes from its type name (:data:`KINDS`); any other prim with ``UsdLux.LightAPI``
applied is a light; anything else is ``unsupported`` and warned about by name, never dropped
silently.
"""

from __future__ import annotations

from pxr import Usd

from pavonine.render.lights import is_light
from pavonine.render.shapes import IMPLICIT

GPRIM = "gprim"  # Mesh and the implicit surfaces: tessellated, shaded (render/mesh.py, shapes.py)
CURVES = "curves"  # BasisCurves: tubes or ribbons (render/curves)
INSTANCER = "instancer"  # PointInstancer (render/instancing.py)
CAMERA = "camera"  # render/camera.py
LIGHT = "light"  # UsdLux (render/lights)
PRUNED = "pruned"  # shading networks and render settings: nothing to draw below them
STRUCTURAL = "structural"  # no geometry of its own; its children are visited
UNSUPPORTED = "unsupported"

#: Prims that carry no geometry of their own (their children are still visited).
STRUCTURAL_TYPES = (
    "",
    "Xform",
    "Scope",
    "SkelRoot",
    "GeomSubset",
    "RenderVar",
    "RenderPass",
    "Shader",
    "Backdrop",
    "Skeleton",  # UsdSkel: deforms the prims bound to it (render/skel.py)
    "SkelAnimation",
    "BlendShape",
)
#: Prims whose children are not geometry either (shading networks, render settings).
PRUNED_TYPES = ("Material", "NodeGraph", "RenderSettings", "RenderProduct")

#: Type name → kind.
KINDS: dict[str, str] = {
    "Mesh": GPRIM,
    **dict.fromkeys(IMPLICIT, GPRIM),
    "BasisCurves": CURVES,
    "PointInstancer": INSTANCER,
    "Camera": CAMERA,
    **dict.fromkeys(PRUNED_TYPES, PRUNED),
    **dict.fromkeys(STRUCTURAL_TYPES, STRUCTURAL),
}
#: Kinds placed in the world by their own transform (pruned when it is unusable).
GEOMETRIC = (GPRIM, CURVES, INSTANCER)


def prim_kind(prim: Usd.Prim) -> str:
    """The kind of translator ``prim`` goes to (module docstring)."""
    kind = KINDS.get(prim.GetTypeName())
    if kind in (GPRIM, CURVES, INSTANCER, CAMERA):
        return kind
    if is_light(prim):  # any prim with LightAPI, typed as a light or not (a mesh light is a gprim)
        return LIGHT
    return kind or UNSUPPORTED
