"""``subdivisionScheme`` → a refined :class:`~pavonine.render.mesh.Surface`.

Catmull-Clark (Catmull & Clark 1978) and Loop (Loop 1987) refinement with the sharpness rules
of DeRose, Kass & Truong, "Subdivision surfaces in character animation" (SIGGRAPH 1998), which
OpenSubdiv implements and USD specifies: each level is a sparse linear map from the coarse
points to the refined points, so every ``vertex`` primvar is refined with the same map as the
points, ``varying`` primvars bilinearly, ``faceVarying`` primvars bilinearly within each face
(OpenSubdiv's ``faceVaryingLinearInterpolation = all``; USD's default ``cornersPlus1`` also
smooths them across faces: a documented approximation), ``uniform`` primvars per authored face.

* ``interpolateBoundary``: ``edgeAndCorner`` (USD's fallback: boundary edges are infinitely sharp,
  boundary vertices of one face are corners), ``edgeOnly``, ``none`` (treated as ``edgeOnly``, warned).
* ``creaseIndices/creaseLengths/creaseSharpnesses`` and ``cornerIndices/cornerSharpnesses``:
  semi-sharp creases and corners (sharpness decreases by 1 per level; a fractional sharpness
  blends the smooth and sharp rules).
* ``holeIndices``: those faces (and their refined children) are not rendered.
* ``bilinear``: linear refinement (no smoothing); ``none``: the polygons as authored.
* Loop on polygons that are not triangles: fan-triangulated first (warned).

Refinement stops after :data:`MAX_LEVELS` levels (or the mesh's ``mitsuba:subdivision_level``,
hdmitsuba's per-mesh setting; 0: the control mesh) or before the refined mesh exceeds
:data:`FACE_BUDGET` faces; a mesh already above the budget is rendered as its control mesh with
smooth normals, with a warning. pymeshlab's Catmull-Clark and Loop filters are not used: they
ignore boundary rules (a unit quad shrinks to [0.24, 0.76]², where USD keeps it whole) and creases;
the tests check this implementation against pymeshlab on closed meshes, where the rules agree.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from pxr import Usd, UsdGeom
from scipy import sparse

from pavonine.render import attributes
from pavonine.render.diagnostics import Diagnostics
from pavonine.render.integrator_settings import SUBDIVISION_LEVEL
from pavonine.render.mesh import Surface, make_topology, smooth_normals
from pavonine.render.primvars import Primvar

MAX_LEVELS = 3
FACE_BUDGET = 250_000
INFINITE = math.inf


@dataclass
class Cage:
    """One level's polygons with their edges, sharpness and per-face bookkeeping."""

    counts: np.ndarray  # (F,)
    indices: np.ndarray  # (C,)
    n_points: int
    edge_sharpness: dict[tuple[int, int], float]  # only edges with sharpness > 0
    vertex_sharpness: np.ndarray  # (n_points,)
    parent_face: np.ndarray  # (F,) authored face of each face
    hole: np.ndarray  # (F,) bool


