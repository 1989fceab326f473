"""The texture atlas (``st``): charting and packing with xatlas, rasterising triangles onto
texels, and the atlas checks (overlaps, folds).

xatlas keeps a nearly flat, connected surface such as a feather vane in *one* chart, whose
outline (a teardrop about twice as long as wide) fills barely a quarter of a square atlas;
a long rachis tube adds strips as long as the feather. So each mesh may be cut into *pieces*
first (:func:`chart_pieces`: bands along its length, no longer than half the vane's width),
which xatlas then charts and packs one by one: the eye feather's atlas goes from 22 % to 73 %
of the square filled (``python -m pavonine.pipeline.convert.atlas`` on the shipped recipes).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import xatlas
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from pavonine.pipeline.convert import topology

#: Charting pieces are bands at most this share of the vane's width long (see module doc).
PIECE_SHARE_OF_WIDTH = 0.5


@dataclass
class AtlasedMesh:
    """A coarse mesh with its xatlas atlas.

    ``attributes``: per *welded* vertex (float, any width). ``faces``: welded indices.
    ``split_faces``: the same faces in atlas (seam-split) indices; ``split_to_welded`` maps an
    atlas vertex to its welded vertex; ``st``: per atlas vertex.
    """

    attributes: np.ndarray
    faces: np.ndarray
    split_faces: np.ndarray
    split_to_welded: np.ndarray
    st: np.ndarray


def chart_pieces(coordinate: np.ndarray, faces: np.ndarray, count: int) -> np.ndarray:
    """Per-face piece label: ``count`` equal bands of the per-vertex ``coordinate`` (by face
    centroid)."""
    centre = coordinate[faces].mean(axis=1)
    low, high = float(coordinate.min()), float(coordinate.max())
    scaled = (centre - low) / max(high - low, 1e-12) * count
    return np.clip(scaled.astype(np.int64), 0, count - 1)


def piece_count(length: float, width: float) -> int:
    """Number of bands for a mesh ``length`` long when pieces may be ``PIECE_SHARE_OF_WIDTH ×
    width`` long (at least one)."""
    return max(1, math.ceil(length / max(PIECE_SHARE_OF_WIDTH * width, 1e-12)))


def cut_edges(faces: np.ndarray, labels: np.ndarray) -> tuple[int, int]:
    """``(boundary edges, seam edges)`` of a triangle mesh whose faces carry piece ``labels``:
    edges with one face, and edges between faces of two different pieces."""
    edges = topology.edges(faces)
    owner = np.tile(np.arange(len(faces)), 3)
    order = np.lexsort((edges[:, 1], edges[:, 0]))
    edges, owner = edges[order], owner[order]
    same = np.all(edges[1:] == edges[:-1], axis=1)
    shared = np.count_nonzero(same)
    seams = int(np.count_nonzero(labels[owner[:-1][same]] != labels[owner[1:][same]]))
    return int(len(edges) - 2 * shared), seams


def build_atlas(
    meshes: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
    resolution: int = 2048,
    pieces: list[np.ndarray | None] | None = None,
) -> tuple[list[AtlasedMesh], int]:
    """Chart and pack ``(points3d, faces, attributes)`` meshes into one shared xatlas atlas.

    ``pieces[i]`` (optional) labels mesh ``i``'s faces; each label is charted separately (a
    seam runs between pieces). ``st`` is scaled uniformly (texels stay square) into [0, 1]²,
    the longer side spanning it. Returns the atlased meshes and the chart count.
    """
    atlas = xatlas.Atlas()
    plan: list[tuple[int, np.ndarray, np.ndarray]] = []  # (mesh, its faces, piece → mesh vertex)
    for i, (points, faces, _) in enumerate(meshes):
        labels = pieces[i] if pieces is not None and pieces[i] is not None else None
        if labels is None:
            labels = np.zeros(len(faces), dtype=np.int64)
        for label in np.unique(labels):
            face_ids = np.nonzero(labels == label)[0]
            used, local = np.unique(faces[face_ids], return_inverse=True)
            atlas.add_mesh(points[used].astype(np.float32), local.reshape(-1, 3).astype(np.uint32))
            plan.append((i, face_ids, used))
    chart_options = xatlas.ChartOptions()
    pack_options = xatlas.PackOptions()
    pack_options.resolution = resolution
    pack_options.padding = 4
    pack_options.bilinear = True
    atlas.generate(chart_options, pack_options)
    scale = np.array([atlas.width, atlas.height], dtype=np.float64) / max(atlas.width, atlas.height)
    split: list[list] = [[np.zeros((len(m[1]), 3), dtype=np.int64), [], [], 0] for m in meshes]
    for k, (i, face_ids, used) in enumerate(plan):
        vmapping, indices, uvs = atlas[k]
        entry = split[i]
        entry[0][face_ids] = indices.astype(np.int64).reshape(-1, 3) + entry[3]
        entry[1].append(used[vmapping.astype(np.int64)])
        entry[2].append(uvs.astype(np.float64) * scale)
        entry[3] += len(vmapping)
    result = []
    for (_, faces, attributes), (split_faces, mappings, sts, _) in zip(meshes, split, strict=True):
        mapping = np.concatenate(mappings)
        if not np.array_equal(mapping[split_faces], faces):
            raise RuntimeError("xatlas reordered faces; cannot carry attributes")
        result.append(AtlasedMesh(attributes, faces, split_faces, mapping, np.concatenate(sts)))
    return result, atlas.chart_count


# --------------------------------------------------------------------------- rasterising


@dataclass
class Coverage:
    """Texel centres covered by triangles: one row per (texel, triangle) hit.

    ``texel``: flat index ``row · width + column``; ``triangle``: index of the covering
    triangle; ``barycentric``: ``(n, 3)`` weights of its corners at the texel centre.
    """

    texel: np.ndarray
    triangle: np.ndarray
    barycentric: np.ndarray


def _edge(a: np.ndarray, b: np.ndarray, px: np.ndarray, py: np.ndarray) -> np.ndarray:
    """Twice the signed area of (a, b, p): positive when p is left of a → b."""
    return (b[..., 0] - a[..., 0]) * (py - a[..., 1]) - (b[..., 1] - a[..., 1]) * (px - a[..., 0])


def _hits(t: np.ndarray, ids: np.ndarray, px: np.ndarray, py: np.ndarray, width: int, height: int):
    """Hits of texel centres ``(px, py)`` ``(m, k)`` (pixel units) against triangles ``t``
    ``(m, 3, 2)``, whose indices are ``ids`` ``(m,)``."""
    a, b, c = t[:, None, 0, :], t[:, None, 1, :], t[:, None, 2, :]
    area = _edge(a, b, c[..., 0], c[..., 1])  # (m, 1)
    sign = np.sign(area)
    w0 = _edge(b, c, px, py) * sign
    w1 = _edge(c, a, px, py) * sign
    w2 = _edge(a, b, px, py) * sign
    inside = (w0 > 0) & (w1 > 0) & (w2 > 0) & (sign != 0)
    inside &= (px >= 0) & (py >= 0) & (px < width) & (py < height)
    col = np.floor(px[inside]).astype(np.int64)
    row = np.floor(py[inside]).astype(np.int64)
    total = np.broadcast_to(np.abs(area), inside.shape)[inside]
    weights = np.stack([w0[inside], w1[inside], w2[inside]], axis=1) / total[:, None]
    return row * width + col, np.broadcast_to(ids[:, None], inside.shape)[inside], weights


def rasterise(triangles: np.ndarray, width: int, height: int) -> Coverage:
    """Every texel centre strictly inside a triangle, with barycentric weights.

    ``triangles``: ``(n, 3, 2)`` corners in pixel units (texel ``(row r, column c)`` has its
    centre at ``(c + ½, r + ½)``), either winding. A centre exactly on an edge belongs to
    neither triangle (so shared edges are never counted twice); degenerate triangles cover
    nothing. Vectorised: triangles are grouped by the size of their bounding box and each
    group tests the texel centres of a box of that size at once.
    """
    tri = np.asarray(triangles, dtype=np.float64)
    lo = np.floor(tri.min(axis=1) - 0.5).astype(np.int64)
    hi = np.ceil(tri.max(axis=1) - 0.5).astype(np.int64)
    span = (hi - lo).max(axis=1) + 1
    found: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    done = np.zeros(len(tri), dtype=bool)
    for big in np.nonzero(span > 64)[0]:
        done[big] = True
        rows, cols = np.mgrid[lo[big, 1] : hi[big, 1] + 1, lo[big, 0] : hi[big, 0] + 1]
        px, py = cols.reshape(1, -1) + 0.5, rows.reshape(1, -1) + 0.5
        found.append(_hits(tri[big : big + 1], np.array([big]), px, py, width, height))
    bucket = 4
    while not done.all():
        members = np.nonzero(~done & (span <= bucket))[0]
        done[members] = True
        for chunk in np.array_split(members, max(1, len(members) * bucket**2 // 2_000_000)):
            if len(chunk):
                dy, dx = np.mgrid[0:bucket, 0:bucket]
                px = lo[chunk, 0, None] + dx.ravel()[None, :] + 0.5
                py = lo[chunk, 1, None] + dy.ravel()[None, :] + 0.5
                found.append(_hits(tri[chunk], chunk, px, py, width, height))
        bucket *= 2
    if not found:
        return Coverage(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3)))
    texel, triangle, weights = (np.concatenate(parts) for parts in zip(*found, strict=True))
    return Coverage(texel, triangle, weights)


def st_to_pixels(st: np.ndarray, width: int, height: int) -> np.ndarray:
    """``st`` (v up, as USD has it) → pixel units of an image whose row 0 is its top."""
    st = np.asarray(st, dtype=np.float64)
    return np.stack([st[..., 0] * width, (1.0 - st[..., 1]) * height], axis=-1)


# --------------------------------------------------------------------------- checks


def st_flips(st_values: np.ndarray, split_faces: np.ndarray) -> int:
    """Triangles whose ``st`` winding disagrees with the majority of their chart (a fold).

    Charts are the connected pieces of the seam-split mesh; xatlas may mirror a whole chart,
    so only disagreement *within* a chart counts. Degenerate ``st`` triangles count too.
    """
    tri = st_values[split_faces]
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    sign = np.sign(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    n = len(st_values)
    rows = np.repeat(np.arange(len(split_faces)), 3)
    incidence = coo_matrix((np.ones(rows.size), (rows, split_faces.ravel())), shape=(len(tri), n))
    _, labels = connected_components(incidence.T @ incidence, directed=False)
    chart = labels[split_faces[:, 0]]
    votes = np.bincount(chart, weights=sign)
    majority = np.where(votes[chart] >= 0, 1.0, -1.0)
    return int(np.sum(sign != majority))


def st_overlap_fraction(st_face_varying: np.ndarray, resolution: int = 1024) -> float:
    """Share of covered texels (pixel centres) that more than one ``st`` triangle covers.

    0 for a valid atlas. Orientation is free (xatlas may mirror a chart); a fold inside a
    chart shows up as double coverage.
    """
    tri = st_to_pixels(np.asarray(st_face_varying).reshape(-1, 3, 2), resolution, resolution)
    coverage = np.bincount(rasterise(tri, resolution, resolution).texel)
    return np.count_nonzero(coverage > 1) / max(np.count_nonzero(coverage), 1)


def fill_fraction(st_face_varying: np.ndarray) -> float:
    """Share of the [0, 1]² atlas square that ``st`` triangles cover (by area)."""
    tri = np.asarray(st_face_varying, dtype=np.float64).reshape(-1, 3, 2)
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    return float(np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).sum() / 2.0)
