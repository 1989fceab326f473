"""``UsdGeom.Mesh`` → Mitsuba triangle meshes.

Reads points, ``faceVertexCounts/Indices``, normals and uv primvars of any interpolation
(constant, uniform, vertex, varying, faceVarying, indexed or not), triangulates polygons as fans,
splits by ``GeomSubset`` material bindings, and builds one ``mi.Mesh`` per material. When every
primvar is per-vertex the mesh keeps its shared vertices; otherwise corners are unwelded.

Bad data renders what it can: faces that use non-finite points or out-of-range indices are dropped
with one warning naming the prim; an empty mesh is skipped with a warning.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from pxr import Usd, UsdGeom, UsdShade

from pavonine.render.diagnostics import Diagnostics
from pavonine.render.xform import (
    flips_handedness,
    normalize,
    transform_directions,
    transform_normals,
    transform_points,
)

PER_VERTEX = ("vertex", "varying")


@dataclass
class Topology:
    """A mesh's polygons after validation, as triangles over face-vertex corners."""

    points: np.ndarray  # (P, 3) float64, object space
    face_vertex_indices: np.ndarray  # (C,) int64, one per corner
    triangles: np.ndarray  # (T, 3) corner indices
    triangle_face: np.ndarray  # (T,) polygon index of each triangle
    face_count: int


@dataclass
class Primvar:
    """A primvar's flattened values with their interpolation."""

    values: np.ndarray
    interpolation: str


@dataclass
class TriangleMesh:
    """A triangle mesh ready for Mitsuba (world or prototype space)."""

    name: str
    positions: np.ndarray  # (V, 3) float32
    faces: np.ndarray  # (F, 3) uint32
    normals: np.ndarray | None = None
    texcoords: np.ndarray | None = None
    attributes: dict[str, np.ndarray] = field(default_factory=dict)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self.positions.min(axis=0), self.positions.max(axis=0)

    def area(self) -> float:
        """Total triangle area, in the units of ``positions`` squared."""
        p = self.positions.astype(np.float64)[self.faces]
        return float(
            0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum()
        )


def read_topology(mesh: UsdGeom.Mesh, time: Usd.TimeCode, diag: Diagnostics) -> Topology | None:
    """Validated topology; ``None`` (with a warning) when nothing renderable remains."""
    where = str(mesh.GetPath())
    points = mesh.GetPointsAttr().Get(time)
    counts = mesh.GetFaceVertexCountsAttr().Get(time)
    indices = mesh.GetFaceVertexIndicesAttr().Get(time)
    if points is None or counts is None or indices is None or len(points) == 0 or len(counts) == 0:
        diag.warn(where, "empty mesh (no points or faces); skipped")
        return None
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    counts = np.asarray(counts, dtype=np.int64)
    indices = np.asarray(indices, dtype=np.int64)
    if counts.sum() != len(indices) or np.any(counts < 0):
        diag.warn(
            where,
            f"faceVertexCounts sum to {counts.sum()} but there are {len(indices)} indices; skipped",
        )
        return None
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    polygon = counts >= 3
    fan = np.where(polygon, counts - 2, 0)
    triangle_face = np.repeat(np.arange(len(counts)), fan)
    k = np.arange(len(triangle_face)) - np.repeat(np.cumsum(fan) - fan, fan)
    first = starts[triangle_face]
    triangles = np.stack([first, first + k + 1, first + k + 2], axis=1)
    if mesh.GetOrientationAttr().Get(time) == UsdGeom.Tokens.leftHanded:
        triangles = triangles[:, [0, 2, 1]]

    bad_index = (indices < 0) | (indices >= len(points))
    finite = np.all(np.isfinite(points), axis=1)
    bad_point = np.zeros(len(indices), dtype=bool)
    bad_point[~bad_index] = ~finite[indices[~bad_index]]
    drop = np.any((bad_index | bad_point)[triangles], axis=1)
    if np.any(bad_index):
        diag.warn(
            where, f"{int(bad_index.sum())} face-vertex indices out of range; their faces dropped"
        )
    if not finite.all():
        diag.warn(
            where,
            f"{int((~finite).sum())} of {len(points)} points are NaN or infinite; "
            f"{len(np.unique(triangle_face[drop]))} faces using them dropped",
        )
    triangles, triangle_face = triangles[~drop], triangle_face[~drop]
    if len(triangles) == 0:
        diag.warn(where, "no renderable faces remain; skipped")
        return None
    safe_indices = np.where(bad_index, 0, indices)
    return Topology(points, safe_indices, triangles, triangle_face, len(counts))