def refine_surface(surface: Surface, time: Usd.TimeCode, diag: Diagnostics) -> Surface:
    """Apply the surface's ``subdivisionScheme`` (and ``holeIndices``); other surfaces unchanged."""
    if surface.scheme == "none":
        return _drop_holes(surface, _holes(surface, time, diag))
    prim, where = surface.prim, surface.where
    surface = _renderable_faces(surface)
    topology = surface.topology
    cage = _cage(surface, time, diag)
    scheme = surface.scheme
    if scheme == "loop" and np.any(topology.face_vertex_counts != 3):
        diag.warn(where, "loop subdivision needs triangles; polygons fan-triangulated first")
        cage, corner_map = _triangulated(cage)
        surface = _faces_to_triangles(surface, corner_map)
    growth = 3 if scheme == "loop" else 4
    asked = _asked_levels(prim, time, diag)
    most = MAX_LEVELS if asked is None else asked
    levels = 0
    while levels < most and len(cage.counts) * growth ** (levels + 1) <= FACE_BUDGET:
        levels += 1
    if asked is not None and levels < asked:
        diag.warn(
            where,
            f"{SUBDIVISION_LEVEL} = {asked} refined to {levels} levels: the budget is "
            f"{FACE_BUDGET} refined faces",
        )
    if asked == 0:
        refined = replace(surface, normals=smooth_normals(topology), scheme="none")
        return _drop_holes(refined, cage.hole)
    if levels == 0:
        diag.warn(
            where,
            f"{scheme} mesh with {len(cage.counts)} faces is above the subdivision budget "
            f"({FACE_BUDGET} refined faces); rendered as its control mesh with smooth normals",
        )
        refined = replace(surface, normals=smooth_normals(topology), scheme="none")
        return _drop_holes(refined, cage.hole)
    if UsdGeom.Mesh(prim).GetTriangleSubdivisionRuleAttr().Get(time) == "smooth":
        diag.warn(
            where, "triangleSubdivisionRule 'smooth' is not supported; catmullClark rule used"
        )
    points = topology.points
    primvars = dict(surface.primvars)
    for _ in range(levels):
        step = _LEVEL[scheme](cage)
        points = step.points @ points
        primvars = {name: _refine_primvar(pv, step) for name, pv in primvars.items()}
        cage = step.child
    refined_topology = make_topology(
        points, cage.counts, cage.indices, topology.left_handed, where, diag
    )
    if refined_topology is None:
        return surface
    return _drop_holes(
        Surface(
            prim,
            refined_topology,
            normals=smooth_normals(refined_topology),
            primvars=primvars,
            double_sided=surface.double_sided,
            scheme="none",
            authored_face=cage.parent_face,
        ),
        cage.hole,
    )


def _asked_levels(prim: Usd.Prim, time: Usd.TimeCode, diag: Diagnostics) -> int | None:
    """hdmitsuba's ``mitsuba:subdivision_level`` of a mesh: the levels to refine (0: the control
    mesh with smooth normals); ``None`` when unauthored or unusable (warned)."""
    attr = prim.GetAttribute(SUBDIVISION_LEVEL)
    value = attr.Get(time) if attr else None
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 16:
        diag.warn(
            str(prim.GetPath()),
            f"{SUBDIVISION_LEVEL} = {value!r} is not an integer from 0 to 16; refined as usual",
        )
        return None
    return int(value)


@dataclass
class Step:
    """One refinement level: the linear maps from coarse to refined data, and the refined cage."""

    points: sparse.csr_matrix  # smooth (the scheme's) map of point data
    linear: sparse.csr_matrix  # bilinear map of point data (``varying`` primvars)
    corners: sparse.csr_matrix  # refined corners from coarse corners (``faceVarying``)
    face_parent: np.ndarray  # refined face → coarse face (``uniform``)
    child: Cage


def _refine_primvar(primvar: Primvar, step: Step) -> Primvar:
    values = primvar.values
    if primvar.interpolation == "vertex" and len(values) >= step.points.shape[1]:
        values = step.points @ values[: step.points.shape[1]]
    elif primvar.interpolation == "varying" and len(values) >= step.linear.shape[1]:
        values = step.linear @ values[: step.linear.shape[1]]
    elif primvar.interpolation == "faceVarying" and len(values) >= step.corners.shape[1]:
        values = step.corners @ values[: step.corners.shape[1]]
    elif primvar.interpolation == "uniform" and len(values) > step.face_parent.max():
        values = values[step.face_parent]
    return Primvar(np.asarray(values), primvar.interpolation, primvar.role)


# -- the cage: edges, sharpness -------------------------------------------------------------------


