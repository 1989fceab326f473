"""A ``UsdGeom.BasisCurves`` prim's topology, its cubic bases as uniform B-splines, and its data.

USD's cubic bases are converted exactly to uniform cubic B-splines (Mitsuba's ``bsplinecurve``,
and what :mod:`.ribbons` evaluates):

* ``bspline``: as authored; ``periodic`` repeats the first three points, ``pinned`` adds the
  phantom points 2P₀ − P₁ and 2Pₙ − Pₙ₋₁ so that the curve starts and ends on its end points.
* ``bezier`` (vstep 3): each segment B₀…B₃ becomes the B-spline P = M·B with
  M = [[6, −7, 2, 0], [0, 2, −1, 0], [0, −1, 2, 0], [0, 2, −7, 6]] (the inverse of the B-spline to
  Bézier basis change, Farin, "Curves and Surfaces for CAGD", §10).
* ``catmullRom`` (vstep 1): each segment P₋₁…P₂ becomes the Bézier P₀, P₀ + (P₁ − P₋₁)/6,
  P₁ − (P₂ − P₀)/6, P₁, then as above.
* ``linear``: polylines (``periodic`` closes the loop).

The conversion is linear, so it applies to any per-control-point data as well as to positions:
``vertex`` primvars follow the curve's basis (UsdGeomBasisCurves, "Primvar Interpolation").
``varying`` (and ``faceVarying``) data are linear across each segment, with the counts of
UsdGeomBasisCurves' varying table (:func:`varying_count`); ``uniform`` is one value per curve.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pxr import Usd, UsdGeom

from pavonine.render import attributes
from pavonine.render.diagnostics import Diagnostics
from pavonine.render.limits import MAX_COORDINATE, coordinates_ok

BEZIER_TO_BSPLINE = np.array([[6, -7, 2, 0], [0, 2, -1, 0], [0, -1, 2, 0], [0, 2, -7, 6]], float)
DEFAULT_WIDTH = 1.0  # scene units, as Hydra when widths are not authored


@dataclass
class CurveTopology:
    """A validated ``BasisCurves`` prim: its control points (object space) and how they join."""

    where: str
    points: np.ndarray  # (P, 3) float64
    counts: np.ndarray  # (C,) control points per curve
    kind: str  # cubic | linear
    basis: str  # bezier | bspline | catmullRom (ignored for linear)
    wrap: str  # nonperiodic | periodic | pinned

    @property
    def starts(self) -> np.ndarray:
        """(C,) the index of each curve's first control point."""
        return np.concatenate([[0], np.cumsum(self.counts)[:-1]]).astype(np.int64)

    def varying_counts(self) -> np.ndarray:
        """(C,) how many ``varying`` values each curve takes."""
        return varying_count(self.counts, self.kind, self.basis, self.wrap)


def read_curves(prim: Usd.Prim, time: Usd.TimeCode, diag: Diagnostics) -> CurveTopology | None:
    """The prim's points, counts, type, basis and wrap; ``None`` (warned) if nothing can render."""
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
    return CurveTopology(where, points, np.asarray(counts, dtype=np.int64), kind, basis, wrap)


def read_widths(
    prim: Usd.Prim, time: Usd.TimeCode, diag: Diagnostics
) -> tuple[np.ndarray, str] | None:
    """``(widths, interpolation)``: ``primvars:widths`` if authored, else ``widths``; negative,
    NaN or infinite widths read as 0 (warned). ``None`` when neither is authored."""
    curves = UsdGeom.BasisCurves(prim)
    primvar = UsdGeom.PrimvarsAPI(prim).GetPrimvar("widths")
    if primvar and primvar.HasAuthoredValue():
        values, interpolation = primvar.ComputeFlattened(time), str(primvar.GetInterpolation())
    elif curves.GetWidthsAttr().HasAuthoredValue():
        values = curves.GetWidthsAttr().Get(time)
        interpolation = str(curves.GetWidthsInterpolation())
    else:
        return None
    if values is None:
        return None
    widths = np.asarray(values, dtype=np.float64).ravel()
    if not np.all(np.isfinite(widths)) or np.any(widths < 0):
        diag.warn(str(prim.GetPath()), "widths are negative, NaN or infinite; those read as 0")
        widths = np.where(np.isfinite(widths) & (widths > 0), widths, 0.0)
    return widths, interpolation


