"""``UsdGeom.Mesh`` → Mitsuba triangle meshes.

A gprim becomes a :class:`Surface`: validated polygons (:class:`Topology`), normals and every
numeric primvar (:mod:`pavonine.render.primvars`). Implicit prims (:mod:`pavonine.render.shapes`),
subdivision (:mod:`pavonine.render.subdivision`) and skinning (:mod:`pavonine.render.skel`) make or
change surfaces; this module turns one into ``mi.Mesh`` objects: polygons as fans, split by
``GeomSubset`` material bindings, one mesh per material. Each non-constant primvar the material
reads becomes a mesh attribute named by :func:`mesh_attribute_name` (with a colour twin when it
has 3 channels). When all per-vertex data built (normals, texture coordinates, those attributes)
is ``vertex``, ``varying`` or ``uniform`` the mesh keeps its shared vertices; otherwise corners are
unwelded.

Bad data renders what it can: attributes of the wrong type are ignored with a warning naming the
prim and the attribute (:mod:`pavonine.render.attributes`); faces that use non-finite points (or
points beyond :data:`~pavonine.render.limits.MAX_COORDINATE`) or out-of-range indices are dropped
with one warning; an empty mesh is skipped with a warning.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from pxr import Usd, UsdGeom, UsdShade

from pavonine.render import attributes
from pavonine.render.diagnostics import Diagnostics
from pavonine.render.limits import MAX_COORDINATE
from pavonine.render.primvars import (
    COLOR_TWIN,
    PER_VERTEX,
    Primvar,
    attribute_values,
    mesh_attribute_name,
    per_corner,
    read_primvars,
)
from pavonine.render.xform import (
    flips_handedness,
    normalize,
    transform_directions,
    transform_normals,
    transform_points,
)

__all__ = ["Primvar", "Surface", "Topology", "mesh_attribute_name"]

SCHEMES = ("catmullClark", "loop", "bilinear", "none")  # USD's fallback first
#: Tessellated barbs' own coordinate per vertex (:mod:`pavonine.render.curves.sampling`): length
#: along the barb and across it (scene units; world-scaled here), and the barb's id.
BARB_COORDINATE = "pavonine_barbCoordinate"
#: Tessellated ribbons' half width at each vertex (scene units): where the barbule pattern
#: (:mod:`pavonine.materials.barbule_pattern`) finds the ribbon's edge.
BARB_HALF_WIDTH = "pavonine_barbHalfWidth"


@dataclass
class Topology:
    """A mesh's polygons after validation, as triangles over face-vertex corners."""

    points: np.ndarray  # (P, 3) float64, object space
    face_vertex_counts: np.ndarray  # (F,) int64
    face_vertex_indices: np.ndarray  # (C,) int64, one per corner
    triangles: np.ndarray  # (T, 3) corner indices
    triangle_face: np.ndarray  # (T,) polygon index of each triangle
    left_handed: bool = False  # triangles wound clockwise from the polygons' corner order

    @property
    def face_count(self) -> int:
        return len(self.face_vertex_counts)

    @property
    def corner_face(self) -> np.ndarray:
        """(C,) the polygon of each face-vertex corner."""
        return np.repeat(np.arange(self.face_count), self.face_vertex_counts)


@dataclass
class Surface:
    """A gprim as polygons with normals and primvars, in object space."""

    prim: Usd.Prim
    topology: Topology
    normals: Primvar | None = None
    primvars: dict[str, Primvar] = field(default_factory=dict)
    double_sided: bool = False
    scheme: str = "none"  # subdivisionScheme still to apply (``none`` once refined)
    #: authored polygon of each polygon (``None``: the identity); GeomSubsets index authored faces
    authored_face: np.ndarray | None = None

    @property
    def where(self) -> str:
        return str(self.prim.GetPath())