def _edges(counts: np.ndarray, indices: np.ndarray):
    """Per corner: its face, next and previous corner, and the id of the edge to the next corner."""
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    face = np.repeat(np.arange(len(counts)), counts)
    local = np.arange(len(indices)) - starts[face]
    nxt = starts[face] + (local + 1) % counts[face]
    prv = starts[face] + (local - 1) % counts[face]
    a, b = indices, indices[nxt]
    keys = np.stack([np.minimum(a, b), np.maximum(a, b)], axis=1)
    unique, edge_of_corner = np.unique(keys, axis=0, return_inverse=True)
    return face, nxt, prv, unique, edge_of_corner.ravel()


def _cage(surface: Surface, time: Usd.TimeCode, diag: Diagnostics) -> Cage:
    topology, prim, where = surface.topology, surface.prim, surface.where
    mesh = UsdGeom.Mesh(prim)
    n = len(topology.points)
    sharp: dict[tuple[int, int], float] = {}
    crease_indices = attributes.int_array(mesh.GetCreaseIndicesAttr(), time, diag)
    crease_lengths = attributes.int_array(mesh.GetCreaseLengthsAttr(), time, diag)
    crease_sharpness = attributes.float_array(mesh.GetCreaseSharpnessesAttr(), time, diag)
    if crease_indices is not None and crease_lengths is not None and crease_sharpness is not None:
        if crease_lengths.sum() != len(crease_indices) or len(crease_sharpness) not in (
            len(crease_lengths),
            int(np.maximum(crease_lengths - 1, 0).sum()),
        ):
            diag.warn(
                where, "creaseIndices/creaseLengths/creaseSharpnesses disagree; creases ignored"
            )
        else:
            per_edge = len(crease_sharpness) != len(crease_lengths)
            start, k = 0, 0
            for c, length in enumerate(crease_lengths):
                chain = crease_indices[start : start + length]
                for i in range(length - 1):
                    s = crease_sharpness[k if per_edge else c]
                    k += 1
                    a, b = int(chain[i]), int(chain[i + 1])
                    if s > 0 and 0 <= a < n and 0 <= b < n:
                        sharp[(min(a, b), max(a, b))] = INFINITE if s >= 10 else float(s)
                start += length
    vertex_sharpness = np.zeros(n)
    corners = attributes.int_array(mesh.GetCornerIndicesAttr(), time, diag)
    corner_sharpness = attributes.float_array(mesh.GetCornerSharpnessesAttr(), time, diag)
    if corners is not None and corner_sharpness is not None:
        if len(corners) != len(corner_sharpness) or np.any((corners < 0) | (corners >= n)):
            diag.warn(
                where, "cornerIndices/cornerSharpnesses disagree or are out of range; ignored"
            )
        else:
            vertex_sharpness[corners] = np.where(corner_sharpness >= 10, INFINITE, corner_sharpness)
    boundary = attributes.token(
        prim, "interpolateBoundary", time, diag, ("edgeAndCorner", "edgeOnly", "none")
    )
    if boundary == "none":
        diag.warn(where, "interpolateBoundary 'none' is not supported; edgeOnly used")
    counts = topology.face_vertex_counts
    indices = topology.face_vertex_indices
    _face, _nxt, _prv, edges, edge_of_corner = _edges(counts, indices)
    faces_per_edge = np.bincount(edge_of_corner, minlength=len(edges))
    for a, b in edges[faces_per_edge != 2]:  # boundary and non-manifold edges are sharp
        sharp[(int(a), int(b))] = INFINITE
    if boundary == "edgeAndCorner":
        boundary_edges = edges[faces_per_edge == 1]
        valence = np.bincount(edges.ravel(), minlength=n)
        on_boundary = np.bincount(boundary_edges.ravel(), minlength=n)
        vertex_sharpness[(on_boundary == 2) & (valence == 2)] = INFINITE
    hole = np.zeros(len(counts), dtype=bool)
    holes = _holes(surface, time, diag)
    hole[holes[holes < len(counts)]] = True
    authored = np.arange(len(counts)) if surface.authored_face is None else surface.authored_face
    return Cage(counts, indices, n, sharp, vertex_sharpness, authored, hole)


