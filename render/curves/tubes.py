"""``BasisCurves`` without ``normals`` → Mitsuba ``linearcurve`` / ``bsplinecurve`` (round tubes).

Mitsuba's B-spline curves are uniform cubic B-splines with a radius per control point: USD's
cubic bases are converted to them exactly (:mod:`.bases`), ``linear`` curves become
``linearcurve`` (``periodic`` closes the loop). ``widths`` are diameters (radius = width/2) with
constant, uniform, varying or vertex interpolation (default 1 scene unit, as Hydra); control
points are transformed to world space and radii scaled by the transform's mean scale. Mitsuba's
curves carry no primvars: a non-constant primvar the shading could read (displayColor,
displayOpacity, a ``UsdPrimvarReader`` varname in the bound material) is warned.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Sequence

import numpy as np
from pxr import Usd, UsdGeom

from pavonine.render.curves.bases import (
    DEFAULT_WIDTH,
    CurveTopology,
    read_curves,
    read_widths,
    to_bspline,
)
from pavonine.render.diagnostics import Diagnostics
from pavonine.render.xform import transform_points


def curve_control_points(
    prim: Usd.Prim, matrix_usd: np.ndarray, time: Usd.TimeCode, diag: Diagnostics
) -> tuple[str, list[np.ndarray]] | None:
    """``("linearcurve" | "bsplinecurve", [(n, 4) x y z radius per curve])`` in ``matrix_usd``'s space."""
    topology = read_curves(prim, time, diag)
    if topology is None:
        return None
    kind, basis, wrap = topology.kind, topology.basis, topology.wrap
    radii = _radii(prim, topology, time, diag)
    scale = abs(np.linalg.det(matrix_usd[:3, :3])) ** (1.0 / 3.0)
    world = transform_points(topology.points, matrix_usd)
    out: list[np.ndarray] = []
    for start, count in zip(topology.starts, topology.counts, strict=True):
        p = np.concatenate(
            [world[start : start + count], radii[start : start + count, None] * scale], 1
        )
        converted = to_bspline(p, kind, basis, wrap)
        if converted is not None:
            out.extend(converted)
    if not out:
        diag.warn(topology.where, "no curve has enough points for its basis; skipped")
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


def _radii(
    prim: Usd.Prim, topology: CurveTopology, time: Usd.TimeCode, diag: Diagnostics
) -> np.ndarray:
    """Radius per control point from ``widths`` of any interpolation (``varying`` resampled to
    the control points: Mitsuba's tubes take one radius per control point)."""
    counts = topology.counts
    n = int(counts.sum())
    read = read_widths(prim, time, diag)
    if read is None:
        return np.full(n, DEFAULT_WIDTH / 2.0)
    widths, interpolation = read
    curve_of_point = np.repeat(np.arange(len(counts)), counts)
    if interpolation == "constant" and len(widths) >= 1:
        return np.full(n, widths[0] / 2.0)
    if interpolation == "uniform" and len(widths) >= len(counts):
        return widths[curve_of_point] / 2.0
    if interpolation == "vertex" and len(widths) >= n:
        return widths[:n] / 2.0
    if interpolation in ("varying", "faceVarying"):
        per_curve = topology.varying_counts()
        if len(widths) >= per_curve.sum():
            out, start = [], 0
            for count, m in zip(counts, per_curve, strict=True):
                w = widths[start : start + m]
                out.append(np.interp(np.linspace(0, 1, count), np.linspace(0, 1, max(m, 1)), w))
                start += m
            return np.concatenate(out) / 2.0
    diag.warn(
        topology.where,
        f"widths: {len(widths)} values do not fit {interpolation} interpolation; width 1 used",
    )
    return np.full(n, DEFAULT_WIDTH / 2.0)


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