@dataclass
class TriangleMesh:
    """A triangle mesh ready for Mitsuba (world or prototype space)."""

    name: str
    positions: np.ndarray  # (V, 3) float32
    faces: np.ndarray  # (F, 3) uint32
    normals: np.ndarray | None = None
    texcoords: np.ndarray | None = None
    attributes: dict[str, np.ndarray] = field(default_factory=dict)
    #: the surface point each vertex is (an index into the translated surface's points)
    point_of_vertex: np.ndarray | None = None

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self.positions.min(axis=0), self.positions.max(axis=0)

    def area(self) -> float:
        """Total triangle area, in the units of ``positions`` squared."""
        p = self.positions.astype(np.float64)[self.faces]
        return float(
            0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum()
        )


def make_topology(
    points: np.ndarray,
    counts: np.ndarray,
    indices: np.ndarray,
    left_handed: bool,
    where: str,
    diag: Diagnostics,
) -> Topology | None:
    """Validated polygons triangulated as fans; ``None`` (with a warning) if none are renderable."""
    if len(points) == 0 or len(counts) == 0:
        diag.warn(where, "empty mesh (no points or faces); skipped")
        return None
    if np.any(counts < 0) or counts.sum() != len(indices):
        diag.warn(
            where,
            f"faceVertexCounts sum to {counts.sum()} but there are {len(indices)} "
            "faceVertexIndices (or a count is negative); skipped",
        )
        return None
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    fan = np.where(counts >= 3, counts - 2, 0)
    triangle_face = np.repeat(np.arange(len(counts)), fan)
    k = np.arange(len(triangle_face)) - np.repeat(np.cumsum(fan) - fan, fan)
    first = starts[triangle_face]
    triangles = np.stack([first, first + k + 1, first + k + 2], axis=1)
    if left_handed:
        triangles = triangles[:, [0, 2, 1]]
    if np.any((counts > 0) & (counts < 3)):
        diag.warn(
            where,
            f"{int(((counts > 0) & (counts < 3)).sum())} faces have fewer than 3 vertices; dropped",
        )

    bad_index = (indices < 0) | (indices >= len(points))
    finite = np.all(np.isfinite(points) & (np.abs(points) <= MAX_COORDINATE), axis=1)
    bad_point = np.zeros(len(indices), dtype=bool)
    bad_point[~bad_index] = ~finite[indices[~bad_index]]
    drop = np.any((bad_index | bad_point)[triangles], axis=1)
    if np.any(bad_index):
        diag.warn(
            where,
            f"{int(bad_index.sum())} faceVertexIndices out of range (0..{len(points) - 1}); "
            "their faces dropped",
        )
    if not finite.all():
        diag.warn(
            where,
            f"{int((~finite).sum())} of {len(points)} points are NaN, infinite or beyond "
            f"±{MAX_COORDINATE:g}; "
            f"{len(np.unique(triangle_face[drop]))} faces using them dropped",
        )
    triangles, triangle_face = triangles[~drop], triangle_face[~drop]
    if len(triangles) == 0:
        diag.warn(where, "no renderable faces remain; skipped")
        return None
    safe_indices = np.where(bad_index, 0, indices)
    return Topology(points, counts, safe_indices, triangles, triangle_face, left_handed)