def _holes(surface: Surface, time: Usd.TimeCode, diag: Diagnostics) -> np.ndarray:
    holes = attributes.int_array(UsdGeom.Mesh(surface.prim).GetHoleIndicesAttr(), time, diag)
    if holes is None or not surface.prim.IsA(UsdGeom.Mesh):
        return np.zeros(0, dtype=np.int64)
    bad = (holes < 0) | (holes >= surface.topology.face_count)
    if np.any(bad):
        diag.warn(surface.where, f"{int(bad.sum())} holeIndices out of range; ignored")
    return holes[~bad]


def _drop_holes(surface: Surface, hole: np.ndarray) -> Surface:
    """Without the triangles of hole faces (``hole``: a face mask, or indices of hole faces)."""
    if hole.dtype != bool:
        mask = np.zeros(surface.topology.face_count, dtype=bool)
        mask[hole] = True
        hole = mask
    if not hole.any():
        return surface
    t = surface.topology
    keep = ~hole[t.triangle_face]
    topology = replace(t, triangles=t.triangles[keep], triangle_face=t.triangle_face[keep])
    return replace(surface, topology=topology)


def _sharpness_arrays(cage: Cage, edges: np.ndarray) -> np.ndarray:
    keys = [(int(a), int(b)) for a, b in edges]
    return np.array([cage.edge_sharpness.get(k, 0.0) for k in keys])


def _vertex_rules(
    cage: Cage,
    edges: np.ndarray,
    edge_s: np.ndarray,
    smooth: sparse.csr_matrix,
    crease: sparse.csr_matrix,
) -> sparse.csr_matrix:
    """Blend smooth / crease / corner vertex rules by the number and sharpness of creased edges."""
    n = cage.n_points
    creased = edge_s > 0
    count = np.bincount(edges[creased].ravel(), minlength=n)
    total = np.bincount(
        edges[creased].ravel(), weights=np.repeat(np.minimum(edge_s[creased], 1.0), 2), minlength=n
    )
    edge_weight = np.where(count > 0, total / np.maximum(count, 1), 0.0)
    corner = (count > 2) | (cage.vertex_sharpness > 0)
    w_corner = np.where(cage.vertex_sharpness > 0, np.minimum(cage.vertex_sharpness, 1.0), 0.0)
    w_corner = np.where(count > 2, np.maximum(w_corner, edge_weight), w_corner)
    w_crease = np.where((count == 2) & ~corner, edge_weight, 0.0)
    w_smooth = 1.0 - w_corner - w_crease
    identity = sparse.identity(n, format="csr")
    return (
        sparse.diags(w_smooth) @ smooth
        + sparse.diags(w_crease) @ crease
        + sparse.diags(w_corner) @ identity
    ).tocsr()


def _crease_rule(n: int, edges: np.ndarray, edge_s: np.ndarray) -> sparse.csr_matrix:
    """(a + 6v + b)/8 over the two creased edges (a, b their other ends)."""
    creased = edges[edge_s > 0]
    rows = np.concatenate([creased[:, 0], creased[:, 1], np.arange(n)])
    cols = np.concatenate([creased[:, 1], creased[:, 0], np.arange(n)])
    vals = np.concatenate([np.full(2 * len(creased), 1 / 8), np.full(n, 6 / 8)])
    return sparse.csr_matrix((vals, (rows, cols)), shape=(n, n))


def _child_sharpness(cage: Cage, edges: np.ndarray, edge_s: np.ndarray) -> dict:
    """Each parent edge (a, b) with sharpness s → child edges (a, m), (m, b) with s − 1."""
    n = cage.n_points
    out: dict[tuple[int, int], float] = {}
    for e in np.flatnonzero(edge_s > 1.0):
        a, b = int(edges[e, 0]), int(edges[e, 1])
        s = edge_s[e] - 1.0
        out[(a, n + e)] = s
        out[(min(b, n + e), max(b, n + e))] = s
    return out


