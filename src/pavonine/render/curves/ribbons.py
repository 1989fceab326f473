"""``BasisCurves`` with authored ``normals`` → flat ribbons, tessellated into a triangle mesh.

USD (UsdGeomBasisCurves, "Tubes and Ribbons"): curves with both widths and normals are imaged as
ribbons oriented in the direction of the interpolated normal vectors, the widths being the
ribbon's width. Each segment is evaluated exactly in its basis at a few parameters
(:mod:`.sampling`). At each sample: the point P, the tangent T = dP/du, the normal N interpolated as authored (``vertex`` with the basis, ``varying`` linearly
per segment, ``uniform`` per curve, ``constant``) and made perpendicular to the curve,
N′ = normalize(N − (N·T̂)T̂), and the width w. The ribbon's edges are P ± (w/2)·S with
S = normalize(T̂ × N′), and each quad (P−, P+, next P+, next P−) faces N′ (S × T̂ = N′).

The result is a :class:`~pavonine.render.mesh.Surface` (quads) that the mesh translator turns
into a Mitsuba mesh like any other (:func:`pavonine.render.mesh.build_triangle_mesh`): vertex
normals N′; every numeric primvar carried to the samples (``vertex``/``varying``/``faceVarying``
as vertex data, ``uniform`` per quad, ``constant`` as authored), so every shader that reads a
primvar gets it (displayColor, displayOpacity, ``UsdPrimvarReader``, the feather's inputs); and
the barb tangent T̂ as ``pavonine_barbTangent`` (unless the prim authors one), the direction the
feather BSDF's barbule frame starts from, and the barb coordinate (length along the barb, place
across it, barb id: ``pavonine_barbCoordinate``) its glitter blocks follow, with the ribbon's
half width as authored (``pavonine_barbHalfWidth``: where the barbule pattern finds its edge).
A feather's barbs (curves authoring ``primvars:pavonine_barbules``, the barbules' reach past
the authored edge as a share of the half width) are tessellated that much wider than authored:
where the vane is closed their barbules reach into the neighbouring barb's, as interlocking
barbules do, and
fill the seam between barbs; each is three vertices across (edge, ramus, edge), its edges
dropped :data:`~pavonine.materials.barbule_pattern.DROOP_DEG` below the ramus (the barbules
droop from it: overlapping barbules of neighbouring barbs are layers at different heights, not
one plane, which a ray passing a gap would start past). A ribbon has no inside: it is shaded on both sides.
"""

from __future__ import annotations

import math

import numpy as np
from pxr import Usd, UsdGeom

from pavonine.materials import barbule_pattern
from pavonine.render import attributes
from pavonine.render.curves.bases import CurveTopology, read_curves
from pavonine.render.curves.sampling import STEPS, fits, sample_curves, strip_surface
from pavonine.render.diagnostics import Diagnostics
from pavonine.render.mesh import BARB_HALF_WIDTH, Surface
from pavonine.render.primvars import Primvar, read_primvar
from pavonine.schemas.primvars import BARBULES_PRIMVAR

_NORMALS = "normals"


def has_normals(prim: Usd.Prim) -> bool:
    """True when the curves author ``normals`` (or ``primvars:normals``): USD's ribbons."""
    primvar = UsdGeom.PrimvarsAPI(prim).GetPrimvar(_NORMALS)
    if primvar and primvar.HasAuthoredValue():
        return True
    return UsdGeom.BasisCurves(prim).GetNormalsAttr().HasAuthoredValue()


def ribbon_surface(
    prim: Usd.Prim,
    time: Usd.TimeCode,
    diag: Diagnostics,
    steps: int = STEPS,
    barbules: bool = True,
) -> Surface | None:
    """The curves as ribbon quads (object space); ``None`` (warned) when they cannot be ribbons:
    no renderable curve, or normals that do not fit their interpolation (rendered as tubes).
    ``barbules=False``: a feather's barbs too as the plain flat ribbon of their authored width
    (USD's own ribbon: :func:`plain_ribbons`)."""
    topology = read_curves(prim, time, diag)
    if topology is None:
        return None
    normals = _normals(prim, topology, time, diag)
    if normals is None:
        return None
    samples = sample_curves(prim, topology, time, diag, {_NORMALS: normals}, steps)
    if samples is None:
        return None
    values = samples.values
    normal, side, bad = _frame(samples.tangents, values[_NORMALS])
    if bad.any():
        diag.warn(
            topology.where,
            f"{int(bad.sum())} of {len(bad)} ribbon samples have a zero normal, a normal along "
            "the curve, or no curve direction; the ribbon narrows to nothing there",
        )
    half = np.where(bad, 0.0, values["widths"][:, 0] / 2.0)[:, None]
    # A feather's barbs: ramus, drooping barbules (barbule_pattern).
    if barbules and _carries_barbules(prim):
        reach = values.get(BARBULES)
        reach = np.zeros_like(half) if reach is None else np.clip(reach[:, :1], 0.0, MAX_REACH)
        return _barb_surface(prim, samples, values["P"], normal, side, half, reach, diag)
    points = np.stack([values["P"] - side * half, values["P"] + side * half], 1).reshape(-1, 3)
    a, b = samples.pairs[:, 0], samples.pairs[:, 1]
    quads = np.stack([2 * a, 2 * a + 1, 2 * b + 1, 2 * b], axis=1)
    # across the barb counter-clockwise seen from N′ is −S: P − S·w/2 at +w/2
    across = (half * np.array([[1.0, -1.0]])).ravel()
    return strip_surface(prim, samples, points, quads, np.repeat(normal, 2, 0), diag, across)