def read_mesh(
    mesh: UsdGeom.Mesh, time: Usd.TimeCode, diag: Diagnostics, base: Usd.TimeCode | None = None
) -> Surface | None:
    """A ``UsdGeom.Mesh`` as a :class:`Surface`; ``None`` (with a warning) if nothing renders.

    ``base``: the frame's time when ``time`` is within its shutter; authored ``velocities`` (and
    ``accelerations``) then move the points from the sample at or before ``base``, as USD says
    (``UsdGeomPointBased::ComputePointsAtTime``)."""
    prim = mesh.GetPrim()
    where = str(prim.GetPath())
    points = attributes.vec3_array(mesh.GetPointsAttr(), time, diag)
    if points is not None and base is not None and base != time:
        if mesh.GetVelocitiesAttr().HasAuthoredValue():
            moved = mesh.ComputePointsAtTime(time, base)
            if moved is not None and len(moved) == len(points):
                points = np.asarray(moved, dtype=np.float64).reshape(-1, 3)
    counts = attributes.int_array(mesh.GetFaceVertexCountsAttr(), time, diag)
    indices = attributes.int_array(mesh.GetFaceVertexIndicesAttr(), time, diag)
    if points is None or counts is None or indices is None:
        diag.warn(
            where, "empty mesh (no usable points, faceVertexCounts or faceVertexIndices); skipped"
        )
        return None
    attributes.check_extent(prim, points, time, diag)
    orientation = attributes.token(prim, "orientation", time, diag, ("rightHanded", "leftHanded"))
    topology = make_topology(points, counts, indices, orientation == "leftHanded", where, diag)
    if topology is None:
        return None
    scheme = attributes.token(prim, "subdivisionScheme", time, diag, SCHEMES)
    return Surface(
        prim,
        topology,
        normals=read_normals(mesh, time, diag),
        primvars=read_primvars(prim, time, diag),
        double_sided=double_sided(prim, time, diag),
        scheme=scheme,
    )


def with_points(surface: Surface, points: np.ndarray, diag: Diagnostics) -> Surface:
    """The surface with its points moved (skinned); authored normals, now stale, are recomputed."""
    from dataclasses import replace

    topology = surface.topology
    if len(points) != len(topology.points):
        diag.warn(surface.where, "skinned points do not match the mesh's points; rest pose")
        return surface
    moved = replace(topology, points=np.asarray(points, dtype=np.float64))
    normals = None if surface.normals is None else smooth_normals(moved)
    return replace(surface, topology=moved, normals=normals)


def double_sided(prim: Usd.Prim, time: Usd.TimeCode, diag: Diagnostics) -> bool:
    """The gprim's ``doubleSided`` (its schema fallback when unauthored; a warning if not a bool)."""
    attr = UsdGeom.Gprim(prim).GetDoubleSidedAttr()
    value = attr.Get(time) if attr else None
    if value is None:
        return False
    if not isinstance(value, bool):
        diag.warn(
            str(prim.GetPath()),
            f"doubleSided has type {attributes.authored_type(attr)}, expected bool; using false",
        )
        return False
    return value


def read_normals(mesh: UsdGeom.Mesh, time: Usd.TimeCode, diag: Diagnostics) -> Primvar | None:
    """``primvars:normals`` if authored, else the ``normals`` attribute with its interpolation."""
    from pavonine.render.primvars import read_primvar

    normals = read_primvar(mesh.GetPrim(), "normals", time, diag)
    if normals is not None:
        return normals if normals.values.shape[1] == 3 else None
    values = attributes.vec3_array(mesh.GetNormalsAttr(), time, diag)
    if values is None or len(values) == 0:
        return None
    interpolation = str(mesh.GetNormalsInterpolation())
    return Primvar(values, interpolation, "Normal")


def smooth_normals(topology: Topology) -> Primvar:
    """Area-weighted vertex normals (for smooth surfaces authored without normals)."""
    p = topology.points
    corner_points = topology.face_vertex_indices[topology.triangles]
    a, b, c = (p[corner_points[:, i]] for i in range(3))
    face_normals = np.cross(b - a, c - a)
    # Each point sums its triangles' normals in the order of corners 0, 1, 2 (as three np.add.at
    # would, bit for bit): one bincount per axis over the corners in that order, ~10x faster.
    corners = corner_points.T.ravel()
    weights = np.tile(face_normals, (3, 1))
    normals = np.stack(
        [np.bincount(corners, weights[:, k], minlength=len(p)) for k in range(3)], axis=1
    ).astype(p.dtype, copy=False)
    return Primvar(normals, "vertex", "Normal")


