"""Clean-up of a triangle mesh in NumPy: the filters :func:`~pavonine.pipeline.convert.vane.
base_vane` runs through pymeshlab, for when pymeshlab cannot load
(:mod:`~pavonine.pipeline.convert.meshing`).

The same five steps, in meshlab's order and with its defaults: merge vertices at identical
positions, remove null faces (zero area), repair non-manifold edges by removing faces (the
smallest first, until two faces remain on the edge), repair non-manifold vertices by splitting
them (one copy per fan of faces), remove unreferenced vertices.
"""

from __future__ import annotations

import numpy as np

from pavonine.pipeline.convert.topology import corner_fans, edges, has_distinct_corners


def merge_duplicate_vertices(
    points: np.ndarray, faces: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """One vertex per distinct position (exact), faces renumbered."""
    _, first, inverse = np.unique(points, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)  # keep the vertices' original order
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return points[first[order]], rank[inverse.reshape(-1)][faces]


def triangle_areas(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area of each triangle (2-D points give signed areas, counter-clockwise positive)."""
    a, b, c = points[faces[:, 0]], points[faces[:, 1]], points[faces[:, 2]]
    if points.shape[1] == 2:
        e1, e2 = b - a, c - a
        return 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)


def drop_null_faces(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Faces with three distinct corners and a non-zero area."""
    return faces[has_distinct_corners(faces) & (triangle_areas(points, faces) != 0.0)]


def drop_non_manifold_edge_faces(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Remove, from every edge with more than two faces, its smallest faces until two remain."""
    n = len(points)
    while True:
        pairs = edges(faces)
        key = pairs[:, 0] * n + pairs[:, 1]
        _, inverse, counts = np.unique(key, return_inverse=True, return_counts=True)
        crowded = counts[inverse.reshape(-1)] > 2
        if not crowded.any():
            return faces
        face = np.tile(np.arange(len(faces)), 3)[crowded]
        edge = inverse.reshape(-1)[crowded]
        area = np.abs(triangle_areas(points, faces))[face]
        order = np.lexsort((area, edge))  # per crowded edge, its smallest face first
        first = np.r_[True, edge[order][1:] != edge[order][:-1]]
        keep = np.ones(len(faces), dtype=bool)
        keep[face[order][first]] = False
        faces = faces[keep]


def split_non_manifold_vertices(
    points: np.ndarray, faces: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """A vertex whose faces form several fans becomes one vertex per fan (same position)."""
    labels = corner_fans(faces, len(points))
    pairs, fan = np.unique(np.column_stack([faces.ravel(), labels]), axis=0, return_inverse=True)
    first = np.r_[True, pairs[1:, 0] != pairs[:-1, 0]]  # a vertex's first fan keeps its index
    index = np.where(first, pairs[:, 0], len(points) + np.cumsum(~first) - 1)
    points = np.concatenate([points, points[pairs[~first, 0]]])
    return points, index[fan.reshape(-1)].reshape(faces.shape)


def compact(points: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Drop unreferenced vertices and renumber (keeping the order)."""
    used = np.zeros(len(points), dtype=bool)
    used[faces.ravel()] = True
    remap = np.cumsum(used) - 1
    return points[used], remap[faces]


def clean(points: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The five clean-up steps (module doc) on a 2-D or 3-D triangle mesh."""
    faces = np.asarray(faces, dtype=np.int64)
    points, faces = merge_duplicate_vertices(points, faces)
    faces = drop_null_faces(points, faces)
    faces = drop_non_manifold_edge_faces(points, faces)
    points, faces = split_non_manifold_vertices(points, faces)
    return compact(points, faces)