def _incidence(rows: np.ndarray, cols: np.ndarray, shape, values=None) -> sparse.csr_matrix:
    values = np.ones(len(rows)) if values is None else values
    return sparse.csr_matrix((values, (rows, cols)), shape=shape)


# -- Catmull-Clark -------------------------------------------------------------------------------


@dataclass
class Level:
    """The incidence structure both schemes start a level from."""

    face: np.ndarray  # (C,) face of each corner
    nxt: np.ndarray  # (C,) next corner in its face
    prv: np.ndarray  # (C,) previous corner in its face
    edges: np.ndarray  # (E, 2) unique edges (a < b)
    edge_of_corner: np.ndarray  # (C,) edge from each corner to the next
    edge_s: np.ndarray  # (E,) sharpness
    ends: sparse.csr_matrix  # (E, n): a + b of each edge
    edge_faces: sparse.csr_matrix  # (E, F) incidence
    n_faces: np.ndarray  # (E,) faces per edge


def _level(cage: Cage) -> Level:
    face, nxt, prv, edges, edge_of_corner = _edges(cage.counts, cage.indices)
    n_edges = len(edges)
    edge_faces = _incidence(edge_of_corner, face, (n_edges, len(cage.counts)))
    return Level(
        face,
        nxt,
        prv,
        edges,
        edge_of_corner,
        _sharpness_arrays(cage, edges),
        _incidence(np.repeat(np.arange(n_edges), 2), edges.ravel(), (n_edges, cage.n_points)),
        edge_faces,
        np.asarray(edge_faces.sum(axis=1)).ravel(),
    )


def _catmull_clark(cage: Cage) -> Step:
    counts, indices, n = cage.counts, cage.indices, cage.n_points
    F, C = len(counts), len(indices)
    lv = _level(cage)
    face, nxt, prv, edges, edge_of_corner = lv.face, lv.nxt, lv.prv, lv.edges, lv.edge_of_corner
    E, edge_s, ends, edge_faces, n_faces = len(edges), lv.edge_s, lv.ends, lv.edge_faces, lv.n_faces
    face_pts = _incidence(face, indices, (F, n), 1.0 / counts[face])  # centroids
    smooth_edge = 0.25 * ends + 0.25 * (edge_faces @ face_pts)
    w = np.where(n_faces == 2, np.minimum(edge_s, 1.0), 1.0)
    edge_pts = sparse.diags(1.0 - w) @ smooth_edge + sparse.diags(w) @ (0.5 * ends)
    # smooth vertex rule: (Q + 2R + (k − 3) S) / k, k the valence
    vert_faces = _incidence(indices, face, (n, F))
    k_faces = np.maximum(np.asarray(vert_faces.sum(axis=1)).ravel(), 1)
    vert_edges = _incidence(edges.ravel(), np.repeat(np.arange(E), 2), (n, E))
    valence = np.maximum(np.asarray(vert_edges.sum(axis=1)).ravel(), 1)
    q = sparse.diags(1.0 / k_faces) @ (vert_faces @ face_pts)
    r = sparse.diags(1.0 / valence) @ (vert_edges @ (0.5 * ends))
    smooth = sparse.diags(1.0 / valence) @ (q + 2.0 * r) + sparse.diags((valence - 3.0) / valence)
    vert_pts = _vertex_rules(cage, edges, edge_s, smooth.tocsr(), _crease_rule(n, edges, edge_s))
    points = sparse.vstack([vert_pts, edge_pts, face_pts]).tocsr()
    lin_edge = 0.5 * ends
    linear = sparse.vstack([sparse.identity(n), lin_edge, face_pts]).tocsr()
    # child quads, one per coarse corner: (v, edge point after, face point, edge point before)
    child_indices = np.stack(
        [indices, n + edge_of_corner, n + E + face, n + edge_of_corner[prv]], axis=1
    ).ravel()
    corner_to_face = _incidence(face, np.arange(C), (F, C), 1.0 / counts[face])
    corners = sparse.vstack(
        [
            sparse.identity(C, format="csr"),
            _incidence(
                np.repeat(np.arange(C), 2),
                np.stack([np.arange(C), nxt], 1).ravel(),
                (C, C),
                np.full(2 * C, 0.5),
            ),
            corner_to_face[face],
            _incidence(
                np.repeat(np.arange(C), 2),
                np.stack([np.arange(C), prv], 1).ravel(),
                (C, C),
                np.full(2 * C, 0.5),
            ),
        ]
    ).tocsr()
    # interleave the four blocks so that rows 4c..4c+3 are the child quad of corner c
    order = np.stack([np.arange(C) + i * C for i in range(4)], axis=1).ravel()
    child = Cage(
        np.full(C, 4),
        child_indices,
        n + E + F,
        _child_sharpness(cage, edges, edge_s),
        np.concatenate([np.maximum(cage.vertex_sharpness - 1.0, 0.0), np.zeros(E + F)]),
        cage.parent_face[face],
        cage.hole[face],
    )
    return Step(points, linear, corners[order], face, child)


