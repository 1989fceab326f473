"""``UsdGeom.BasisCurves`` → Mitsuba ``linearcurve`` / ``bsplinecurve`` shapes (round tubes).

Mitsuba's B-spline curves are uniform cubic B-splines with a radius per control point; USD's
cubic bases are converted to them exactly:

* ``bspline``: as authored; ``periodic`` repeats the first three points, ``pinned`` adds the
  phantom points 2P₀ − P₁ and 2Pₙ − Pₙ₋₁ so that the curve starts and ends on its end points.
* ``bezier`` (vstep 3): each segment B₀…B₃ becomes the B-spline P = M·B with
  M = [[6, −7, 2, 0], [0, 2, −1, 0], [0, −1, 2, 0], [0, 2, −7, 6]] (the inverse of the B-spline to
  Bézier basis change, Farin, "Curves and Surfaces for CAGD", §10).
* ``catmullRom`` (vstep 1): each segment P₋₁…P₂ becomes the Bézier P₀, P₀ + (P₁ − P₋₁)/6,
  P₁ − (P₂ − P₀)/6, P₁, then as above.
* ``linear``: ``linearcurve`` (``periodic`` closes the loop).

``widths`` are diameters (radius = width/2) with constant, uniform, varying or vertex
interpolation (default 1 scene unit, as Hydra); control points are transformed to world space and
radii scaled by the transform's mean scale. Ribbons (authored ``normals``) render as tubes, and
Mitsuba's curves carry no primvars: a non-constant primvar the shading could read (displayColor,
displayOpacity, a ``UsdPrimvarReader`` varname in the bound material) is warned.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Sequence

import numpy as np
from pxr import Usd, UsdGeom

from pavonine.render import attributes
from pavonine.render.diagnostics import Diagnostics
from pavonine.render.limits import MAX_COORDINATE, coordinates_ok
from pavonine.render.xform import transform_points

BEZIER_TO_BSPLINE = np.array([[6, -7, 2, 0], [0, 2, -1, 0], [0, -1, 2, 0], [0, 2, -7, 6]], float)
DEFAULT_WIDTH = 1.0


def curve_control_points(
    prim: Usd.Prim, matrix_usd: np.ndarray, time: Usd.TimeCode, diag: Diagnostics
) -> tuple[str, list[np.ndarray]] | None:
    """``("linearcurve" | "bsplinecurve", [(n, 4) x y z radius per curve])`` in ``matrix_usd``'s space."""
    where = str(prim.GetPath())
    curves = UsdGeom.BasisCurves(prim)
    points = attributes.vec3_array(curves.GetPointsAttr(), time, diag)
    counts = attributes.int_array(curves.GetCurveVertexCountsAttr(), time, diag)
    if points is None or counts is None or len(points) == 0 or len(counts) == 0:
        diag.warn(where, "no points or curveVertexCounts; skipped")
        return None
    if np.any(counts < 0) or counts.sum() != len(points):
        diag.warn(
            where, f"curveVertexCounts sum to {counts.sum()} for {len(points)} points; skipped"
        )
        return None
    if not coordinates_ok(points):
        diag.warn(where, f"points are NaN, infinite or beyond ±{MAX_COORDINATE:g}; skipped")
        return None
    kind = attributes.token(prim, "type", time, diag, ("cubic", "linear"))
    basis = attributes.token(prim, "basis", time, diag, ("bezier", "bspline", "catmullRom"))
    wrap = attributes.token(prim, "wrap", time, diag, ("nonperiodic", "periodic", "pinned"))
    radii = _radii(curves, counts, kind, basis, wrap, time, diag)
    if curves.GetNormalsAttr().HasAuthoredValue():
        diag.warn(where, "normals (oriented ribbons) are not supported; rendered as round tubes")
    scale = abs(np.linalg.det(matrix_usd[:3, :3])) ** (1.0 / 3.0)
    world = transform_points(points, matrix_usd)
    out: list[np.ndarray] = []
    start = 0
    for count in counts:
        p = np.concatenate(
            [world[start : start + count], radii[start : start + count, None] * scale], 1
        )
        start += count
        converted = _to_bspline(p, kind, basis, wrap)
        if converted is not None:
            out.extend(converted)
    if not out:
        diag.warn(where, "no curve has enough points for its basis; skipped")
        return None
    return ("linearcurve" if kind == "linear" else "bsplinecurve"), out


def warn_varying_primvars(prim: Usd.Prim, read: Sequence[str], diag: Diagnostics) -> None:
    """Warn about each primvar in ``read`` (those the bound material reads: ``MaterialSpec.primvars``)
    that is not constant on the curves: Mitsuba curves carry no attributes, so the material's
    reader uses its fallback there."""
    api = UsdGeom.PrimvarsAPI(prim)
    for name in read:
        primvar = api.GetPrimvar(name)
        if primvar and primvar.HasValue() and primvar.GetInterpolation() != "constant":
            diag.warn(
                str(prim.GetPath()),
                f"{primvar.GetName()}: non-constant primvars on curves are not supported "
                "(Mitsuba curves carry none); the reader's fallback is used",
            )