def read_primvar(mesh: UsdGeom.Mesh, name: str, time: Usd.TimeCode) -> Primvar | None:
    """A primvar flattened (indexed primvars expanded), or ``None`` if absent."""
    primvar = UsdGeom.PrimvarsAPI(mesh.GetPrim()).GetPrimvar(name)
    if not primvar or not primvar.HasValue():
        return None
    values = primvar.ComputeFlattened(time)
    if values is None or len(values) == 0:
        return None
    return Primvar(np.asarray(values, dtype=np.float64), str(primvar.GetInterpolation()))


def read_normals(mesh: UsdGeom.Mesh, time: Usd.TimeCode) -> Primvar | None:
    """``primvars:normals`` if authored, else the ``normals`` attribute with its interpolation."""
    normals = read_primvar(mesh, "normals", time)
    if normals is not None:
        return normals
    values = mesh.GetNormalsAttr().Get(time)
    if values is None or len(values) == 0:
        return None
    return Primvar(np.asarray(values, dtype=np.float64), str(mesh.GetNormalsInterpolation()))


def smooth_normals(topology: Topology) -> Primvar:
    """Area-weighted vertex normals (for subdivision surfaces authored without normals)."""
    p = topology.points
    corner_points = topology.face_vertex_indices[topology.triangles]
    a, b, c = (p[corner_points[:, i]] for i in range(3))
    face_normals = np.cross(b - a, c - a)
    normals = np.zeros_like(p)
    for i in range(3):
        np.add.at(normals, corner_points[:, i], face_normals)
    return Primvar(normals, "vertex")


def per_corner(
    primvar: Primvar, topology: Topology, where: str, name: str, diag: Diagnostics
) -> np.ndarray | None:
    """Primvar values for every face-vertex corner, whatever its interpolation."""
    values, interpolation = primvar.values, primvar.interpolation
    n_corners = len(topology.face_vertex_indices)
    if interpolation == "constant":
        return np.repeat(values[:1], n_corners, axis=0)
    if interpolation == "uniform":
        if len(values) < topology.face_count:
            diag.warn(
                where,
                f"uniform primvar {name} has {len(values)} values for {topology.face_count} faces; ignored",
            )
            return None
        corner_face = np.zeros(n_corners, dtype=np.int64)
        corner_face[topology.triangles.ravel()] = np.repeat(topology.triangle_face, 3)
        return values[corner_face]
    if interpolation in PER_VERTEX:
        if len(values) < len(topology.points):
            diag.warn(
                where,
                f"{interpolation} primvar {name} has {len(values)} values for {len(topology.points)} points; ignored",
            )
            return None
        return values[topology.face_vertex_indices]
    if interpolation == "faceVarying":
        if len(values) < n_corners:
            diag.warn(
                where,
                f"faceVarying primvar {name} has {len(values)} values for {n_corners} face-vertices; ignored",
            )
            return None
        return values[:n_corners]
    diag.warn(where, f"primvar {name} has unknown interpolation {interpolation!r}; ignored")
    return None


def material_groups(
    mesh: UsdGeom.Mesh, topology: Topology, time: Usd.TimeCode, diag: Diagnostics
) -> list[tuple[UsdShade.Material | None, np.ndarray]]:
    """``(bound material, triangle mask)`` per ``GeomSubset`` (familyName materialBind) and the rest."""
    prim = mesh.GetPrim()
    binding = UsdShade.MaterialBindingAPI(prim)
    remaining = np.ones(len(topology.triangles), dtype=bool)
    groups: list[tuple[UsdShade.Material | None, np.ndarray]] = []
    for subset in binding.GetMaterialBindSubsets():
        faces = subset.GetIndicesAttr().Get(time)
        if faces is None or len(faces) == 0:
            continue
        faces = np.asarray(faces, dtype=np.int64)
        selected = np.isin(topology.triangle_face, faces) & remaining
        remaining &= ~selected
        material = UsdShade.MaterialBindingAPI(subset.GetPrim()).ComputeBoundMaterial()[0]
        groups.append((material if material else None, selected))
    material = binding.ComputeBoundMaterial()[0]
    groups.append((material if material else None, remaining))
    return [(m, mask) for m, mask in groups if mask.any()]


