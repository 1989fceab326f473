"""Topology of a triangle mesh: the manifold and orientation check every LOD must pass."""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components


def edges(faces: np.ndarray) -> np.ndarray:
    """Each triangle's three edges as sorted vertex pairs, ``(3F, 2)``: all first edges
    ``(0, 1)``, then ``(1, 2)``, then ``(2, 0)`` (edge ``k·F + f`` belongs to face ``f``)."""
    return np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), 1)


def has_distinct_corners(faces: np.ndarray) -> np.ndarray:
    """Mask of the triangles whose three corners are three different vertices."""
    return (
        (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 2] != faces[:, 0])
    )


def edge_report(faces: np.ndarray, n_vertices: int) -> dict[str, int]:
    """Topology check: non-manifold edges (> 2 faces), inconsistently oriented edges and
    non-manifold vertices (a vertex whose faces form more than one fan)."""
    faces = np.asarray(faces, dtype=np.int64)
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    pairs = edges(faces)
    key = pairs[:, 0] * n_vertices + pairs[:, 1]
    _, counts = np.unique(key, return_counts=True)
    directed_key = directed[:, 0] * n_vertices + directed[:, 1]
    _, dcounts = np.unique(directed_key, return_counts=True)
    corner_v = faces.ravel()
    labels = corner_fans(faces, n_vertices)
    fans_per_vertex = np.bincount(
        np.unique(np.column_stack([corner_v, labels]), axis=0)[:, 0], minlength=n_vertices
    )
    return {
        "non_manifold_edges": int(np.sum(counts > 2)),
        "misoriented_edges": int(np.sum(dcounts > 1)),
        "non_manifold_vertices": int(np.sum(fans_per_vertex > 1)),
    }


def corner_fans(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """Per corner (``faces.ravel()`` order), a label of its *fan*: the corners of a vertex whose
    faces connect through edges incident to that vertex share a label. A manifold vertex has one
    fan; a vertex where two pieces touch has more."""
    faces = np.asarray(faces, dtype=np.int64)
    corner_v = faces.ravel()
    nxt = faces[:, [1, 2, 0]].ravel()
    prv = faces[:, [2, 0, 1]].ravel()
    # Each corner links (v, nxt) and (v, prv) "spokes"; corners sharing a spoke are linked.
    spokes = np.concatenate([corner_v * n_vertices + nxt, corner_v * n_vertices + prv])
    corners = np.concatenate([np.arange(len(corner_v)), np.arange(len(corner_v))])
    order = np.argsort(spokes, kind="stable")
    s_sorted, c_sorted = spokes[order], corners[order]
    same = s_sorted[1:] == s_sorted[:-1]
    links = (c_sorted[:-1][same], c_sorted[1:][same])
    n_corners = len(corner_v)
    graph = coo_matrix((np.ones(len(links[0])), links), shape=(n_corners, n_corners))
    return connected_components(graph, directed=False)[1]