# -- Loop ---------------------------------------------------------------------------------------


def _loop(cage: Cage) -> Step:
    counts, indices, n = cage.counts, cage.indices, cage.n_points
    F, C = len(counts), len(indices)
    lv = _level(cage)
    face, edges, edge_of_corner = lv.face, lv.edges, lv.edge_of_corner
    E, edge_s, ends, edge_faces, n_faces = len(edges), lv.edge_s, lv.ends, lv.edge_faces, lv.n_faces
    tri_sum = _incidence(face, indices, (F, n))
    smooth_edge = 0.125 * ends + 0.125 * (edge_faces @ tri_sum)  # 3/8 (a+b) + 1/8 (c+d)
    w = np.where(n_faces == 2, np.minimum(edge_s, 1.0), 1.0)
    edge_pts = sparse.diags(1.0 - w) @ smooth_edge + sparse.diags(w) @ (0.5 * ends)
    vert_edges = _incidence(edges.ravel(), np.repeat(np.arange(E), 2), (n, E))
    valence = np.maximum(np.asarray(vert_edges.sum(axis=1)).ravel(), 1)
    beta = (5 / 8 - (3 / 8 + np.cos(2 * np.pi / valence) / 4) ** 2) / valence  # Loop 1987
    neighbours = vert_edges @ ends - sparse.diags(valence.astype(float))
    smooth = sparse.diags(1.0 - valence * beta) + sparse.diags(beta) @ neighbours
    vert_pts = _vertex_rules(cage, edges, edge_s, smooth.tocsr(), _crease_rule(n, edges, edge_s))
    points = sparse.vstack([vert_pts, edge_pts]).tocsr()
    linear = sparse.vstack([sparse.identity(n), 0.5 * ends]).tocsr()
    c0 = np.arange(0, C, 3)
    c1, c2 = c0 + 1, c0 + 2
    e0, e1, e2 = (n + edge_of_corner[c] for c in (c0, c1, c2))
    v0, v1, v2 = indices[c0], indices[c1], indices[c2]
    child_indices = np.stack([v0, e0, e2, v1, e1, e0, v2, e2, e1, e0, e1, e2], axis=1).ravel()

    def corner_rows(spec):
        rows, cols, vals = [], [], []
        for slot, parts in enumerate(spec):
            for corner, weight in parts:
                rows.append(np.arange(F) * 12 + slot)
                cols.append(corner)
                vals.append(np.full(F, weight))
        return _incidence(
            np.concatenate(rows), np.concatenate(cols), (12 * F, C), np.concatenate(vals)
        )

    m01, m12, m20 = [(c0, 0.5), (c1, 0.5)], [(c1, 0.5), (c2, 0.5)], [(c2, 0.5), (c0, 0.5)]
    corners = corner_rows(
        [[(c0, 1.0)], m01, m20, [(c1, 1.0)], m12, m01, [(c2, 1.0)], m20, m12, m01, m12, m20]
    )
    parent = np.repeat(np.arange(F), 4)
    child = Cage(
        np.full(4 * F, 3),
        child_indices,
        n + E,
        _child_sharpness(cage, edges, edge_s),
        np.concatenate([np.maximum(cage.vertex_sharpness - 1.0, 0.0), np.zeros(E)]),
        cage.parent_face[parent],
        cage.hole[parent],
    )
    return Step(points, linear, corners, parent, child)