def _radii(curves, counts, kind, basis, wrap, time, diag) -> np.ndarray:
    """Radius per control point from ``widths`` of any interpolation."""
    n = int(counts.sum())
    where = str(curves.GetPath())
    primvar = UsdGeom.PrimvarsAPI(curves).GetPrimvar("widths")
    values, interpolation = None, None
    if primvar and primvar.HasAuthoredValue():
        values, interpolation = primvar.ComputeFlattened(time), primvar.GetInterpolation()
    elif curves.GetWidthsAttr().HasAuthoredValue():
        values, interpolation = curves.GetWidthsAttr().Get(time), curves.GetWidthsInterpolation()
    if values is None:
        return np.full(n, DEFAULT_WIDTH / 2.0)
    widths = np.asarray(values, dtype=np.float64).ravel()
    if not np.all(np.isfinite(widths)) or np.any(widths < 0):
        diag.warn(where, "widths are negative, NaN or infinite; those read as 0")
        widths = np.where(np.isfinite(widths) & (widths > 0), widths, 0.0)
    curve_of_point = np.repeat(np.arange(len(counts)), counts)
    if interpolation == "constant" and len(widths) >= 1:
        return np.full(n, widths[0] / 2.0)
    if interpolation == "uniform" and len(widths) >= len(counts):
        return widths[curve_of_point] / 2.0
    if interpolation == "vertex" and len(widths) >= n:
        return widths[:n] / 2.0
    if interpolation == "varying":
        per_curve = [_varying_count(int(c), kind, basis, wrap) for c in counts]
        if len(widths) >= sum(per_curve):
            out, start = [], 0
            for count, m in zip(counts, per_curve, strict=True):
                w = widths[start : start + m]
                out.append(np.interp(np.linspace(0, 1, count), np.linspace(0, 1, max(m, 1)), w))
                start += m
            return np.concatenate(out) / 2.0
    diag.warn(
        where,
        f"widths: {len(widths)} values do not fit {interpolation} interpolation; width 1 used",
    )
    return np.full(n, DEFAULT_WIDTH / 2.0)


def _varying_count(count: int, kind: str, basis: str, wrap: str) -> int:
    """Segments + 1 (nonperiodic) or segments (periodic), as UsdGeomBasisCurves counts them."""
    if kind == "linear":
        return count
    vstep = 3 if basis == "bezier" else 1
    if wrap == "periodic":
        return count // vstep
    return (count - 4) // vstep + 2 if count >= 4 else 1


def _to_bspline(p: np.ndarray, kind: str, basis: str, wrap: str) -> list[np.ndarray] | None:
    """One USD curve (n × 4: position, radius) as Mitsuba curves' control points."""
    if kind == "linear":
        if len(p) < 2:
            return None
        return [np.vstack([p, p[:1]]) if wrap == "periodic" else p]
    if basis == "bspline":
        if wrap == "periodic":
            p = np.vstack([p, p[:3]])
        elif wrap == "pinned":
            p = np.vstack([2 * p[:1] - p[1:2], p, 2 * p[-1:] - p[-2:-1]])
        return [p] if len(p) >= 4 else None
    if basis == "catmullRom":
        if wrap == "periodic":
            p = np.vstack([p[-1:], p, p[:2]])
        elif wrap == "pinned":
            p = np.vstack([2 * p[:1] - p[1:2], p, 2 * p[-1:] - p[-2:-1]])
        if len(p) < 4:
            return None
        segments = []
        for i in range(1, len(p) - 2):
            a, b, c, d = p[i - 1], p[i], p[i + 1], p[i + 2]
            segments.append(BEZIER_TO_BSPLINE @ np.stack([b, b + (c - a) / 6, c - (d - b) / 6, c]))
        return segments
    # bezier, vstep 3
    if wrap == "periodic":
        p = np.vstack([p, p[:1]])
    count = (len(p) - 1) // 3
    if count < 1:
        return None
    return [BEZIER_TO_BSPLINE @ p[3 * i : 3 * i + 4] for i in range(count)]


def to_mitsuba_curves(kind: str, curves: list[np.ndarray], bsdf) -> object:
    """A Mitsuba curve shape from control points (written to a temporary file, which it reads)."""
    import mitsuba as mi

    fd, path = tempfile.mkstemp(suffix=".txt", prefix="pavonine_curves_")
    try:
        with os.fdopen(fd, "w") as handle:
            for curve in curves:
                radius = np.maximum(curve[:, 3], 1e-6)
                for (x, y, z), r in zip(curve[:, :3], radius, strict=True):
                    handle.write(f"{x:.9g} {y:.9g} {z:.9g} {r:.9g}\n")
                handle.write("\n")
        return mi.load_dict({"type": kind, "filename": path, "bsdf": bsdf})
    finally:
        os.unlink(path)


def bounds_of(curves: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned bounds of the tubes (control points ± radius: B-splines stay in their hull)."""
    allp = np.vstack(curves)
    r = allp[:, 3:4]
    return (allp[:, :3] - r).min(axis=0), (allp[:, :3] + r).max(axis=0)
