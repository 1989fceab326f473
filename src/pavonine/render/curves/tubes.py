"""``BasisCurves`` without ``normals`` → Mitsuba ``linearcurve`` / ``bsplinecurve`` (round tubes).

Mitsuba's B-spline curves are uniform cubic B-splines with a radius per control point: USD's
cubic bases are converted to them exactly (:mod:`.bases`), ``linear`` curves become
``linearcurve`` (``periodic`` closes the loop). ``widths`` are diameters (radius = width/2) with
constant, uniform, varying or vertex interpolation (default 1 scene unit, as Hydra); control
points are transformed to world space and radii scaled by the transform's mean scale.

Mitsuba's curves carry no attributes, so curves whose material reads a primvar that is not
constant on them (displayColor, displayOpacity, a ``UsdPrimvarReader`` varname, the feather's
inputs: :func:`reads_varying_primvars`) are tessellated instead (:func:`tube_surface`): rings of
:data:`SIDES` vertices around the samples of :mod:`.sampling`, framed by rotation-minimising
frames (double reflection: Wang, Jüttler, Zheng & Liu 2008, "Computation of rotation minimizing
frames", ACM TOG 27(1), Algorithm 1) so that the quads do not twist, with radial vertex normals
and the primvars carried to the vertices, as ribbons are. Their silhouette is within
1 − cos(π/SIDES) = 1.9 % of the round tube's.
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
from pavonine.render.curves.sampling import STEPS, sample_curves, strip_surface
from pavonine.render.diagnostics import Diagnostics
from pavonine.render.mesh import Surface
from pavonine.render.xform import transform_points

SIDES = 16  # vertices around a tessellated tube


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


def reads_varying_primvars(prim: Usd.Prim, read: Sequence[str]) -> bool:
    """Whether a primvar in ``read`` (those the bound material reads: ``MaterialSpec.primvars``)
    is authored on the curves and not constant: then they are tessellated (Mitsuba's curves
    carry no attributes)."""
    api = UsdGeom.PrimvarsAPI(prim)
    for name in read:
        primvar = api.GetPrimvar(name)
        if primvar and primvar.HasValue() and primvar.GetInterpolation() != "constant":
            return True
    return False


def tube_surface(
    prim: Usd.Prim, time: Usd.TimeCode, diag: Diagnostics, steps: int = STEPS, sides: int = SIDES
) -> Surface | None:
    """The curves as tubes of quads (object space) carrying their primvars; ``None`` (warned)
    when no curve can render."""
    topology = read_curves(prim, time, diag)
    samples = None if topology is None else sample_curves(prim, topology, time, diag, None, steps)
    if samples is None:
        return None
    tangents = samples.unit_tangents()
    across = _rotation_minimising(samples.values["P"], tangents, samples.lengths)
    around = np.cross(tangents, across)
    angle = 2 * np.pi * np.arange(sides) / sides
    radial = (
        np.cos(angle)[None, :, None] * across[:, None]
        + np.sin(angle)[None, :, None] * around[:, None]
    )  # (N, sides, 3): r × s = T̂, so k → k + 1 turns counter-clockwise about the curve
    half = samples.values["widths"][:, :1, None] / 2.0
    points = (samples.values["P"][:, None] + half * radial).reshape(-1, 3)
    k = np.arange(sides)
    a = samples.pairs[:, :1] * sides
    b = samples.pairs[:, 1:] * sides
    quads = np.stack([a + k, a + (k + 1) % sides, b + (k + 1) % sides, b + k], axis=2)
    return strip_surface(prim, samples, points, quads.reshape(-1, 4), radial.reshape(-1, 3), diag)


def _rotation_minimising(points: np.ndarray, tangents: np.ndarray, lengths: np.ndarray):
    """(N, 3) unit vectors across each curve, carried along it by double reflection (Wang et
    al. 2008, Algorithm 1), curves of one sample count at a time."""
    out = np.zeros_like(points)
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]])
    for length in np.unique(lengths):
        index = starts[lengths == length][:, None] + np.arange(length)  # (G, L)
        x, t = points[index], tangents[index]
        axis = np.eye(3)[np.argmin(np.abs(t[:, 0]), axis=1)]
        r = np.cross(t[:, 0], axis)
        r /= np.linalg.norm(r, axis=1, keepdims=True)
        frames = [r]
        for i in range(length - 1):
            v1 = x[:, i + 1] - x[:, i]
            r_l, t_l = _reflect(r, v1), _reflect(t[:, i], v1)
            r = _reflect(r_l, t[:, i + 1] - t_l)
            frames.append(r)
        out[index] = np.stack(frames, axis=1)
    return out


def _reflect(vectors: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """``vectors`` mirrored in the planes normal to ``normal`` (unchanged where it is ~0)."""
    c = np.sum(normal * normal, axis=1, keepdims=True)
    scale = np.where(c > 1e-24, 2.0 / np.where(c > 1e-24, c, 1.0), 0.0)
    return vectors - scale * np.sum(normal * vectors, axis=1, keepdims=True) * normal


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
