"""Quadric half-edge collapse in NumPy: the decimation used when pymeshlab cannot load.

Garland & Heckbert, "Surface simplification using quadric error metrics" (SIGGRAPH 1997),
with the choices :func:`~pavonine.pipeline.convert.mesh.decimate_mesh` asks of pymeshlab's
``meshing_decimation_quadric_edge_collapse``:

- *half-edge* collapse: a vertex ``u`` merges into a neighbour ``v`` that stays where it is
  (``optimalplacement=False``), so every surviving vertex keeps its attributes exactly;
- boundary vertices (the silhouette, and the atlas seams, along which the mesh is split) are
  never removed (``preserveboundary``);
- the link condition keeps the topology (``preservetopology``; Dey et al. 1999: ``u`` and
  ``v`` share exactly the two neighbours opposite their edge); no triangle may turn its normal
  by more than :data:`NORMAL_LIMIT_DEG` (``preservenormal``) nor flip or flatten in ``st``;
- priority: quadric error over ``min(quality, QUALITY_THRESHOLD)`` (``qualitythr=0.3``), as
  VCG's ``TriEdgeCollapseQuadric`` weighs it.

VCG collapses one edge at a time from a heap. Here collapses are applied in rounds, vectorised:
every vertex picks its cheapest valid collapse, and picks at least three edges apart, the
cheaper first, are applied together (their neighbourhoods are disjoint, so each check made
before the round still holds after it).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.sparse import coo_matrix

from pavonine.pipeline.convert.topology import edges, has_distinct_corners

#: Largest turn of a triangle's normal a collapse may cause (degrees).
NORMAL_LIMIT_DEG = 60.0
#: Triangles of at least this quality (1 = equilateral, ``4√3·area / Σ edge²``) carry no penalty.
QUALITY_THRESHOLD = 0.3


def plane_quadrics(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Per-vertex sum of the area-weighted quadrics ``K = a·ppᵀ`` of its triangles' planes
    ``p = (n, −n·x)`` (Garland & Heckbert 1997, Eq. 2), shape ``(n, 4, 4)``, cm⁴ for cm input."""
    a, b, c = points[faces[:, 0]], points[faces[:, 1]], points[faces[:, 2]]
    normal = np.cross(b - a, c - a)
    double_area = np.linalg.norm(normal, axis=1)
    unit = normal / np.maximum(double_area, 1e-300)[:, None]
    plane = np.column_stack([unit, -np.sum(unit * a, axis=1)])
    k = 0.5 * double_area[:, None, None] * plane[:, :, None] * plane[:, None, :]
    flat = k.reshape(len(faces), 16)
    n = len(points)
    quadric = np.zeros((n, 16))
    for corner in range(3):
        for entry in range(16):
            quadric[:, entry] += np.bincount(faces[:, corner], flat[:, entry], minlength=n)
    return quadric.reshape(n, 4, 4)


