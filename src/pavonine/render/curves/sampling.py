"""Curves sampled for tessellation: positions, tangents and every datum at a few points per segment.

Each segment is evaluated exactly in its basis (:mod:`.bases`) at :data:`STEPS` + 1 parameters
(2 for ``linear``), curves of one length at a time. Data follow their interpolation
(UsdGeomBasisCurves, "Primvar Interpolation"): ``vertex`` with the curve's basis, ``varying`` and
``faceVarying`` linearly per segment (the varying table's counts), ``uniform`` per curve,
``constant`` everywhere. :mod:`.ribbons` and :mod:`.tubes` build their meshes on the samples;
:func:`carried_primvars` hands the primvars on to the mesh's vertices and faces.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from pxr import Usd

from pavonine.render.curves.bases import (
    DEFAULT_WIDTH,
    CurveTopology,
    basis_weights,
    needed_values,
    read_widths,
    segment_windows,
)
from pavonine.render.diagnostics import Diagnostics
from pavonine.render.mesh import BARB_COORDINATE, Surface, make_topology
from pavonine.render.primvars import Primvar, read_primvars
from pavonine.schemas.primvars import BARB_ID_PRIMVAR, BARB_TANGENT_PRIMVAR

STEPS = 4  # spans per cubic segment
BARB_TANGENT = BARB_TANGENT_PRIMVAR  # the feather BSDF's barb direction (shading.feather)
BARB_ID = BARB_ID_PRIMVAR  # uniform: the barb's id (docs/render.md, "Ribbons")
WIDTHS = "widths"
INTERPOLATIONS = ("constant", "uniform", "vertex", "varying", "faceVarying")
_WHAT = {"uniform": "curves", "vertex": "points"}


@dataclass
class CurveSamples:
    """Samples along every renderable curve, curve after curve (each curve's contiguous)."""

    data: dict[str, Primvar]  # what was sampled, as authored (interpolation, role)
    values: dict[str, np.ndarray]  # "P" and each name of ``data`` → (N, k) per sample
    tangents: np.ndarray  # (N, 3) dP/du
    pairs: np.ndarray  # (Q, 2) consecutive samples of one segment: one strip piece each
    pair_curve: np.ndarray  # (Q,) the curve of each piece
    lengths: np.ndarray  # samples of each sampled curve, in order

    def unit_tangents(self) -> np.ndarray:
        length = np.linalg.norm(self.tangents, axis=1, keepdims=True)
        return self.tangents / np.maximum(length, 1e-30)


def sample_curves(
    prim: Usd.Prim,
    topology: CurveTopology,
    time: Usd.TimeCode,
    diag: Diagnostics,
    extra: dict[str, Primvar] | None = None,
    steps: int = STEPS,
) -> CurveSamples | None:
    """The curves' widths, ``extra`` data (already checked) and every numeric primvar that fits
    its interpolation (the others warned by name), sampled; ``None`` (warned) when no curve has
    enough points for its basis."""
    data = {**(extra or {}), WIDTHS: _widths(prim, topology, time, diag)}
    for name, primvar in read_primvars(prim, time, diag).items():
        if name != WIDTHS and fits(primvar, topology, f"primvars:{name}", diag):
            data[name] = primvar
    samples = _sample(topology, data, steps)
    if samples is None:
        diag.warn(topology.where, "no curve has enough points for its basis; skipped")
        return None
    # a cubic basis can overshoot below 0 where vertex widths taper (Catmull-Rom, Bézier)
    samples.values[WIDTHS] = np.maximum(samples.values[WIDTHS], 0.0)
    return samples


def fits(
    primvar: Primvar,
    topology: CurveTopology,
    name: str,
    diag: Diagnostics,
    instead: str = "ignored",
) -> bool:
    """Whether ``primvar`` has enough values for its interpolation on these curves (else warned,
    saying what is done ``instead``)."""
    interpolation = primvar.interpolation
    if interpolation not in INTERPOLATIONS:
        diag.warn(topology.where, f"{name} has unknown interpolation {interpolation!r}; {instead}")
        return False
    needed = needed_values(topology, interpolation)
    if len(primvar.values) >= needed:
        return True
    what = _WHAT.get(interpolation, "varying values")
    diag.warn(
        topology.where,
        f"{interpolation} {name} has {len(primvar.values)} values for {needed} {what}; {instead}",
    )
    return False


def barb_coordinates(samples: CurveSamples, across: np.ndarray) -> np.ndarray:
    """``(V, 3)`` per vertex: arc length from the curve's first sample (chords between samples),
    ``across`` (the vertex's place across the barb, counter-clockwise seen from its front) and
    the barb's id (``primvars:pavonine_barbId`` if authored, else the curve's index): where the
    feather BSDF finds a barb's barbules and blocks (:data:`BARB_COORDINATE`)."""
    points = samples.values["P"]
    step = np.concatenate([[0.0], np.linalg.norm(np.diff(points, axis=0), axis=1)])
    starts = np.concatenate([[0], np.cumsum(samples.lengths)[:-1]]).astype(int)
    step[starts] = 0.0
    arc = np.cumsum(step)
    arc -= np.repeat(arc[starts], samples.lengths)
    if BARB_ID in samples.values:
        barb = samples.values[BARB_ID][:, 0]
    else:
        barb = np.zeros(len(points))
        barb[samples.pairs.ravel()] = np.repeat(samples.pair_curve, 2)
    per_sample = len(across) // len(points)
    sampled = np.stack([arc, np.zeros_like(arc), np.rint(barb)], axis=1)
    out = np.repeat(sampled, per_sample, axis=0)
    out[:, 1] = across
    return out


def carried_primvars(
    samples: CurveSamples, per_sample: int, per_pair: int, across: np.ndarray | None = None
) -> dict[str, Primvar]:
    """The sampled primvars for a mesh with ``per_sample`` vertices per sample (in sample order)
    and ``per_pair`` faces per strip piece: vertex data per vertex, ``uniform`` per face,
    ``constant`` as authored; plus the unit tangent as :data:`BARB_TANGENT` unless authored, and
    the barb coordinate (:func:`barb_coordinates`; ``across`` per vertex, 0 when not given)."""
    out: dict[str, Primvar] = {}
    for name, primvar in samples.data.items():
        if name in (WIDTHS, "normals"):
            continue
        if primvar.interpolation == "constant":
            out[name] = primvar
        elif primvar.interpolation == "uniform":
            face_curve = np.repeat(samples.pair_curve, per_pair)
            out[name] = Primvar(primvar.values[face_curve], "uniform", primvar.role)
        else:
            values = np.repeat(samples.values[name], per_sample, axis=0)
            out[name] = Primvar(values, "vertex", primvar.role)
    if BARB_TANGENT not in out:
        tangents = np.repeat(samples.unit_tangents(), per_sample, axis=0)
        out[BARB_TANGENT] = Primvar(tangents, "vertex", "Vector")
    if across is None:
        across = np.zeros(len(samples.tangents) * per_sample)
    out[BARB_COORDINATE] = Primvar(barb_coordinates(samples, across), "vertex")
    return out


def strip_surface(
    prim: Usd.Prim,
    samples: CurveSamples,
    points: np.ndarray,
    quads: np.ndarray,
    normals: np.ndarray,
    diag: Diagnostics,
    across: np.ndarray | None = None,
) -> Surface | None:
    """The mesh built on ``samples``: ``points`` (the same number per sample, in sample order)
    joined by ``quads`` (the same number per strip piece, in piece order; each becomes two
    triangles, :func:`conditioned_triangles`), vertex ``normals``, the primvars carried
    (:func:`carried_primvars`, ``across`` per point); shaded on both sides (ribbons have no
    inside, tube meshes open ends)."""
    per_sample = len(points) // len(samples.tangents)
    triangles = conditioned_triangles(points, quads)
    per_pair = len(triangles) // len(samples.pairs)
    counts = np.full(len(triangles), 3, dtype=np.int64)
    topology = make_topology(points, counts, triangles.ravel(), False, str(prim.GetPath()), diag)
    if topology is None:
        return None
    return Surface(
        prim,
        topology,
        normals=Primvar(normals, "vertex", "Normal"),
        primvars=carried_primvars(samples, per_sample, per_pair, across),
        double_sided=True,
    )


def conditioned_triangles(points: np.ndarray, quads: np.ndarray) -> np.ndarray:
    """Each quad ``(a, b, c, d)`` as the triangles ``(a, b, c)`` and ``(a, c, d)``, each turned
    (its winding kept) to start at its widest corner.

    Mitsuba reads a mesh attribute at a hit from the hit point (``Mesh::barycentric_coordinates``:
    least squares on the edges ``e₁, e₂`` from the triangle's FIRST vertex, divided by
    ``|e₁|²|e₂|² − (e₁·e₂)²`` = ``|e₁|²|e₂|² sin²θ``, θ the angle there), in float32. Where a
    ribbon tapers (a barb's tip, a gap in the vane), a triangle is a needle: from its sharp corner
    the two long edges are nearly parallel and that determinant rounds to 0, so the attribute is
    NaN (the eye's barbs: 18 of 26,814 triangles; a NaN class made the feather BSDF gather 8 GiB
    past its table, SIGSEGV). From the widest corner (θ ≥ 60°) the determinant keeps its digits
    for every shape but a flat one (three points nearly on a line: next to no area to be hit)."""
    triangles = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]], axis=1).reshape(-1, 3)
    corners = points[triangles]
    after = np.roll(corners, -1, axis=1) - corners
    before = np.roll(corners, 1, axis=1) - corners
    lengths = np.linalg.norm(after, axis=2) * np.linalg.norm(before, axis=2)
    cosine = np.sum(after * before, axis=2) / np.maximum(lengths, 1e-300)
    first = np.argmin(np.where(lengths > 0.0, cosine, 2.0), axis=1)
    turn = (first[:, None] + np.arange(3)[None, :]) % 3
    return np.take_along_axis(triangles, turn, axis=1)


