"""``UsdGeom.BasisCurves`` → Mitsuba: round tubes (:mod:`.tubes`) and flat ribbons (:mod:`.ribbons`).

As USD says (UsdGeomBasisCurves, "Tubes and Ribbons"): curves with authored ``normals`` are
ribbons facing their interpolated normals, tessellated into a triangle mesh that carries every
primvar; curves without are tubes of radius width/2 (Mitsuba's ``bsplinecurve`` /
``linearcurve``, which carry no primvars). Topology, bases and per-curve data: :mod:`.bases`.
"""

from __future__ import annotations

from pavonine.render.curves.ribbons import has_normals, ribbon_surface
from pavonine.render.curves.tubes import (
    bounds_of,
    curve_control_points,
    to_mitsuba_curves,
    warn_varying_primvars,
)

__all__ = [
    "bounds_of",
    "curve_control_points",
    "has_normals",
    "ribbon_surface",
    "to_mitsuba_curves",
    "warn_varying_primvars",
]
