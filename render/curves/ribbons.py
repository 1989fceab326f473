"""``BasisCurves`` with authored ``normals`` → flat ribbons, tessellated into a triangle mesh.

USD (UsdGeomBasisCurves, "Tubes and Ribbons"): curves with both widths and normals are imaged as
ribbons oriented in the direction of the interpolated normal vectors, the widths being the
ribbon's width. Each segment is evaluated exactly in its basis (:mod:`.bases`) at
:data:`STEPS` + 1 parameters (2 for ``linear``). At each sample: the point P, the tangent
T = dP/du, the normal N interpolated as authored (``vertex`` with the basis, ``varying`` linearly
per segment, ``uniform`` per curve, ``constant``) and made perpendicular to the curve,
N′ = normalize(N − (N·T̂)T̂), and the width w. The ribbon's edges are P ± (w/2)·S with
S = normalize(T̂ × N′), and each quad (P−, P+, next P+, next P−) faces N′ (S × T̂ = N′).

The result is a :class:`~pavonine.render.mesh.Surface` (quads) that the mesh translator turns
into a Mitsuba mesh like any other (:func:`pavonine.render.mesh.build_triangle_mesh`): vertex
normals N′; every numeric primvar carried to the samples (``vertex``/``varying``/``faceVarying``
as vertex data, ``uniform`` per quad, ``constant`` as authored), so every shader that reads a
primvar gets it (displayColor, displayOpacity, ``UsdPrimvarReader``, the feather's inputs); and
the barb tangent T̂ as ``pavonine_barbTangent`` (unless the prim authors one), the direction the
feather BSDF's barbule frame starts from. A ribbon has no inside: it is shaded on both sides.
"""

from __future__ import annotations

import functools

import numpy as np
from pxr import Usd, UsdGeom

from pavonine.render import attributes
from pavonine.render.curves.bases import (
    DEFAULT_WIDTH,
    CurveTopology,
    basis_weights,
    needed_values,
    read_curves,
    read_widths,
    segment_windows,
)
from pavonine.render.diagnostics import Diagnostics
from pavonine.render.mesh import Surface, make_topology
from pavonine.render.primvars import Primvar, read_primvar, read_primvars

STEPS = 4  # spans per cubic segment (a segment is exact at its ends; 4 spans: < 1 % of its sag)
BARB_TANGENT = "pavonine_barbTangent"  # the feather BSDF's barb direction (shading.feather)
_NORMALS, _WIDTHS = "normals", "widths"
_WHAT = {"uniform": "curves", "vertex": "points", "varying": "varying values"}


def has_normals(prim: Usd.Prim) -> bool:
    """True when the curves author ``normals`` (or ``primvars:normals``): USD's ribbons."""
    primvar = UsdGeom.PrimvarsAPI(prim).GetPrimvar(_NORMALS)
    if primvar and primvar.HasAuthoredValue():
        return True
    return UsdGeom.BasisCurves(prim).GetNormalsAttr().HasAuthoredValue()


def ribbon_surface(
    prim: Usd.Prim, time: Usd.TimeCode, diag: Diagnostics, steps: int = STEPS
) -> Surface | None:
    """The curves as ribbon quads (object space); ``None`` (warned) when they cannot be ribbons:
    no renderable curve, or normals that do not fit their interpolation (rendered as tubes)."""
    topology = read_curves(prim, time, diag)
    if topology is None:
        return None
    normals = _normals(prim, topology, time, diag)
    if normals is None:
        return None
    data = {_NORMALS: normals, _WIDTHS: _widths(prim, topology, time, diag)}
    for name, primvar in read_primvars(prim, time, diag).items():
        if name != _WIDTHS and _fits(primvar, topology, f"primvars:{name}", diag):
            data[name] = primvar
    samples = _sample(topology, data, steps)
    if samples is None:
        diag.warn(topology.where, "no curve has enough points for its basis; skipped")
        return None
    values, tangents, quads, quad_curve = samples
    normal, side, bad = _frame(tangents, values[_NORMALS])
    if bad.any():
        diag.warn(
            topology.where,
            f"{int(bad.sum())} of {len(bad)} ribbon samples have a zero normal, a normal along "
            "the curve, or no curve direction; the ribbon narrows to nothing there",
        )
    half = np.where(bad, 0.0, values[_WIDTHS][:, 0] / 2.0)[:, None]
    points = np.stack([values["P"] - side * half, values["P"] + side * half], 1).reshape(-1, 3)
    counts = np.full(len(quads), 4, dtype=np.int64)
    surface_topology = make_topology(points, counts, quads.ravel(), False, topology.where, diag)
    if surface_topology is None:
        return None
    primvars: dict[str, Primvar] = {}
    for name, primvar in data.items():
        if name in (_NORMALS, _WIDTHS):
            continue
        if primvar.interpolation == "constant":
            primvars[name] = primvar
        elif primvar.interpolation == "uniform":
            primvars[name] = Primvar(primvar.values[quad_curve], "uniform", primvar.role)
        else:
            primvars[name] = Primvar(np.repeat(values[name], 2, 0), "vertex", primvar.role)
    if BARB_TANGENT not in primvars:
        unit = tangents / np.maximum(np.linalg.norm(tangents, axis=1, keepdims=True), 1e-30)
        primvars[BARB_TANGENT] = Primvar(np.repeat(unit, 2, 0), "vertex", "Vector")
    return Surface(
        prim,
        surface_topology,
        normals=Primvar(np.repeat(normal, 2, 0), "vertex", "Normal"),
        primvars=primvars,
        double_sided=True,
    )


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
    if normals.values.shape[1] != 3 or not _fits(normals, topology, _NORMALS, diag, "tubes"):
        return None
    return normals