def _widths(
    prim: Usd.Prim, topology: CurveTopology, time: Usd.TimeCode, diag: Diagnostics
) -> Primvar:
    """The widths as a primvar of their interpolation (1 scene unit when absent or unfit)."""
    default = Primvar(np.array([[DEFAULT_WIDTH]]), "constant")
    read = read_widths(prim, time, diag)
    if read is None:
        return default
    widths = Primvar(read[0][:, None], read[1])
    return widths if fits(widths, topology, WIDTHS, diag, "width 1 used") else default


def _sample(topology: CurveTopology, data: dict[str, Primvar], steps: int) -> CurveSamples | None:
    """Every segment evaluated at its sample parameters, curves of one length at a time."""
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
    tangents, pair_curve, pairs, lengths = [], [], [], []
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
        start = (segment + np.arange(len(u) - 1)[None]).ravel()
        pairs.append(np.stack([start, start + 1], axis=1))
        pair_curve.append(np.repeat(curves, s * (len(u) - 1)))
        lengths.append(np.full(g, s * len(u)))
        sample_count += n
    if not pairs:
        return None
    return CurveSamples(
        data,
        {n: np.concatenate(v) for n, v in out.items() if v},
        np.concatenate(tangents),
        np.concatenate(pairs),
        np.concatenate(pair_curve),
        np.concatenate(lengths),
    )


def _flat(n: int, a: np.ndarray) -> np.ndarray:
    return a.reshape(n, -1)