def build_triangle_mesh(
    mesh: UsdGeom.Mesh,
    topology: Topology,
    triangle_mask: np.ndarray,
    matrix_usd: np.ndarray,
    uv_primvar: str,
    attributes: dict[str, str],
    time: Usd.TimeCode,
    diag: Diagnostics,
    name: str,
    primvars: Sequence[str] = (),
) -> TriangleMesh:
    """One material's triangles with positions/normals/uvs/attributes transformed by ``matrix_usd``.

    ``primvars``: primvars the material reads per mesh; the non-constant ones become Mitsuba
    attributes as authored (see ``shading.primvars.mesh_attributes``).
    """
    where = str(mesh.GetPath())
    normals = read_normals(mesh, time)
    if normals is None and mesh.GetSubdivisionSchemeAttr().Get(time) != UsdGeom.Tokens.none:
        normals = smooth_normals(topology)
    uv = read_primvar(mesh, uv_primvar, time)
    if uv is None and uv_primvar != "st":
        diag.warn(where, f"primvar {uv_primvar} not found; using st for texture coordinates")
        uv = read_primvar(mesh, "st", time)
    extra = {mi_name: read_primvar(mesh, primvar, time) for primvar, mi_name in attributes.items()}
    extra = {k: v for k, v in extra.items() if v is not None}

    plain = {n: pv for n in primvars if (pv := read_primvar(mesh, n, time)) is not None}
    plain = {n: pv for n, pv in plain.items() if pv.interpolation != UsdGeom.Tokens.constant}
    per_face = UsdGeom.Tokens.uniform
    varying = [
        normals,
        uv,
        *extra.values(),
        *(p for p in plain.values() if p.interpolation != per_face),
    ]
    welded = all(pv is None or pv.interpolation in (*PER_VERTEX, "constant") for pv in varying)
    triangles = topology.triangles[triangle_mask]
    if welded:
        vertex_of_corner = topology.face_vertex_indices
    else:
        vertex_of_corner = np.arange(len(topology.face_vertex_indices))
    used, faces = np.unique(vertex_of_corner[triangles], return_inverse=True)
    faces = faces.reshape(-1, 3)
    # one representative corner per output vertex
    corner_of_vertex = np.empty(len(used), dtype=np.int64)
    corner_of_vertex[faces.ravel()] = triangles.ravel()

    positions = transform_points(
        topology.points[topology.face_vertex_indices[corner_of_vertex]], matrix_usd
    )
    if flips_handedness(matrix_usd):
        faces = faces[:, [0, 2, 1]]
    out = TriangleMesh(name, positions.astype(np.float32), faces.astype(np.uint32))

    def corner_values(primvar: Primvar, label: str) -> np.ndarray | None:
        values = per_corner(primvar, topology, where, label, diag)
        return None if values is None else values[corner_of_vertex]

    if normals is not None:
        n = corner_values(normals, "normals")
        if n is not None:
            n = transform_normals(np.nan_to_num(n, nan=0.0, posinf=0.0, neginf=0.0), matrix_usd)
            bad = np.linalg.norm(n, axis=1) < 0.5  # zero, NaN or infinite as authored
            if np.any(bad):
                diag.warn(
                    where,
                    f"{int(bad.sum())} of {len(n)} normals are zero, NaN or infinite; "
                    "face normals used for those",
                )
                n[bad] = face_normals_at_vertices(out.positions, out.faces)[bad]
            out.normals = n.astype(np.float32)
    if uv is not None:
        t = corner_values(uv, uv_primvar)
        if t is not None and t.shape[1] >= 2 and np.all(np.isfinite(t)):
            # USD's st has v up; Mitsuba's bitmap rows start at the top (as its OBJ/PLY loaders do).
            out.texcoords = np.stack([t[:, 0], 1.0 - t[:, 1]], axis=1).astype(np.float32)
    out.attributes = {}
    for mi_name, primvar in extra.items():
        values = corner_values(primvar, mi_name)
        if values is not None and values.shape[1] == 3:
            out.attributes[mi_name] = transform_directions(values, matrix_usd).astype(np.float32)
    if plain:
        from pavonine.render.shading.primvars import mesh_attributes

        out.attributes.update(
            mesh_attributes(plain, topology, triangle_mask, corner_of_vertex, where, diag)
        )
    for mi_name in set(attributes.values()) - set(out.attributes):
        # Requested but not authored (e.g. a hand-made feather mesh without barb tangents): the
        # BSDF reads the attribute on every mesh of its material, so supply dp/du instead.
        out.attributes[mi_name] = uv_tangents(out.positions, out.faces, out.texcoords)
    return out


