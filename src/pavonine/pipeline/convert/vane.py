"""The coarse vane: a feather-space lattice cut to the alpha map's silhouette by marching
triangles, freed of small islands and cleaned (:func:`base_vane`; by meshlab's filters, or their
NumPy twins in :mod:`~pavonine.pipeline.convert.cleaning` when pymeshlab cannot load).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from pavonine.base.map_files import area_reduce, sample_bilinear
from pavonine.pipeline.convert.cleaning import clean, compact, triangle_areas
from pavonine.pipeline.convert.meshing import meshing_backend

#: Smallest fraction of an edge at which the silhouette may cut it (keeps triangles fat).
_CUT_CLAMP = 0.15


def grid_mesh(rows: int, cols: int) -> tuple[np.ndarray, np.ndarray]:
    """Feather-space vertices of a ``rows × cols`` lattice over [0,1]² and its triangles
    (diagonals alternating so the lattice has no preferred direction), counter-clockwise."""
    u, v = np.meshgrid(np.linspace(0.0, 1.0, cols), np.linspace(0.0, 1.0, rows))
    uv = np.stack([u.ravel(), v.ravel()], axis=1)
    idx = np.arange(rows * cols).reshape(rows, cols)
    a, b = idx[:-1, :-1], idx[:-1, 1:]
    c, d = idx[1:, 1:], idx[1:, :-1]
    flip = ((np.arange(rows - 1)[:, None] + np.arange(cols - 1)[None, :]) % 2).astype(bool)
    t1 = np.where(flip[..., None], np.stack([a, b, d], -1), np.stack([a, b, c], -1))
    t2 = np.where(flip[..., None], np.stack([b, c, d], -1), np.stack([a, c, d], -1))
    faces = np.concatenate([t1.reshape(-1, 3), t2.reshape(-1, 3)])
    return uv, faces


def clip_to_silhouette(
    uv: np.ndarray, faces: np.ndarray, level: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Keep the part of a triangle mesh where the piecewise-linear ``level`` is positive.

    Marching triangles: each triangle is kept, dropped, or cut along the zero line into one
    triangle or a quad (two triangles). Cut points are shared per edge, so the result is a
    conforming manifold mesh whose boundary follows the silhouette. A cut is kept at least
    ``15 %`` of an edge away from its ends so no sliver is created.
    """
    level = np.where(level == 0.0, 1e-9, level)
    inside = level > 0
    count = inside[faces].sum(axis=1)
    keep = faces[count == 3]
    partial = faces[(count == 1) | (count == 2)]
    pcount = inside[partial].sum(axis=1)
    # Rotate each partial triangle (keeping orientation) so that its odd vertex comes first:
    # the single inside vertex (count 1) or the single outside vertex (count 2).
    odd = np.where(pcount[:, None] == 1, inside[partial], ~inside[partial])
    shift = np.argmax(odd, axis=1)
    order = (shift[:, None] + np.arange(3)[None, :]) % 3
    tri = np.take_along_axis(partial, order, axis=1)
    # Unique cut edges → new vertices.
    edges = np.concatenate([tri[:, [0, 1]], tri[:, [0, 2]]])
    key = np.sort(edges, axis=1)
    unique, inverse = np.unique(key, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    l0, l1 = level[unique[:, 0]], level[unique[:, 1]]
    t = np.clip(l0 / (l0 - l1), _CUT_CLAMP, 1.0 - _CUT_CLAMP)
    cut_uv = uv[unique[:, 0]] * (1 - t)[:, None] + uv[unique[:, 1]] * t[:, None]
    cut_index = len(uv) + inverse
    c01 = cut_index[: len(tri)]
    c02 = cut_index[len(tri) :]
    one = pcount == 1
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    single = np.stack([a, c01, c02], axis=1)[one]
    quad_a = np.stack([c01, b, c], axis=1)[~one]
    quad_b = np.stack([c01, c, c02], axis=1)[~one]
    all_uv = np.concatenate([uv, cut_uv])
    all_faces = np.concatenate([keep, single, quad_a, quad_b])
    return compact(all_uv, all_faces)


def drop_islands(
    points: np.ndarray, faces: np.ndarray, min_share: float = 0.005
) -> tuple[np.ndarray, np.ndarray]:
    """Remove connected pieces holding less than ``min_share`` of the total area."""
    n = len(points)
    rows = np.repeat(np.arange(len(faces)), 3)
    graph = coo_matrix((np.ones(rows.size), (rows, faces.ravel())), shape=(len(faces), n))
    adjacency = graph.T @ graph
    _, labels = connected_components(adjacency, directed=False)
    area = np.abs(triangle_areas(points, faces))
    face_label = labels[faces[:, 0]]
    per_label = np.bincount(face_label, weights=area)
    keep = per_label[face_label] >= min_share * area.sum()
    return compact(points, faces[keep])


def clean_flat(uv: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Meshlab's cleaning filters on the flat feather-space mesh (positions = (u, v, 0)), or
    their NumPy twins (:func:`~pavonine.pipeline.convert.cleaning.clean`) without pymeshlab.

    Merges duplicate vertices, removes null faces and unreferenced vertices and repairs any
    non-manifold edge or vertex. Working in feather space keeps the coordinate recoverable.
    """
    backend = meshing_backend()
    if backend.name == "numpy":
        return clean(uv, faces)
    pymeshlab = backend.pymeshlab
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(np.column_stack([uv, np.zeros(len(uv))]), faces.astype(np.int32)))
    ms.meshing_remove_duplicate_vertices()
    ms.meshing_remove_null_faces()
    ms.meshing_repair_non_manifold_edges()
    ms.meshing_repair_non_manifold_vertices()
    ms.meshing_remove_unreferenced_vertices()
    mesh = ms.current_mesh()
    return mesh.vertex_matrix()[:, :2].copy(), mesh.face_matrix().astype(np.int64)


def base_vane(
    alpha: np.ndarray, threshold: float, target_triangles: int
) -> tuple[np.ndarray, np.ndarray]:
    """Coarse vane in feather space: a lattice cut to the alpha silhouette (``alpha > threshold``).

    The lattice pitch is chosen so that the kept part has about ``target_triangles``. Alpha is
    box-filtered to the pitch first so fine gaps (loose barb tips) do not shred the outline;
    they remain in the alpha map for the renderer's opacity.
    """
    height, width = alpha.shape
    aspect = width / height
    cover = float(np.mean(alpha > threshold))
    if cover <= 0.0:
        raise ValueError("alpha map is fully transparent")
    pitch = math.sqrt(target_triangles / (2.0 * aspect * max(cover, 1e-3)))
    reduced: dict[int, np.ndarray] = {}  # by factor: the corrected pitch often keeps it
    for _ in range(3):  # the first pitch is an estimate; correct it by the count it gave
        rows = max(4, round(pitch)) + 1
        cols = max(4, round((rows - 1) * aspect)) + 1
        factor = max(1, int(height / (rows - 1) / 2))
        if factor not in reduced:
            reduced[factor] = area_reduce(alpha, factor)
        filtered = reduced[factor]
        uv, faces = grid_mesh(rows, cols)
        level = sample_bilinear(filtered, uv).astype(np.float64) - threshold
        uv, faces = clip_to_silhouette(uv, faces, level)
        if len(faces) == 0:
            raise ValueError("alpha map has no region above the cut threshold at mesh resolution")
        ratio = target_triangles / len(faces)
        if abs(ratio - 1.0) < 0.02:
            break
        pitch *= math.sqrt(ratio)
    uv, faces = drop_islands(uv, faces)
    return clean_flat(uv, faces)
