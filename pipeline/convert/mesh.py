"""Feather geometry: a vane cut to the alpha silhouette, a rachis tube, an xatlas atlas, regular
refinement carrying every UV, displacement by the displacement map, and decimated LODs.

Spaces
------
*Feather space* ``(u, v) ∈ [0, 1]²`` is the space the maps are read in: ``u`` left → right
across the image, ``v`` from the image's bottom row (the feather's base) to its top row (the
apex); see :func:`pavonine.pipeline.maps.io.sample_bilinear`. *Object space* is centimetres,
Y up along the feather, X across it, the iridescent front facing +Z:

    P(u, v) = ((u - ½) W,  v L,  -bend · max(v, 0)² - cup · (2u - 1)²)

with ``L`` the mapped length and ``W = L · aspect`` (pixels are square). The displaced vane is
``P + h · d(u, v) · n(u, v)``, ``d`` the displacement map and ``h`` the displacement height.

Pipeline (why this order): xatlas' cost grows superlinearly with the triangle count, so the
atlas is computed on a *coarse* base mesh (a few thousand triangles, milliseconds) and carried
exactly through a regular refinement (every coarse triangle split into ``n²`` similar ones,
UVs interpolated linearly inside it, which keeps the atlas free of overlaps). Positions are
then evaluated analytically from the feather-space coordinate, so refinement costs one
vectorised pass. Lower LODs are refined less and decimated by pymeshlab's quadric edge
collapse with boundaries (silhouette and atlas seams) locked and vertices kept in place, so
every attribute of a surviving vertex stays exact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pymeshlab
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from pavonine.pipeline.convert.atlas import (
    AtlasedMesh,
    build_atlas,
    chart_pieces,
    cut_edges,
    piece_count,
    st_flips,
)
from pavonine.pipeline.convert.barbs import (
    away_from_rachis,
    barb_direction_field,
    sample_direction,
)
from pavonine.pipeline.maps.io import area_reduce, sample_bilinear

#: Smallest fraction of an edge at which the silhouette may cut it (keeps triangles fat).
_CUT_CLAMP = 0.15


@dataclass
class FeatherFrame:
    """The base surface ``P(u, v)`` (module docstring) with its dimensions in centimetres."""

    length: float
    aspect: float
    bend: float
    cup: float

    @property
    def width(self) -> float:
        return self.length * self.aspect

    def position(self, uv: np.ndarray) -> np.ndarray:
        u, v = uv[:, 0], uv[:, 1]
        x = (u - 0.5) * self.width
        y = v * self.length
        z = -self.bend * np.maximum(v, 0.0) ** 2 - self.cup * (2.0 * u - 1.0) ** 2
        return np.stack([x, y, z], axis=1)

    def derivatives(self, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(∂P/∂u, ∂P/∂v)`` at each feather-space point."""
        u, v = uv[:, 0], uv[:, 1]
        dpdu = np.zeros((len(uv), 3))
        dpdu[:, 0] = self.width
        dpdu[:, 2] = -4.0 * self.cup * (2.0 * u - 1.0)
        dpdv = np.zeros((len(uv), 3))
        dpdv[:, 1] = self.length
        dpdv[:, 2] = -2.0 * self.bend * np.maximum(v, 0.0)
        return dpdu, dpdv

    def normal(self, uv: np.ndarray) -> np.ndarray:
        dpdu, dpdv = self.derivatives(uv)
        return _normalise(np.cross(dpdu, dpdv))


def _normalise(vectors: np.ndarray) -> np.ndarray:
    norms = np.linalg.norm(vectors, axis=1, keepdims=True)
    return vectors / np.where(norms > 0, norms, 1.0)


# --------------------------------------------------------------------------- base vane


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


def compact(points: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Drop unreferenced vertices and renumber."""
    used = np.zeros(len(points), dtype=bool)
    used[faces.ravel()] = True
    remap = np.cumsum(used) - 1
    return points[used], remap[faces]


def triangle_areas(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area of each triangle (2-D points give signed areas, counter-clockwise positive)."""
    a, b, c = points[faces[:, 0]], points[faces[:, 1]], points[faces[:, 2]]
    if points.shape[1] == 2:
        e1, e2 = b - a, c - a
        return 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)


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