def varying_count(count: np.ndarray, kind: str, basis: str, wrap: str) -> np.ndarray:
    """Per curve of ``count`` points: segments + 1 (nonperiodic, pinned) or segments (periodic),
    UsdGeomBasisCurves' varying table."""
    count = np.asarray(count, dtype=np.int64)
    if kind == "linear" or (wrap == "pinned" and basis != "bezier"):
        return count  # pinned: (count − 2) + 1 segments, + 1
    vstep = 3 if basis == "bezier" else 1
    if wrap == "periodic":
        return count // vstep
    return np.where(count >= 4, (count - 4) // vstep + 2, 1)


def needed_values(topology: CurveTopology, interpolation: str) -> int:
    """How many values data of ``interpolation`` must have on these curves."""
    return {
        "constant": 1,
        "uniform": len(topology.counts),
        "vertex": len(topology.points),
        "varying": int(topology.varying_counts().sum()),
        "faceVarying": int(topology.varying_counts().sum()),
    }[interpolation]


def bspline_runs(p: np.ndarray, kind: str, basis: str, wrap: str) -> np.ndarray | None:
    """Curves of n points (``p``: (..., n, k), position and any per-point data) as runs of joined
    uniform B-spline (cubic) or polyline (linear) control points: (..., R, L, k). ``None`` when
    the curves have too few points for their basis."""
    n = p.shape[-2]

    def join(*parts):
        return np.concatenate(parts, axis=-2)

    def phantoms(q):  # 2P₀ − P₁ and 2Pₙ − Pₙ₋₁: the curve starts and ends on its end points
        return join(2 * q[..., :1, :] - q[..., 1:2, :], q, 2 * q[..., -1:, :] - q[..., -2:-1, :])

    if kind == "linear":
        if n < 2:
            return None
        return (join(p, p[..., :1, :]) if wrap == "periodic" else p)[..., None, :, :]
    if basis == "bspline":
        if wrap == "periodic":
            p = join(p, p[..., :3, :])
        elif wrap == "pinned" and n >= 2:
            p = phantoms(p)
        return p[..., None, :, :] if p.shape[-2] >= 4 else None
    if basis == "catmullRom":
        if wrap == "periodic":
            p = join(p[..., -1:, :], p, p[..., :2, :])
        elif wrap == "pinned" and n >= 2:
            p = phantoms(p)
        if p.shape[-2] < 4:
            return None
        a, b, c, d = p[..., :-3, :], p[..., 1:-2, :], p[..., 2:-1, :], p[..., 3:, :]
        return BEZIER_TO_BSPLINE @ np.stack([b, b + (c - a) / 6, c - (d - b) / 6, c], axis=-2)
    # bezier, vstep 3
    if wrap == "periodic":
        p = join(p, p[..., :1, :])
    count = (p.shape[-2] - 1) // 3
    if count < 1:
        return None
    return BEZIER_TO_BSPLINE @ p[..., 3 * np.arange(count)[:, None] + np.arange(4), :]


def to_bspline(p: np.ndarray, kind: str, basis: str, wrap: str) -> list[np.ndarray] | None:
    """One USD curve (n × k) as its runs of B-spline (or polyline) control points, one array each
    (:func:`bspline_runs`)."""
    runs = bspline_runs(p, kind, basis, wrap)
    return None if runs is None else list(runs)


def segment_windows(p: np.ndarray, kind: str, basis: str, wrap: str) -> np.ndarray | None:
    """(..., S, 4, k) uniform B-spline control points of each segment of curves ``p``
    (..., n, k) (cubic), (..., S, 2, k) (linear), in the order of the curve; ``None`` when the
    curves have too few points for their basis."""
    runs = bspline_runs(p, kind, basis, wrap)
    if runs is None:
        return None
    order = 2 if kind == "linear" else 4
    windows = np.lib.stride_tricks.sliding_window_view(runs, order, axis=-2)  # (..., R, W, k, o)
    windows = np.swapaxes(windows, -1, -2)
    return windows.reshape(*runs.shape[:-3], -1, order, runs.shape[-1])


def basis_weights(u: np.ndarray, kind: str) -> tuple[np.ndarray, np.ndarray]:
    """Weights of a segment's control points at parameters ``u`` ∈ [0, 1] and their d/du.

    Cubic: the uniform B-spline basis (1−u)³/6, (3u³ − 6u² + 4)/6, (−3u³ + 3u² + 3u + 1)/6, u³/6
    (Farin, §10); linear: 1 − u, u. Returns two (len(u), order) arrays.
    """
    u = np.asarray(u, dtype=np.float64)
    if kind == "linear":
        ones = np.ones_like(u)
        return np.stack([1 - u, u], axis=1), np.stack([-ones, ones], axis=1)
    w = np.stack([(1 - u) ** 3, 3 * u**3 - 6 * u**2 + 4, -3 * u**3 + 3 * u**2 + 3 * u + 1, u**3], 1)
    dw = np.stack([-3 * (1 - u) ** 2, 9 * u**2 - 12 * u, -9 * u**2 + 6 * u + 3, 3 * u**2], 1)
    return w / 6.0, dw / 6.0