def boundary_vertices(faces: np.ndarray, n: int) -> np.ndarray:
    """Mask of the vertices on an edge that only one triangle has."""
    pairs = edges(faces)
    unique, counts = np.unique(pairs[:, 0] * n + pairs[:, 1], return_counts=True)
    single = unique[counts == 1]
    mask = np.zeros(n, dtype=bool)
    mask[single // n] = mask[single % n] = True
    return mask


def _cross(e1: np.ndarray, e2: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (k, 3) arrays (``np.cross`` without its overhead)."""
    return np.column_stack(
        [
            e1[:, 1] * e2[:, 2] - e1[:, 2] * e2[:, 1],
            e1[:, 2] * e2[:, 0] - e1[:, 0] * e2[:, 2],
            e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0],
        ]
    )


def _fans(
    points: np.ndarray, st: np.ndarray, apex: np.ndarray, a: np.ndarray, b: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Triangles ``(apex, a, b)``: unnormalised normals, twice their signed ``st`` area, and the
    squared lengths of their two edges at ``apex``."""
    e1, e2 = points[a] - points[apex], points[b] - points[apex]
    s1, s2 = st[a] - st[apex], st[b] - st[apex]
    st_area = s1[:, 0] * s2[:, 1] - s1[:, 1] * s2[:, 0]
    return _cross(e1, e2), st_area, np.einsum("ij,ij->i", e1, e1) + np.einsum("ij,ij->i", e2, e2)


def collapse_costs(
    points: np.ndarray,
    faces: np.ndarray,
    st: np.ndarray,
    quadric: np.ndarray,
    locked: np.ndarray,
    floor: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every valid half-edge collapse ``u → v``: ``(u, v, priority)``.

    Valid: ``u`` is not locked, the link condition holds, and no remaining triangle around
    ``u`` turns by more than :data:`NORMAL_LIMIT_DEG` or flips or flattens in ``st``.
    """
    n = len(points)
    u = faces.ravel()
    v = faces[:, [1, 2, 0]].ravel()  # each interior edge once per direction, from its 2 faces
    free = ~locked[u]
    u, v = u[free], v[free]
    adjacency = coo_matrix((np.ones(len(u) * 2), (np.r_[u, v], np.r_[v, u])), shape=(n, n))
    adjacency = (adjacency.tocsr() > 0).astype(np.int32)
    common = np.asarray(adjacency[u].multiply(adjacency[v]).sum(axis=1)).ravel()
    link = common == 2
    u, v = u[link], v[link]
    # Every (candidate, triangle around u) pair: the triangle with u replaced by v.
    corner_vertex = faces.ravel()
    order = np.argsort(corner_vertex, kind="stable")
    degree = np.bincount(corner_vertex, minlength=n)
    start = np.cumsum(degree) - degree
    reps = degree[u]
    pair = np.repeat(np.arange(len(u)), reps)
    offset = np.arange(len(pair)) - np.repeat(np.cumsum(reps) - reps, reps)
    corner = order[start[u][pair] + offset]
    face, k = np.divmod(corner, 3)
    a = corner_vertex[3 * face + (k + 1) % 3]  # the triangle is (u, a, b), counter-clockwise
    b = corner_vertex[3 * face + (k + 2) % 3]
    target = v[pair]
    stays = (a != target) & (b != target)  # the two triangles on the edge uv vanish
    pair, face, a, b, target = (x[stays] for x in (pair, face, a, b, target))
    face_normal, face_st, _ = _fans(points, st, faces[:, 0], faces[:, 1], faces[:, 2])
    face_length = np.sqrt(np.einsum("ij,ij->i", face_normal, face_normal))
    old_normal, old_st, old_length = face_normal[face], face_st[face], face_length[face]
    new_normal, new_st, spokes = _fans(points, st, target, a, b)
    new_length = np.sqrt(np.einsum("ij,ij->i", new_normal, new_normal))
    rim = points[b] - points[a]
    perimeter2 = spokes + np.einsum("ij,ij->i", rim, rim)
    quality = 2.0 * math.sqrt(3.0) * new_length / np.maximum(perimeter2, 1e-300)
    cos_turn = np.einsum("ij,ij->i", old_normal, new_normal) / np.maximum(
        old_length * new_length, 1e-300
    )
    bad = (
        (cos_turn < math.cos(math.radians(NORMAL_LIMIT_DEG)))
        | (old_st * new_st <= 0.0)
        | (np.abs(new_st) <= 1e-6 * np.abs(old_st))
    )
    invalid = np.bincount(pair, bad, minlength=len(u)) > 0
    worst = np.full(len(u), QUALITY_THRESHOLD)
    if len(pair):
        first = np.flatnonzero(np.r_[True, pair[1:] != pair[:-1]])  # pair is sorted
        worst[pair[first]] = np.minimum(np.minimum.reduceat(quality, first), QUALITY_THRESHOLD)
    homogeneous = np.column_stack([points[v], np.ones(len(v))])
    error = np.einsum("ei,eij,ej->e", homogeneous, quadric[u] + quadric[v], homogeneous)
    priority = np.maximum(error, floor) / np.maximum(worst, 1e-12)
    return u[~invalid], v[~invalid], priority[~invalid]


def independent_collapses(
    u: np.ndarray, v: np.ndarray, priority: np.ndarray, faces: np.ndarray, n: int, budget: int
) -> tuple[np.ndarray, np.ndarray]:
    """Each vertex's cheapest collapse; of those, in passes, the ones cheapest within two
    edges (then those and their two rings leave, and the next pass picks among the rest), so
    that no two kept collapses touch a common triangle or neighbour; the cheapest ``budget``
    of the picks."""
    best = np.lexsort((priority, u))
    first = np.r_[True, u[best][1:] != u[best][:-1]]
    bu, bv, bp = u[best][first], v[best][first], priority[best][first]
    by_cost = np.argsort(bp, kind="stable")
    bu, bv = bu[by_cost], bv[by_cost]
    none = np.iinfo(np.int64).max
    rank = np.full(n, none)
    rank[bu] = np.arange(len(bu))
    a = faces.ravel()
    b = faces[:, [1, 2, 0]].ravel()
    chosen = np.zeros(len(bu), dtype=bool)
    for _ in range(_SELECTION_PASSES):  # each pass: the candidates cheapest within two rings
        near = rank.copy()
        for _ in range(2):
            reach = near.copy()
            np.minimum.at(reach, a, near[b])
            np.minimum.at(reach, b, near[a])
            near = reach
        picked = (rank[bu] == near[bu]) & (rank[bu] != none)
        if not picked.any():
            break
        chosen |= picked
        # The picks and every candidate within two rings of one leave the race.
        blocked = np.zeros(n, dtype=bool)
        blocked[bu[picked]] = True
        for _ in range(2):
            grown = blocked.copy()
            grown[a[blocked[b]]] = True
            grown[b[blocked[a]]] = True
            blocked = grown
        rank[blocked] = none
    kept = np.flatnonzero(chosen)[:budget]  # bu is in order of cost
    return bu[kept], bv[kept]


#: Passes of picking within one round of collapses (more: more collapses per round).
_SELECTION_PASSES = 24


def collapse_to(points: np.ndarray, faces: np.ndarray, st: np.ndarray, target: int) -> np.ndarray:
    """Faces after half-edge collapses bring ``faces`` down to about ``target`` triangles
    (fewer collapses when no valid one is left). Indices still refer to ``points``; a vertex
    no face uses any more was removed."""
    faces = np.asarray(faces, dtype=np.int64)
    n = len(points)
    quadric = plane_quadrics(points, faces)
    locked = boundary_vertices(faces, n)
    diagonal = float(np.linalg.norm(np.ptp(points, axis=0)))
    floor = 1e-15 * diagonal**4  # VCG's QuadricEpsilon, relative to the mesh size
    while len(faces) > target:
        u, v, priority = collapse_costs(points, faces, st, quadric, locked, floor)
        if len(u) == 0:
            break
        budget = math.ceil((len(faces) - target) / 2)  # a collapse removes two triangles
        u, v = independent_collapses(u, v, priority, faces, n, budget)
        remap = np.arange(n)
        remap[u] = v
        faces = remap[faces]
        faces = faces[has_distinct_corners(faces)]
        quadric[v] += quadric[u]
    return faces
