"""Feather geometry: a vane cut to the alpha silhouette, a rachis tube, an xatlas atlas, regular
refinement carrying every UV, displacement by the displacement map, and decimated LODs.

The spaces and the base surface ``P(u, v)`` are in :mod:`~pavonine.pipeline.convert.surface`;
the coarse pieces in :mod:`~pavonine.pipeline.convert.vane` (cut to the silhouette) and
:mod:`~pavonine.pipeline.convert.rachis` (the shaft); the refinement in
:mod:`~pavonine.pipeline.convert.refinement`; the manifold check in
:mod:`~pavonine.pipeline.convert.topology`. This module assembles them into LODs.

Pipeline (why this order): xatlas' cost grows superlinearly with the triangle count, so the
atlas is computed on a *coarse* base mesh (a few thousand triangles, milliseconds) and carried
exactly through a regular refinement (every coarse triangle split into ``n²`` similar ones,
UVs interpolated linearly inside it, which keeps the atlas free of overlaps). Positions are
then evaluated analytically from the feather-space coordinate, so refinement costs one
vectorised pass. Lower LODs are refined less and decimated by quadric edge collapse
(pymeshlab's, or :mod:`~pavonine.pipeline.convert.collapse` in NumPy when pymeshlab cannot
load: :mod:`~pavonine.pipeline.convert.meshing`) with boundaries (silhouette and atlas seams)
locked and vertices kept in place, so every attribute of a surviving vertex stays exact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from pavonine.base.map_filters import displacement_heights
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
from pavonine.pipeline.convert.collapse import collapse_to
from pavonine.pipeline.convert.meshing import meshing_backend
from pavonine.pipeline.convert.rachis import RachisSpec, base_rachis, rachis_positions
from pavonine.pipeline.convert.refinement import RefinedMesh, refine, subdivision_for
from pavonine.pipeline.convert.surface import FeatherFrame, normalise, vertex_normals
from pavonine.pipeline.convert.topology import edge_report
from pavonine.pipeline.convert.vane import base_vane, triangle_areas


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
    heights = displacement_heights(geo.displacement, uv, geo.displacement_cm, spacing)
    base = frame.position(uv)
    normal = frame.normal(uv)
    points = base + heights[:, None] * normal
    normals = vertex_normals(points, refined.faces)
    outward = away_from_rachis(uv, frame.aspect, geo.rachis.top)
    direction = sample_direction(geo.barb_field, uv, outward)
    dpdu, dpdv = frame.derivatives(uv)
    # Field vectors are in square feather units (v = 1 ↔ length): dv/du scale = aspect.
    tangent = dpdu * (direction[:, :1] / frame.aspect) + dpdv * direction[:, 1:2]
    tangent = normalise(tangent - np.sum(tangent * normals, axis=1, keepdims=True) * normals)
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
    tangent = normalise(tangent - np.sum(tangent * normals, axis=1, keepdims=True) * normals)
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
    """Quadric edge collapse (:func:`quadric_collapse`) to ``target`` triangles, keeping every
    UV exact: the mesh is collapsed split along its atlas seams, so seams and the silhouette are
    locked boundaries, and surviving vertices keep their source index, so feather UV, ``st``,
    height and barb tangent are copied, not re-interpolated.
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
    new_split_faces = quadric_collapse(mesh.points[split_welded], split_faces, split_st, target)
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
    tangent = normalise(tangent - np.sum(tangent * normals, axis=1, keepdims=True) * normals)
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


def quadric_collapse(
    points: np.ndarray, faces: np.ndarray, st: np.ndarray, target: int
) -> np.ndarray:
    """``faces`` decimated to about ``target`` triangles by half-edge quadric collapse with the
    boundary locked, as indices into ``points`` (which keep their places).

    pymeshlab when it loads: ``preserveboundary`` locks the boundary; ``optimalplacement=False``
    keeps each surviving vertex where it was; ``autoclean=False`` because its clean-up merges
    the coincident vertices on either side of a seam, joining two charts (their ``st`` folds);
    a vertex's index rides along as a custom attribute. Otherwise
    :func:`~pavonine.pipeline.convert.collapse.collapse_to`, the same in NumPy, which also
    refuses collapses that fold ``st``.
    """
    backend = meshing_backend()
    if backend.name == "numpy":
        return collapse_to(points, faces, st, target)
    pymeshlab = backend.pymeshlab
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(points, faces.astype(np.int32)), set_as_current=True)
    ms.current_mesh().add_vertex_custom_scalar_attribute(
        np.arange(len(points), dtype=np.float64), "source"
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
    return source[out.face_matrix().astype(np.int64)]
