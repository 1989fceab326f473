"""``UsdGeom.BasisCurves`` → Mitsuba: round tubes (:mod:`.tubes`) and flat ribbons (:mod:`.ribbons`).

As USD says (UsdGeomBasisCurves, "Tubes and Ribbons"): curves with authored ``normals`` are
ribbons facing their interpolated normals, tessellated into a triangle mesh that carries every
primvar; curves without are tubes of radius width/2: Mitsuba's ``bsplinecurve`` /
``linearcurve``, or, when their material reads a primvar that varies on them (Mitsuba's curves
carry none), a tessellated tube mesh. Topology and bases: :mod:`.bases`; samples along the
curves: :mod:`.sampling`.
"""

from __future__ import annotations

from pavonine.render.curves.ribbons import has_normals, ribbon_surface
from pavonine.render.curves.tubes import (
    bounds_of,
    curve_control_points,
    reads_varying_primvars,
    to_mitsuba_curves,
    tube_surface,
)

__all__ = [
    "bounds_of",
    "curve_control_points",
    "has_normals",
    "reads_varying_primvars",
    "ribbon_surface",
    "to_mitsuba_curves",
    "tube_surface",
]