def _bilinear(cage: Cage) -> Step:
    step = _catmull_clark(cage)
    return replace(step, points=step.linear)


_LEVEL = {"catmullClark": _catmull_clark, "loop": _loop, "bilinear": _bilinear}


def _renderable_faces(surface: Surface) -> Surface:
    """Only the polygons that kept triangles (no NaN points, no bad indices), primvars to match."""
    t = surface.topology
    keep = np.zeros(t.face_count, dtype=bool)
    keep[t.triangle_face] = True
    if keep.all():
        return surface
    corner_keep = keep[t.corner_face]
    kept_faces = np.flatnonzero(keep)
    counts = t.face_vertex_counts[keep]
    indices = t.face_vertex_indices[corner_keep]
    points = np.nan_to_num(t.points, nan=0.0, posinf=0.0, neginf=0.0)  # the rest are unused
    topology = make_topology(points, counts, indices, t.left_handed, surface.where, Diagnostics())
    primvars = {}
    for name, pv in surface.primvars.items():
        if pv.interpolation == "faceVarying" and len(pv.values) >= len(corner_keep):
            pv = Primvar(pv.values[: len(corner_keep)][corner_keep], pv.interpolation, pv.role)
        elif pv.interpolation == "uniform" and len(pv.values) >= t.face_count:
            pv = Primvar(pv.values[: t.face_count][keep], pv.interpolation, pv.role)
        primvars[name] = pv
    authored = kept_faces if surface.authored_face is None else surface.authored_face[kept_faces]
    return replace(surface, topology=topology, primvars=primvars, authored_face=authored)


def _triangulated(cage: Cage) -> tuple[Cage, np.ndarray]:
    """The cage with polygons fanned into triangles, and the coarse corner of each new corner."""
    counts = cage.counts
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    fan = np.maximum(counts - 2, 0)
    tri_face = np.repeat(np.arange(len(counts)), fan)
    k = np.arange(len(tri_face)) - np.repeat(np.cumsum(fan) - fan, fan)
    first = starts[tri_face]
    corner_map = np.stack([first, first + k + 1, first + k + 2], axis=1).ravel()
    return (
        Cage(
            np.full(len(tri_face), 3),
            cage.indices[corner_map],
            cage.n_points,
            cage.edge_sharpness,
            cage.vertex_sharpness,
            cage.parent_face[tri_face],
            cage.hole[tri_face],
        ),
        corner_map,
    )


def _faces_to_triangles(surface: Surface, corner_map: np.ndarray) -> Surface:
    """Face-varying and uniform primvars re-indexed for the fan-triangulated cage."""
    t = surface.topology
    tri_face = t.corner_face[corner_map][::3]
    primvars = {}
    for name, pv in surface.primvars.items():
        if pv.interpolation == "faceVarying" and len(pv.values) >= len(t.face_vertex_indices):
            pv = Primvar(pv.values[corner_map], pv.interpolation, pv.role)
        elif pv.interpolation == "uniform" and len(pv.values) >= t.face_count:
            pv = Primvar(pv.values[tri_face], pv.interpolation, pv.role)
        primvars[name] = pv
    return replace(surface, primvars=primvars)