def _widths(
    prim: Usd.Prim, topology: CurveTopology, time: Usd.TimeCode, diag: Diagnostics
) -> Primvar:
    """The ribbon widths as a primvar of their interpolation (1 scene unit when absent or unfit)."""
    default = Primvar(np.array([[DEFAULT_WIDTH]]), "constant")
    read = read_widths(prim, time, diag)
    if read is None:
        return default
    widths = Primvar(read[0][:, None], read[1])
    return widths if _fits(widths, topology, _WIDTHS, diag, "width 1") else default


def _fits(
    primvar: Primvar,
    topology: CurveTopology,
    name: str,
    diag: Diagnostics,
    instead: str = "ignored",
) -> bool:
    """Whether ``primvar`` has enough values for its interpolation on these curves (else warned)."""
    interpolation = primvar.interpolation
    if interpolation not in ("constant", "uniform", "vertex", "varying", "faceVarying"):
        diag.warn(topology.where, f"{name} has unknown interpolation {interpolation!r}; {instead}")
        return False
    needed = needed_values(topology, interpolation)
    if len(primvar.values) >= needed:
        return True
    what = _WHAT.get(interpolation, "varying values")
    used = {"tubes": "rendered as round tubes", "width 1": "width 1 used"}.get(instead, instead)
    diag.warn(
        topology.where,
        f"{interpolation} {name} has {len(primvar.values)} values for {needed} {what}; {used}",
    )
    return False


def _sample(topology: CurveTopology, data: dict[str, Primvar], steps: int):
    """Every segment evaluated at its sample parameters, curves of one length at a time.

    Returns ``(values, tangents, quads, quad_curve)``: ``values`` maps ``"P"`` and each name of
    ``data`` to per-sample (N, k) arrays, ``tangents`` (N, 3) are dP/du, the quads (Q, 4) index
    the ribbon's vertices (2 per sample: the −S edge, then the +S edge), and ``quad_curve`` (Q,)
    is each quad's curve. ``None`` when no curve has enough points.
    """
    kind = topology.kind
    per_point = [n for n, pv in data.items() if pv.interpolation == "vertex"]
    columns = [topology.points] + [data[n].values[: len(topology.points)] for n in per_point]
    edges = np.cumsum([0] + [c.shape[1] for c in columns])
    stacked = np.concatenate(columns, axis=1)
    u = np.linspace(0.0, 1.0, steps + 1) if kind == "cubic" else np.array([0.0, 1.0])
    weights, derivative = basis_weights(u, kind)
    periodic = topology.wrap == "periodic"
    varying = topology.varying_counts()
    varying_start = np.concatenate([[0], np.cumsum(varying)[:-1]])
    out: dict[str, list[np.ndarray]] = {n: [] for n in ["P", *data]}
    tangents, quad_curve, quads = [], [], []
    sample_count = 0
    for count in np.unique(topology.counts):
        curves = np.nonzero(topology.counts == count)[0]
        index = topology.starts[curves][:, None] + np.arange(count)
        windows = segment_windows(stacked[index], kind, topology.basis, topology.wrap)
        if windows is None:
            continue
        g, s = len(curves), windows.shape[1]
        n = g * s * len(u)  # samples: curve-major, then segment, then u
        flat = functools.partial(_flat, n)

        at = np.einsum("uo,gsok->gsuk", weights, windows)
        tangents.append(flat(np.einsum("uo,gsok->gsuk", derivative, windows[..., :3])))
        out["P"].append(flat(at[..., :3]))
        for i, name in enumerate(per_point, start=1):
            out[name].append(flat(at[..., edges[i] : edges[i + 1]]))
        m = int(varying[curves[0]])
        first = np.minimum(np.arange(s), m - 1)
        second = (np.arange(s) + 1) % m if periodic else np.minimum(np.arange(s) + 1, m - 1)
        lerp = u[None, None, :, None]
        for name, primvar in data.items():
            if primvar.interpolation in ("varying", "faceVarying"):
                base = varying_start[curves][:, None]
                a = primvar.values[base + first][:, :, None]
                b = primvar.values[base + second][:, :, None]
                out[name].append(flat(a + (b - a) * lerp))
            elif primvar.interpolation in ("uniform", "constant"):
                rows = curves if primvar.interpolation == "uniform" else np.zeros(g, int)
                out[name].append(np.repeat(primvar.values[rows], s * len(u), axis=0))
        segment = sample_count + np.arange(g * s)[:, None] * len(u)
        base = (segment + np.arange(len(u) - 1)[None]).ravel()
        quads.append(np.stack([2 * base, 2 * base + 1, 2 * base + 3, 2 * base + 2], 1))
        quad_curve.append(np.repeat(curves, s * (len(u) - 1)))
        sample_count += n
    if not quads:
        return None
    values = {n: np.concatenate(v) for n, v in out.items() if v}
    return values, np.concatenate(tangents), np.concatenate(quads), np.concatenate(quad_curve)


def _flat(n: int, a: np.ndarray) -> np.ndarray:
    return a.reshape(n, -1)


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