def pymeshlab_clean(uv: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Meshlab's cleaning filters on the flat feather-space mesh (positions = (u, v, 0)).

    Merges duplicate vertices, removes null faces and unreferenced vertices and repairs any
    non-manifold edge or vertex. Working in feather space keeps the coordinate recoverable.
    """
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
    for _ in range(3):  # the first pitch is an estimate; correct it by the count it gave
        rows = max(4, round(pitch)) + 1
        cols = max(4, round((rows - 1) * aspect)) + 1
        factor = max(1, int(height / (rows - 1) / 2))
        filtered = area_reduce(alpha, factor)
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
    return pymeshlab_clean(uv, faces)


# --------------------------------------------------------------------------- rachis


@dataclass
class RachisSpec:
    """The shaft: from ``-calamus`` below the vane to ``top`` (feather-space v), tapering."""

    calamus_cm: float
    top: float
    radius_cm: float
    tip_radius_cm: float


def _rachis_centre(frame: FeatherFrame, s: np.ndarray, lift: np.ndarray) -> np.ndarray:
    uv = np.column_stack([np.full_like(s, 0.5), s])
    return frame.position(uv) + lift[:, None] * frame.normal(uv)


def _rachis_radius(spec: RachisSpec, frame: FeatherFrame, s: np.ndarray) -> np.ndarray:
    bottom = -spec.calamus_cm / frame.length
    t = np.clip((s - bottom) / (spec.top - bottom), 0.0, 1.0)
    return spec.radius_cm + (spec.tip_radius_cm - spec.radius_cm) * t**0.7


def base_rachis(
    spec: RachisSpec, frame: FeatherFrame, rings: int = 48, sides: int = 8
) -> tuple[np.ndarray, np.ndarray]:
    """Coarse rachis tube with conical end caps as *tube coordinates* ``(s, cos φ, sin φ, w)``.

    ``s`` is the feather-space ``v`` along the shaft, ``φ`` the angle around it and ``w`` the
    share of the radius (1 on the tube, 0 at the end-cap apexes). :func:`rachis_positions`
    turns linearly interpolated tube coordinates into points.
    """
    bottom = -spec.calamus_cm / frame.length
    s = np.linspace(bottom, spec.top, rings)
    phi = 2 * np.pi * np.arange(sides) / sides
    ss, pp = np.meshgrid(s, phi, indexing="ij")
    coords = np.column_stack([ss.ravel(), np.cos(pp).ravel(), np.sin(pp).ravel(), np.ones(ss.size)])
    idx = np.arange(rings * sides).reshape(rings, sides)
    nxt = np.roll(idx, -1, axis=1)
    a, b, c, d = idx[:-1], nxt[:-1], nxt[1:], idx[1:]
    faces = np.concatenate(
        [np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)]
    )
    cap_len = 0.6 * spec.radius_cm / frame.length
    tip_len = 1.5 * spec.tip_radius_cm / frame.length
    apex = np.array([[bottom - cap_len, 0.0, 0.0, 0.0], [spec.top + tip_len, 0.0, 0.0, 0.0]])
    base_apex, top_apex = len(coords), len(coords) + 1
    ring0, ring1 = idx[0], idx[-1]
    cap0 = np.stack([np.full(sides, base_apex), np.roll(ring0, -1), ring0], -1)
    cap1 = np.stack([np.full(sides, top_apex), ring1, np.roll(ring1, -1)], -1)
    return np.concatenate([coords, apex]), np.concatenate([faces, cap0, cap1])


def rachis_positions(
    spec: RachisSpec, frame: FeatherFrame, coords: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Object-space points and the shaft direction of tube coordinates (:func:`base_rachis`);
    the interpolated direction around the shaft is renormalised so the tube stays round."""
    s = coords[:, 0]
    ring = coords[:, 1:3]
    norm = np.linalg.norm(ring, axis=1)
    ring = ring / np.where(norm > 1e-12, norm, 1.0)[:, None]
    bottom = -spec.calamus_cm / frame.length
    s_in = np.clip(s, bottom, spec.top)
    radius = _rachis_radius(spec, frame, s_in) * np.clip(coords[:, 3], 0.0, 1.0)
    lift = 0.35 * _rachis_radius(spec, frame, s_in)
    centre = _rachis_centre(frame, s, lift)
    ds = 1e-4
    tangent = _normalise(_rachis_centre(frame, s + ds, lift) - _rachis_centre(frame, s - ds, lift))
    e1 = np.tile(np.array([1.0, 0.0, 0.0]), (len(s), 1))
    e2 = _normalise(np.cross(tangent, e1))
    e1 = np.cross(e2, tangent)
    points = centre + radius[:, None] * (ring[:, :1] * e1 + ring[:, 1:2] * e2)
    return points, tangent


# --------------------------------------------------------------------------- refinement


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


# --------------------------------------------------------------------------- surface fields


def vertex_normals(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals (unit length)."""
    a, b, c = points[faces[:, 0]], points[faces[:, 1]], points[faces[:, 2]]
    face_normals = np.cross(b - a, c - a)  # length = 2·area: area weighting
    normals = np.zeros_like(points)
    for k in range(3):
        for axis in range(3):
            normals[:, axis] += np.bincount(
                faces[:, k], weights=face_normals[:, axis], minlength=len(points)
            )
    return _normalise(normals)


def prefilter(values: np.ndarray, spacing_uv: float) -> np.ndarray:
    """Low-pass a map to a mesh whose vertices are ``spacing_uv`` (feather v units) apart,
    so displacement sampled at vertices does not alias (Gaussian, σ = ½ vertex spacing)."""
    sigma = 0.5 * spacing_uv * values.shape[0]
    if sigma < 0.5:
        return values
    return ndimage.gaussian_filter(values, sigma, mode="nearest")


# --------------------------------------------------------------------------- assembly


@dataclass
class MeshData:
    """One mesh ready to write: welded points/faces and per-vertex / face-varying data."""

    name: str
    points: np.ndarray  # (n, 3) cm
    faces: np.ndarray  # (m, 3) welded indices, counter-clockwise seen from the front
    normals: np.ndarray  # (n, 3)
    feather_uv: np.ndarray  # (n, 2)
    barb_tangent: np.ndarray  # (n, 3)
    st_values: np.ndarray  # (k, 2) atlas coordinates
    st_indices: np.ndarray  # (m·3,) face-varying index into st_values
    height: np.ndarray | None = None  # (n,) displacement height above the base surface, cm

    @property
    def st(self) -> np.ndarray:
        """Face-varying ``st`` (one row per face corner)."""
        return self.st_values[self.st_indices]

    @property
    def triangle_count(self) -> int:
        return len(self.faces)

    def extent(self) -> np.ndarray:
        return np.stack([self.points.min(axis=0), self.points.max(axis=0)])


@dataclass
class FeatherGeometry:
    """Inputs shared by every LOD: frame, rachis, atlased coarse meshes and sampled fields."""

    frame: FeatherFrame
    rachis: RachisSpec
    vane: AtlasedMesh
    rachis_mesh: AtlasedMesh
    displacement: np.ndarray
    barb_field: np.ndarray
    displacement_cm: float
    chart_count: int
    timings: dict[str, float] = field(default_factory=dict)


def build_base(
    alpha: np.ndarray,
    displacement: np.ndarray,
    frame: FeatherFrame,
    rachis: RachisSpec,
    displacement_cm: float,
    threshold: float,
    base_triangles: int,
    rachis_triangles: int = 200,
    low_triangles: int | None = None,
) -> tuple[FeatherGeometry, float]:
    """Coarse vane + rachis, atlased together. Returns the geometry and the atlas time (s).

    ``rachis_triangles``: the coarse rachis' budget (the lowest LOD's share), 6 sides around.
    ``low_triangles``: the lowest LOD's target, which bounds how many pieces the vane is cut
    into for the atlas (:func:`vane_piece_count`).
    """
    import time

    uv, faces = base_vane(alpha, threshold, base_triangles)
    vane_points = frame.position(uv)
    sides = 6
    rings = int(np.clip(round(rachis_triangles / (2 * sides)), 4, 48))
    coords, rachis_faces = base_rachis(rachis, frame, rings=rings, sides=sides)
    rachis_points, _ = rachis_positions(rachis, frame, coords)
    width = float(np.ptp(vane_points[:, 0]))
    low_vane = (1.0 - RACHIS_SHARE) * (low_triangles or len(faces))
    pieces = [
        chart_pieces(uv[:, 1], faces, vane_piece_count(uv, faces, vane_points, low_vane)),
        chart_pieces(
            coords[:, 0], rachis_faces, piece_count(float(np.ptp(rachis_points[:, 1])), width)
        ),
    ]
    start = time.perf_counter()
    (vane, rachis_mesh), charts = build_atlas(
        [(vane_points, faces, uv), (rachis_points, rachis_faces, coords)], pieces=pieces
    )
    atlas_seconds = time.perf_counter() - start
    barb = barb_direction_field(displacement)
    geometry = FeatherGeometry(
        frame, rachis, vane, rachis_mesh, displacement, barb, displacement_cm, charts
    )
    return geometry, atlas_seconds


#: Boundary vertices (silhouette and seams, all locked by decimation) the lowest LOD's vane may
#: have, as a share of its triangle target: quadric collapse with a locked boundary cannot go
#: much below one triangle per boundary vertex without folding the atlas.
LOW_LOD_BOUNDARY_SHARE = 0.5


def vane_piece_count(
    uv: np.ndarray, faces: np.ndarray, points: np.ndarray, low_vane_triangles: float
) -> int:
    """Bands the coarse vane is cut into for the atlas: as many as :func:`piece_count` asks
    for (pieces no longer than half the vane's width), but no more than keep the lowest LOD's
    boundary (silhouette + both sides of every seam, multiplied by its refinement) within
    ``LOW_LOD_BOUNDARY_SHARE`` of its target."""
    wanted = piece_count(float(np.ptp(points[:, 1])), float(np.ptp(points[:, 0])))
    refinement = subdivision_for(len(faces), 2.0 * low_vane_triangles)
    for count in range(wanted, 1, -1):
        silhouette, seams = cut_edges(faces, chart_pieces(uv[:, 1], faces, count))
        if (silhouette + 2 * seams) * refinement <= LOW_LOD_BOUNDARY_SHARE * low_vane_triangles:
            return count
    return 1


def _vane_mesh(geo: FeatherGeometry, refined: RefinedMesh, spacing: float) -> MeshData:
    frame = geo.frame
    uv = np.clip(refined.attributes, 0.0, 1.0)
    heights = geo.displacement_cm * sample_bilinear(prefilter(geo.displacement, spacing), uv)
    base = frame.position(uv)
    normal = frame.normal(uv)
    points = base + heights[:, None] * normal
    normals = vertex_normals(points, refined.faces)
    outward = away_from_rachis(uv, frame.aspect, geo.rachis.top)
    direction = sample_direction(geo.barb_field, uv, outward)
    dpdu, dpdv = frame.derivatives(uv)
    # Field vectors are in square feather units (v = 1 ↔ length): dv/du scale = aspect.
    tangent = dpdu * (direction[:, :1] / frame.aspect) + dpdv * direction[:, 1:2]
    tangent = _normalise(tangent - np.sum(tangent * normals, axis=1, keepdims=True) * normals)
    return MeshData(
        "Vane",
        points,
        refined.faces,
        normals,
        uv,
        tangent,
        refined.st,
        refined.split_faces.ravel(),
        heights.astype(np.float64),
    )


def _rachis_mesh(geo: FeatherGeometry, refined: RefinedMesh) -> MeshData:
    coords = refined.attributes
    points, tangent = rachis_positions(geo.rachis, geo.frame, coords)
    normals = vertex_normals(points, refined.faces)
    feather_uv = np.column_stack([np.full(len(coords), 0.5), np.clip(coords[:, 0], 0.0, 1.0)])
    tangent = _normalise(tangent - np.sum(tangent * normals, axis=1, keepdims=True) * normals)
    return MeshData(
        "Rachis",
        points,
        refined.faces,
        normals,
        feather_uv,
        tangent,
        refined.st,
        refined.split_faces.ravel(),
    )


#: Share of each LOD's triangle budget spent on the rachis.
RACHIS_SHARE = 0.04


def _spacing(geo: FeatherGeometry, n: int) -> float:
    """Mean vertex spacing of the vane refined ``n`` ways, in feather-v units."""
    area = np.abs(triangle_areas(geo.vane.attributes * [geo.frame.aspect, 1.0], geo.vane.faces))
    return math.sqrt(2.0 * area.mean()) / n


def build_lod(geo: FeatherGeometry, target: int, decimate: bool) -> list[MeshData]:
    """Vane and rachis meshes with about ``target`` triangles in total.

    ``decimate=False``: regular refinement to the target. ``decimate=True``: the vane is refined
    to about twice the target, then quadric edge collapse brings it down (see
    :func:`decimate_mesh`), spending triangles where the barb streaks are. The rachis, a
    smooth tube with no detail to keep, is always regularly refined (at least its coarse mesh).
    """
    factor = 2.0 if decimate else 1.0
    vane_target = (1.0 - RACHIS_SHARE) * target
    rachis_target = RACHIS_SHARE * target
    n_vane = subdivision_for(len(geo.vane.faces), factor * vane_target)
    n_rachis = subdivision_for(len(geo.rachis_mesh.faces), rachis_target)
    vane = _vane_mesh(geo, refine(geo.vane, n_vane), _spacing(geo, n_vane))
    rachis = _rachis_mesh(geo, refine(geo.rachis_mesh, n_rachis))
    if decimate:
        decimated = decimate_towards(vane, round(vane_target))
        if decimated is None:  # every collapse folded the atlas: fall back to plain refinement
            n_vane = subdivision_for(len(geo.vane.faces), vane_target)
            decimated = _vane_mesh(geo, refine(geo.vane, n_vane), _spacing(geo, n_vane))
        vane = decimated
    return [vane, rachis]


def decimate_towards(mesh: MeshData, target: int) -> MeshData | None:
    """:func:`decimate_mesh` to ``target``; when that folds the atlas, halve the count step by
    step instead and keep the last step that did not (the closest valid mesh above the
    target). ``None`` when not even the first halving is valid."""
    direct = decimate_mesh(mesh, target)
    if direct is not None or mesh.triangle_count <= target:
        return direct
    best = None
    current = mesh
    while current.triangle_count > target:
        step = decimate_mesh(current, max(target, current.triangle_count // 2))
        if step is None or step.triangle_count >= current.triangle_count:
            break
        best = current = step
    return best


def decimate_mesh(mesh: MeshData, target: int) -> MeshData | None:
    """Quadric edge collapse (pymeshlab) to ``target`` triangles, keeping every UV exact.

    The mesh is handed to meshlab split along its atlas seams, so seams and the silhouette
    are boundaries, which ``preserveboundary`` locks; ``optimalplacement=False`` keeps each
    surviving vertex where it was; ``autoclean=False`` because its clean-up merges the
    coincident vertices on either side of a seam, joining two charts (their ``st`` folds). A
    vertex's source index rides along as a custom attribute, so feather UV, ``st``, height and
    barb tangent are copied, not re-interpolated.
    Returns ``None`` when the result would fold the atlas (a triangle flipped in ``st``
    against the rest of its chart).
    """
    if target >= mesh.triangle_count:
        return mesh
    # Split vertices (one per distinct st value); each belongs to one welded vertex.
    split_faces = mesh.st_indices.reshape(-1, 3)
    split_welded = np.zeros(len(mesh.st_values), dtype=np.int64)
    split_welded[mesh.st_indices] = mesh.faces.ravel()
    split_st = mesh.st_values
    ms = pymeshlab.MeshSet()
    ms.add_mesh(
        pymeshlab.Mesh(mesh.points[split_welded], split_faces.astype(np.int32)),
        set_as_current=True,
    )
    ms.current_mesh().add_vertex_custom_scalar_attribute(
        np.arange(len(split_welded), dtype=np.float64), "source"
    )
    ms.meshing_decimation_quadric_edge_collapse(
        targetfacenum=int(target),
        preserveboundary=True,
        boundaryweight=2.0,
        optimalplacement=False,
        preservenormal=True,
        preservetopology=True,
        planarquadric=True,
        qualitythr=0.3,
        autoclean=False,
    )
    out = ms.current_mesh()
    source = np.rint(out.vertex_custom_scalar_attribute_array("source")).astype(np.int64)
    new_split_faces = source[out.face_matrix().astype(np.int64)]
    welded_faces_old = split_welded[new_split_faces]
    # Collapses along a locked straight boundary can leave a triangle whose corners are
    # collinear in st (a zero-width sliver on the edge of a chart): drop those, then insist
    # on an unfolded atlas and a manifold mesh, else give up (the caller refines instead).
    tri = split_st[new_split_faces]
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    st_area = np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    sliver = st_area <= 1e-9 * np.median(st_area)
    if sliver.any():
        new_split_faces = new_split_faces[~sliver]
        welded_faces_old = welded_faces_old[~sliver]
        report = edge_report(welded_faces_old, len(mesh.points))
        if any(report.values()):
            return None
    if st_flips(split_st, new_split_faces) > 0:
        return None
    kept_split, st_indices = np.unique(new_split_faces.ravel(), return_inverse=True)
    kept, welded_faces = np.unique(welded_faces_old.ravel(), return_inverse=True)
    welded_faces = welded_faces.reshape(-1, 3)
    points = mesh.points[kept]
    normals = vertex_normals(points, welded_faces)
    tangent = mesh.barb_tangent[kept]
    tangent = _normalise(tangent - np.sum(tangent * normals, axis=1, keepdims=True) * normals)
    return MeshData(
        mesh.name,
        points,
        welded_faces,
        normals,
        mesh.feather_uv[kept],
        tangent,
        split_st[kept_split],
        st_indices,
        None if mesh.height is None else mesh.height[kept],
    )


# --------------------------------------------------------------------------- checks


def edge_report(faces: np.ndarray, n_vertices: int) -> dict[str, int]:
    """Topology check: non-manifold edges (> 2 faces), inconsistently oriented edges and
    non-manifold vertices (a vertex whose faces form more than one fan)."""
    faces = np.asarray(faces, dtype=np.int64)
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    lo, hi = directed.min(axis=1), directed.max(axis=1)
    key = lo * n_vertices + hi
    _, counts = np.unique(key, return_counts=True)
    directed_key = directed[:, 0] * n_vertices + directed[:, 1]
    _, dcounts = np.unique(directed_key, return_counts=True)
    # Fans: faces around a vertex connected through shared edges incident to the vertex.
    corner_v = faces.ravel()
    nxt = faces[:, [1, 2, 0]].ravel()
    prv = faces[:, [2, 0, 1]].ravel()
    # Each corner links (v, nxt) and (v, prv) "spokes"; corners sharing a spoke are linked.
    spoke_a = corner_v * n_vertices + nxt
    spoke_b = corner_v * n_vertices + prv
    spokes = np.concatenate([spoke_a, spoke_b])
    corners = np.concatenate([np.arange(len(corner_v)), np.arange(len(corner_v))])
    order = np.argsort(spokes, kind="stable")
    s_sorted, c_sorted = spokes[order], corners[order]
    same = s_sorted[1:] == s_sorted[:-1]
    links = (c_sorted[:-1][same], c_sorted[1:][same])
    n_corners = len(corner_v)
    graph = coo_matrix((np.ones(len(links[0])), links), shape=(n_corners, n_corners))
    _, labels = connected_components(graph, directed=False)
    fans_per_vertex = np.bincount(
        np.unique(np.column_stack([corner_v, labels]), axis=0)[:, 0], minlength=n_vertices
    )
    return {
        "non_manifold_edges": int(np.sum(counts > 2)),
        "misoriented_edges": int(np.sum(dcounts > 1)),
        "non_manifold_vertices": int(np.sum(fans_per_vertex > 1)),
    }