def plain_ribbons(prim: Usd.Prim) -> Surface | None:
    """The plain ribbon surface of ``BasisCurves`` with authored ``normals`` at the default time:
    the authored width, no barbules, whatever the curves carry (USD's own ribbon, what the
    exports write for hosts without ribbons, handed to them by the application:
    :mod:`pavonine.pipeline.export.ribbons`); ``None`` for curves that are not ribbons or have
    no renderable curve."""
    if not has_normals(prim):
        return None
    return ribbon_surface(prim, Usd.TimeCode.Default(), Diagnostics(), barbules=False)


#: Barbs' ``primvars:pavonine_barbules``: their barbules' reach past the authored edge (share of
#: the half width), at most this.
BARBULES = BARBULES_PRIMVAR
MAX_REACH = 2.0


def _carries_barbules(prim: Usd.Prim) -> bool:
    from pavonine.render.barbules import carries_barbules

    return carries_barbules(prim)


def _barb_surface(prim, samples, centre, normal, side, half, reach, diag) -> Surface | None:
    """A feather's barb: three vertices across each sample (edge, ramus, edge), the ribbon
    ``1 + reach`` wider than authored (``primvars:pavonine_barbules``) and its edges dropped by
    ``tan(DROOP_DEG)`` of their distance from the ramus (the barbules droop from it); the
    authored half width as ``pavonine_barbHalfWidth``."""
    wide = half * (1.0 + reach)
    drop = math.tan(math.radians(barbule_pattern.DROOP_DEG)) * wide
    left = centre - side * wide - normal * drop
    right = centre + side * wide - normal * drop
    points = np.stack([left, centre, right], 1).reshape(-1, 3)
    a, b = samples.pairs[:, 0], samples.pairs[:, 1]
    quads = np.concatenate(
        [
            np.stack([3 * a, 3 * a + 1, 3 * b + 1, 3 * b], axis=1),
            np.stack([3 * a + 1, 3 * a + 2, 3 * b + 2, 3 * b + 1], axis=1),
        ],
        axis=1,
    ).reshape(-1, 4)
    across = (wide * np.array([[1.0, 0.0, -1.0]])).ravel()
    surface = strip_surface(prim, samples, points, quads, np.repeat(normal, 3, 0), diag, across)
    if surface is not None:
        surface.primvars[BARB_HALF_WIDTH] = Primvar(np.repeat(half, 3, axis=0), "vertex")
    return surface


def _normals(
    prim: Usd.Prim, topology: CurveTopology, time: Usd.TimeCode, diag: Diagnostics
) -> Primvar | None:
    """``primvars:normals`` if authored, else ``normals`` with its interpolation; ``None``
    (warned: the curves render as tubes) if they do not fit."""
    normals = read_primvar(prim, _NORMALS, time, diag)
    if normals is None:
        attr = UsdGeom.BasisCurves(prim).GetNormalsAttr()
        values = attributes.vec3_array(attr, time, diag)
        if values is None or len(values) == 0:
            diag.warn(topology.where, "normals are unusable; rendered as round tubes")
            return None
        interpolation = str(UsdGeom.BasisCurves(prim).GetNormalsInterpolation())
        normals = Primvar(values, interpolation, "Normal")
    tubes = "rendered as round tubes"
    if normals.values.shape[1] != 3 or not fits(normals, topology, _NORMALS, diag, tubes):
        return None
    if not np.all(np.isfinite(normals.values)):
        diag.warn(topology.where, "normals are NaN or infinite; those read as 0")
        normals.values = np.nan_to_num(normals.values, nan=0.0, posinf=0.0, neginf=0.0)
    return normals


def _frame(tangents: np.ndarray, normals: np.ndarray):
    """``(N′, S, bad)`` per sample: the normal made perpendicular to the tangent, the unit width
    direction T̂ × N′, and the samples where either is undefined."""
    length = np.linalg.norm(tangents, axis=1, keepdims=True)
    t = tangents / np.maximum(length, 1e-30)
    n = normals - np.sum(normals * t, axis=1, keepdims=True) * t
    n_length = np.linalg.norm(n, axis=1, keepdims=True)
    scale = np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-30)
    bad = (length[:, 0] <= 1e-12 * np.abs(tangents).max(initial=1.0)) | (
        n_length[:, 0] <= 1e-6 * scale[:, 0]
    )
    n = np.where(bad[:, None], np.array([0.0, 0.0, 1.0]), n / np.maximum(n_length, 1e-30))
    side = np.cross(t, n)
    side /= np.maximum(np.linalg.norm(side, axis=1, keepdims=True), 1e-30)
    return n, side, bad
