"""Regular refinement of an atlased mesh: every triangle split into ``n²`` similar ones, with
every attribute and the atlas coordinates ``st`` interpolated linearly inside it (which keeps
the atlas free of overlaps), vertices on shared edges generated once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pavonine.pipeline.convert.atlas import AtlasedMesh


def _lattice(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Barycentric lattice points ``(i, j)`` of a triangle split ``n`` ways, and its triangles."""
    points = [(i, j) for j in range(n + 1) for i in range(n + 1 - j)]
    index = {p: k for k, p in enumerate(points)}
    tris = []
    for j in range(n):
        for i in range(n - j):
            tris.append((index[(i, j)], index[(i + 1, j)], index[(i, j + 1)]))
            if i + j < n - 1:
                tris.append((index[(i + 1, j)], index[(i + 1, j + 1)], index[(i, j + 1)]))
    return np.array(points, dtype=np.int64), np.array(tris, dtype=np.int64)


def _refine_indices(
    faces: np.ndarray, n_vertices: int, n: int, lattice: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Global vertex index of every lattice point of every face, plus how to compute it.

    Returns ``(index[f, p], parents (k, 3), weights (k, 3))`` where new vertex ``k`` is
    ``Σ weights·vertex[parents]``; vertices on a shared edge are generated once.
    """
    i, j = lattice[:, 0], lattice[:, 1]
    m = len(faces)
    a, b, c = faces[:, 0], faces[:, 1], faces[:, 2]
    edge_pairs = np.concatenate([np.stack([a, b], 1), np.stack([a, c], 1), np.stack([b, c], 1)])
    lo, hi = (
        np.minimum(edge_pairs[:, 0], edge_pairs[:, 1]),
        np.maximum(edge_pairs[:, 0], edge_pairs[:, 1]),
    )
    edge_key = lo * n_vertices + hi
    unique_keys, edge_id = np.unique(edge_key, return_inverse=True)
    edge_id = edge_id.reshape(3, m)
    forward = (edge_pairs[:, 0] < edge_pairs[:, 1]).reshape(3, m)
    n_edges = len(unique_keys)
    edge_base = n_vertices
    interior_base = edge_base + n_edges * (n - 1)
    interior_mask = (i >= 1) & (j >= 1) & (i + j <= n - 1)
    n_interior = int(interior_mask.sum())
    interior_local = np.cumsum(interior_mask) - 1

    index = np.empty((m, len(lattice)), dtype=np.int64)
    for p, (pi, pj) in enumerate(lattice):
        if pi == 0 and pj == 0:
            index[:, p] = a
        elif pi == n and pj == 0:
            index[:, p] = b
        elif pi == 0 and pj == n:
            index[:, p] = c
        elif pj == 0:  # edge a→b, fraction pi/n from a
            k = np.where(forward[0], pi, n - pi)
            index[:, p] = edge_base + edge_id[0] * (n - 1) + (k - 1)
        elif pi == 0:  # edge a→c, fraction pj/n from a
            k = np.where(forward[1], pj, n - pj)
            index[:, p] = edge_base + edge_id[1] * (n - 1) + (k - 1)
        elif pi + pj == n:  # edge b→c, fraction pj/n from b
            k = np.where(forward[2], pj, n - pj)
            index[:, p] = edge_base + edge_id[2] * (n - 1) + (k - 1)
        else:
            index[:, p] = interior_base + np.arange(m) * n_interior + interior_local[p]

    total = interior_base + m * n_interior
    parents = np.zeros((total, 3), dtype=np.int64)
    weights = np.zeros((total, 3), dtype=np.float64)
    parents[:n_vertices, 0] = np.arange(n_vertices)
    weights[:n_vertices, 0] = 1.0
    if n > 1:
        lo_u, hi_u = unique_keys // n_vertices, unique_keys % n_vertices
        t = np.arange(1, n) / n
        rows = edge_base + np.arange(n_edges)[:, None] * (n - 1) + np.arange(n - 1)[None, :]
        parents[rows, 0] = lo_u[:, None]
        parents[rows, 1] = hi_u[:, None]
        weights[rows, 0] = 1.0 - t[None, :]
        weights[rows, 1] = t[None, :]
    if n_interior:
        ii, jj = i[interior_mask], j[interior_mask]
        rows = interior_base + np.arange(m)[:, None] * n_interior + np.arange(n_interior)[None, :]
        parents[rows] = faces[:, None, :]
        weights[rows, 0] = ((n - ii - jj) / n)[None, :]
        weights[rows, 1] = (ii / n)[None, :]
        weights[rows, 2] = (jj / n)[None, :]
    return index, parents, weights, total


@dataclass
class RefinedMesh:
    """A refined mesh: welded attributes and faces, plus per-atlas-vertex ``st`` and the
    seam-split faces (same face order) for face-varying UVs."""

    attributes: np.ndarray
    faces: np.ndarray
    split_faces: np.ndarray
    split_to_welded: np.ndarray
    st: np.ndarray

    @property
    def face_varying_st(self) -> np.ndarray:
        return self.st[self.split_faces.ravel()]


def refine(mesh: AtlasedMesh, n: int) -> RefinedMesh:
    """Split every triangle into ``n²`` similar triangles, interpolating attributes and ``st``.

    The welded mesh and the atlas (split) mesh are refined with the same lattice, so face
    ``f`` of one is face ``f`` of the other; seam vertices stay welded in the former.
    """
    lattice, tris = _lattice(n)
    index_w, parents_w, weights_w, _total_w = _refine_indices(
        mesh.faces, len(mesh.attributes), n, lattice
    )
    index_s, parents_s, weights_s, total_s = _refine_indices(
        mesh.split_faces, len(mesh.st), n, lattice
    )
    attributes = np.einsum("kj,kjc->kc", weights_w, mesh.attributes[parents_w])
    st = np.einsum("kj,kjc->kc", weights_s, mesh.st[parents_s])
    faces = index_w[:, tris].reshape(-1, 3)
    split_faces = index_s[:, tris].reshape(-1, 3)
    split_to_welded = np.empty(total_s, dtype=np.int64)
    split_to_welded[split_faces.ravel()] = faces.ravel()
    return RefinedMesh(attributes, faces, split_faces, split_to_welded, st)


def subdivision_for(base_triangles: int, target: int) -> int:
    """Segments per edge ``n`` so that ``base · n²`` is closest to ``target`` (at least 1)."""
    return max(1, round(math.sqrt(target / max(base_triangles, 1))))