def material_groups(
    surface: Surface, time: Usd.TimeCode, diag: Diagnostics
) -> list[tuple[UsdShade.Material | None, np.ndarray]]:
    """``(bound material, triangle mask)`` per ``GeomSubset`` (familyName materialBind) and the rest."""
    topology = surface.topology
    binding = UsdShade.MaterialBindingAPI(surface.prim)
    face = topology.triangle_face
    if surface.authored_face is not None:
        face = surface.authored_face[face]
    remaining = np.ones(len(topology.triangles), dtype=bool)
    groups: list[tuple[UsdShade.Material | None, np.ndarray]] = []
    subsets = binding.GetMaterialBindSubsets() if surface.prim.IsA(UsdGeom.Imageable) else []
    for subset in subsets:
        faces = attributes.int_array(subset.GetIndicesAttr(), time, diag)
        if faces is None or len(faces) == 0:
            continue
        authored_faces = (
            topology.face_count
            if surface.authored_face is None
            else int(surface.authored_face.max() + 1)
        )
        if np.any((faces < 0) | (faces >= authored_faces)):
            diag.warn(
                str(subset.GetPath()),
                f"indices out of range (0..{authored_faces - 1}); those faces ignored",
            )
        selected = np.isin(face, faces) & remaining
        remaining &= ~selected
        material = UsdShade.MaterialBindingAPI(subset.GetPrim()).ComputeBoundMaterial()[0]
        groups.append((material if material else None, selected))
    material = binding.ComputeBoundMaterial()[0]
    groups.append((material if material else None, remaining))
    return [(m, mask) for m, mask in groups if mask.any()]