def face_normals_at_vertices(positions: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit area-weighted mean of the geometric normals of the triangles around each vertex.

    Follows the faces' winding (Mitsuba's geometric normal ``(p1 − p0) × (p2 − p0)``); a vertex
    used by no triangle, or only by degenerate ones, gets the zero vector.
    """
    p = positions.astype(np.float64)
    a, b, c = (p[faces[:, i]] for i in range(3))
    per_face = np.cross(b - a, c - a)
    normals = np.zeros_like(p)
    for i in range(3):
        np.add.at(normals, faces[:, i], per_face)
    return normalize(normals)


def uv_tangents(positions: np.ndarray, faces: np.ndarray, uv: np.ndarray | None) -> np.ndarray:
    """Per-vertex unit ``dp/du`` (Lengyel 2001, "Computing tangent space basis vectors").

    Per triangle ``T = (Δv₂ e₁ − Δv₁ e₂) / (Δu₁ Δv₂ − Δu₂ Δv₁)``, summed at its vertices. Vertices
    without a usable tangent (no UVs, degenerate UVs) get the zero vector, which the feather BSDF
    reads as "barb along the surface tangent".
    """
    tangents = np.zeros_like(positions, dtype=np.float64)
    if uv is not None and len(faces):
        p = positions[faces].astype(np.float64)
        t = uv[faces].astype(np.float64)
        e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
        d1, d2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
        det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
        ok = np.abs(det) > 1e-20
        per_face = np.zeros_like(e1)
        per_face[ok] = (d2[ok, 1, None] * e1[ok] - d1[ok, 1, None] * e2[ok]) / det[ok, None]
        for corner in range(3):
            np.add.at(tangents, faces[:, corner], per_face)
    length = np.linalg.norm(tangents, axis=1, keepdims=True)
    return np.where(length > 1e-20, tangents / np.where(length > 0, length, 1.0), 0.0).astype(
        np.float32
    )


def to_mitsuba_mesh(triangle_mesh: TriangleMesh, bsdf, emitter=None) -> object:
    """An ``mi.Mesh`` with the given BSDF object (and optionally an area emitter) attached."""
    import mitsuba as mi

    props = mi.Properties()
    props["bsdf"] = bsdf
    if emitter is not None:
        props["emitter"] = emitter
    m = mi.Mesh(
        triangle_mesh.name,
        len(triangle_mesh.positions),
        len(triangle_mesh.faces),
        props=props,
        has_vertex_normals=triangle_mesh.normals is not None,
        has_vertex_texcoords=triangle_mesh.texcoords is not None,
    )
    params = mi.traverse(m)
    # Buffers in the parameters' own types: ``mi.Float(ndarray)`` only exists in JIT variants,
    # the scalar variants' dynamic arrays are ``drjit.scalar.ArrayXf``/``ArrayXu``.
    floats, indices = type(params["vertex_positions"]), type(params["faces"])
    params["vertex_positions"] = floats(triangle_mesh.positions.ravel())
    params["faces"] = indices(triangle_mesh.faces.ravel())
    if triangle_mesh.normals is not None:
        params["vertex_normals"] = floats(triangle_mesh.normals.ravel())
    if triangle_mesh.texcoords is not None:
        params["vertex_texcoords"] = floats(triangle_mesh.texcoords.ravel())
    params.update()
    for name, values in triangle_mesh.attributes.items():
        m.add_attribute(name, values.shape[1], floats(values.ravel()))
    return m