def build_triangle_mesh(
    surface: Surface,
    triangle_mask: np.ndarray,
    matrix_usd: np.ndarray,
    uv_primvar: str,
    feather_attributes: dict[str, str],
    diag: Diagnostics,
    name: str,
    primvars: Sequence[str] = (),
) -> TriangleMesh:
    """One material's triangles with positions/normals/uvs/attributes transformed by ``matrix_usd``.

    ``primvars`` are the primvars the material reads per mesh (``MaterialSpec.primvars``: its
    ``UsdPrimvarReader``\\ s, ``displayColor``/``displayOpacity`` for the no-material fallback).
    Each non-constant one among them becomes the attribute :func:`mesh_attribute_name` names,
    with its values as authored (object space, refined with the surface), 1 or 3 channels
    (:func:`attribute_values`); a 3-channel one also gets its colour twin (:data:`COLOR_TWIN`).
    Primvars nobody reads are not built, so a mesh keeps its shared vertices unless a face-varying
    primvar is read. ``feather_attributes`` (primvar → Mitsuba name) are the feather BSDF's
    direction attributes, transformed with the mesh and renormalised.
    """
    topology, where = surface.topology, surface.where
    normals = surface.normals
    if normals is None and surface.scheme != "none":
        normals = smooth_normals(topology)
    uv = surface.primvars.get(uv_primvar)
    if uv is None and uv_primvar != "st":
        diag.warn(where, f"primvar {uv_primvar} not found; using st for texture coordinates")
        uv = surface.primvars.get("st")
    read = {n.removeprefix("primvars:") for n in primvars}
    attribute_primvars = {
        n: pv for n, pv in surface.primvars.items() if n in read and pv.interpolation != "constant"
    }
    per_vertex = {n: pv for n, pv in attribute_primvars.items() if pv.interpolation != "uniform"}
    per_vertex.update({n: surface.primvars[n] for n in feather_attributes if n in surface.primvars})
    corner_data = [normals, uv, *per_vertex.values()]
    welded = all(pv is None or pv.interpolation in (*PER_VERTEX, "constant") for pv in corner_data)
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
    out.point_of_vertex = topology.face_vertex_indices[corner_of_vertex]
    corner_face = topology.corner_face

    def corner_values(primvar: Primvar, label: str) -> np.ndarray | None:
        values = per_corner(
            primvar,
            topology.face_vertex_indices,
            corner_face,
            len(topology.points),
            topology.face_count,
            where,
            label,
            diag,
        )
        return None if values is None else values[corner_of_vertex]

    if normals is not None:
        n = corner_values(normals, "normals")
        if n is not None:
            n = transform_normals(n, matrix_usd)
            bad = np.linalg.norm(n, axis=1) < 0.5  # zero as authored
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
        if t is not None and t.shape[1] >= 2:
            # USD's st has v up; Mitsuba's bitmap rows start at the top (as its OBJ/PLY loaders do).
            out.texcoords = np.stack([t[:, 0], 1.0 - t[:, 1]], axis=1).astype(np.float32)
    for primvar_name, primvar in attribute_primvars.items():
        attribute = mesh_attribute_name(primvar_name, primvar.interpolation)
        if primvar.interpolation == "uniform":
            if len(primvar.values) < topology.face_count:
                diag.warn(
                    where,
                    f"uniform primvar {primvar_name} has {len(primvar.values)} values for "
                    f"{topology.face_count} faces; ignored",
                )
                continue
            values = primvar.values[topology.triangle_face[triangle_mask]]
        else:
            values = corner_values(primvar, primvar_name)
            if values is None:
                continue
        out.attributes[attribute] = attribute_values(values)
        if out.attributes[attribute].shape[1] == 3:
            out.attributes[attribute + COLOR_TWIN] = out.attributes[attribute]
    for primvar_name, mi_name in feather_attributes.items():
        primvar = surface.primvars.get(primvar_name)
        values = None if primvar is None else corner_values(primvar, primvar_name)
        if primvar_name == BARB_COORDINATE:  # lengths scale with the transform, the id does not
            scale = abs(np.linalg.det(matrix_usd[:3, :3])) ** (1.0 / 3.0)
            coordinate = np.zeros((len(out.positions), 3)) if values is None else values
            out.attributes[mi_name] = (coordinate * [scale, scale, 1.0]).astype(np.float32)
        elif primvar_name == BARB_HALF_WIDTH:  # a length: scales with the transform
            scale = abs(np.linalg.det(matrix_usd[:3, :3])) ** (1.0 / 3.0)
            half = np.zeros((len(out.positions), 1)) if values is None else values[:, :1]
            out.attributes[mi_name] = (half * scale).astype(np.float32)
        elif values is not None and values.shape[1] == 3:
            out.attributes[mi_name] = transform_directions(values, matrix_usd).astype(np.float32)
        else:
            # Requested but not authored (e.g. a hand-made feather mesh without barb tangents):
            # the BSDF reads the attribute on every mesh of its material, so supply dp/du instead.
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


#: Byte alignment of the buffers handed to Dr.Jit (a cache line; packet loads need less).
ALIGNMENT = 64


def _aligned(array_type):
    """A constructor ``ndarray → array_type`` that first copies the values to an aligned buffer.

    Dr.Jit marks an array made from a NumPy buffer *unaligned* when the buffer's address does not
    suit packet loads, and then traces gathers from it (a mesh's texture coordinates, say) one
    component at a time. Where NumPy's allocator puts an array varies from run to run, so the
    traced path tracer did too: the eye feather's kernel came out with 23,612 to 23,966
    operations, and a variant not yet in Dr.Jit's disk cache meant a whole LLVM compile inside
    the render. With aligned buffers it is the same kernel every run (23,612 operations).
    """
    import drjit as dr

    if not dr.is_jit_v(array_type):
        return array_type

    def make(values: np.ndarray):
        flat = np.ascontiguousarray(values).ravel()
        raw = np.empty(flat.nbytes + ALIGNMENT, dtype=np.uint8)
        start = -raw.ctypes.data % ALIGNMENT
        aligned = raw[start : start + flat.nbytes].view(flat.dtype)
        aligned[:] = flat
        return array_type(aligned)

    return make


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
    floats = _aligned(type(params["vertex_positions"]))
    indices = _aligned(type(params["faces"]))
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
