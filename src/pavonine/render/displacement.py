"""Displacement at render time: tessellate a mesh, then move its vertices along the normal.

A material whose displacement is not zero gives its meshes a :class:`Displacement`:
UsdPreviewSurface's ``displacement`` input, a MaterialX ``displacementshader``
(``ND_displacement_float``: ``displacement · scale``), hdmitsuba's ``outputs:mitsuba:displacement``
terminal (a texture ``t``, displacing by ``t − 0.5`` as hdmitsuba's ``usd_mitsuba/mesh.py``
does), and a feather material's displacement map with ``pavonine:displacementHeight`` > 0. The
delegate builds such meshes as :class:`DisplacedMesh` (after subdivision: :mod:`.subdivision`
refines the surface first); once the cameras are known :func:`resolve` tessellates each one:

1. **Level**: every triangle of the mesh is split into ``n²`` (a regular barycentric grid; one
   ``n`` per mesh, so a shared edge is split alike on both sides and the surface cannot crack)
   with ``n`` the smallest level that brings the longest triangle edge, seen from every camera, to
   :data:`TARGET_EDGE_PX` pixels (distance to the camera: the triangle's nearest vertex, no
   closer than the near clip; meshes in instance prototypes are measured at the scene bounds'
   nearest point). Levels are capped at :data:`MAX_LEVEL`.
2. **Ceiling**: all displaced meshes of a render together get at most :data:`MAX_TRIANGLES`
   triangles. Beyond it every level is scaled down by one factor until they fit, and each mesh
   left coarser than asked is warned about by name; a mesh that would get no refinement at all
   (``n = 1`` where it asked for more) keeps its material's **bump map** instead, undisplaced,
   with a warning: bump mapping is the fallback for scenes too large to tessellate.
3. Every per-vertex array (positions, normals, texture coordinates, mesh attributes) is
   interpolated linearly over the grid.
4. **Heights**: ``h = offset + scale · d(uv)`` with ``d`` the texture low-passed to the vertex
   spacing and read bilinearly with its wrap mode and uv transform:
   :func:`pavonine.base.map_filters.displacement_heights`, the converter's own formula
   for the baked feather vane, so a feather displaced here and one baked by ``convert`` agree.
5. **Move**: ``P' = P + h · n`` with ``n`` the object-space unit normal carried through the
   mesh's transform (``h`` is in object units, as UsdPreviewSurface specifies); normals are then
   recomputed from the displaced triangles (area-weighted, welded across unwelded corners that
   shared a position and a normal), and direction attributes (the feather's barb tangent) made
   perpendicular to them again.

Memory: a displaced triangle costs about :data:`BYTES_PER_TRIANGLE` at peak (Mitsuba's buffers and
BVH plus the tessellation's temporaries; measured by ``benchmarks/bench_displacement.py``: +55 MB
for 131,072 triangles), so the ceiling is about 3.5 GB.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, replace

import numpy as np

from pavonine.render.diagnostics import Diagnostics
from pavonine.render.mesh import TriangleMesh, face_normals_at_vertices, to_mitsuba_mesh

#: Longest edge of a displaced triangle on screen, in pixels (Karma's and Cycles' dicing default).
TARGET_EDGE_PX = 1.0
#: Triangles all displaced meshes of one render may have together (memory ceiling, see above).
MAX_TRIANGLES = 8_000_000
#: Peak bytes per displaced triangle (measured, see the module docstring): the ceiling's memory.
BYTES_PER_TRIANGLE = 440
#: Largest per-mesh level (each triangle into at most MAX_LEVEL² triangles).
MAX_LEVEL = 256


@dataclass(frozen=True)
class Displacement:
    """What displaces a material's meshes: ``offset + scale · texels(uv)`` (or the constant).

    ``texels`` (H×W, row 0 the image's top) are read at a mesh's texture coordinates (Mitsuba's
    uv, v down) through ``to_uv`` (3×3, Mitsuba uv → texture uv) with ``wrap`` (clamp, repeat,
    mirror); ``None`` displaces by ``offset`` everywhere. ``keep_bump``: the material's BSDF keeps
    its bump map on the displaced mesh (the feather, whose baked mesh keeps it too); otherwise
    the bump wrapper (:attr:`MaterialSpec.bsdf`'s outermost ``bumpmap``) is the fallback only.
    """

    where: str  # the shader (or material) that displaces, for warnings
    texels: np.ndarray | None = None
    to_uv: np.ndarray | None = None
    wrap: str = "clamp"
    scale: float = 1.0
    offset: float = 0.0
    keep_bump: bool = False

    @property
    def key(self) -> tuple:
        return (self.where, self.scale, self.offset, self.keep_bump)


def from_texture(where: str, value, scale: float = 1.0, offset: float = 0.0, **kw) -> Displacement:
    """A :class:`Displacement` from a translated value: a float or a ``bitmap`` dict (its texels,
    ``to_uv`` and ``wrap_mode``). Raises ``ValueError`` for anything else (primvar readers...)."""
    if isinstance(value, (int, float)):
        return Displacement(where, None, None, "clamp", 1.0, offset + scale * float(value), **kw)
    if not (isinstance(value, dict) and value.get("type") == "bitmap"):
        raise ValueError("only a texture or a constant can displace")
    texels = np.array(value["bitmap"], dtype=np.float64)
    texels = texels[..., 0] if texels.ndim == 3 else texels
    to_uv = np.array(value["to_uv"].matrix, dtype=np.float64) if "to_uv" in value else np.eye(3)
    wrap = value.get("wrap_mode", "repeat")
    return Displacement(where, texels, to_uv, wrap, scale, offset, **kw)


def heights(displacement: Displacement, texcoords: np.ndarray | None, faces: np.ndarray):
    """Per-vertex heights of a mesh (object units): the module docstring's step 4."""
    from pavonine.base.map_filters import displacement_heights

    d = displacement
    if d.texels is None or texcoords is None:
        count = 0 if texcoords is None else len(texcoords)
        return np.full(count, d.offset) if d.texels is None else None
    uv = np.column_stack([texcoords, np.ones(len(texcoords))]) @ d.to_uv.T
    feather_uv = np.column_stack([uv[:, 0], 1.0 - uv[:, 1]])  # Mitsuba's v down → v up
    h, w = d.texels.shape
    spacing = _uv_spacing(feather_uv, faces) * math.sqrt(w / h)
    return d.offset + displacement_heights(d.texels, feather_uv, d.scale, spacing, d.wrap)


def _uv_spacing(uv: np.ndarray, faces: np.ndarray) -> float:
    """Mean vertex spacing in uv, ``sqrt(2 · mean triangle area)`` (as the converter measures)."""
    t = uv[faces]
    e1, e2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    return math.sqrt(2.0 * float(area.mean())) if len(area) else 0.0


# -- tessellation ---------------------------------------------------------------------------------


def grid(level: int) -> tuple[np.ndarray, np.ndarray]:
    """Barycentric grid of one triangle split ``level`` ways: integer weights (P, 3) summing to
    ``level`` over its corners (a, b, c), and (level², 3) triangles over those points, wound as
    (a, b, c) is."""
    n = level
    ij = [(i, j) for i in range(n + 1) for j in range(n + 1 - i)]
    index = {p: k for k, p in enumerate(ij)}
    weights = np.array([(n - i - j, i, j) for i, j in ij], dtype=np.int64)
    tris = []
    for i in range(n):
        for j in range(n - i):
            tris.append((index[i, j], index[i + 1, j], index[i, j + 1]))
            if i + j < n - 1:
                tris.append((index[i + 1, j], index[i + 1, j + 1], index[i, j + 1]))
    return weights, np.array(tris, dtype=np.int64)


def tessellate(mesh: TriangleMesh, level: int) -> TriangleMesh:
    """Every triangle split into ``level²`` with each per-vertex array interpolated linearly.

    Points on a shared edge are shared (one vertex per edge position), so a displaced result
    stays watertight wherever the input was welded.
    """
    if level <= 1:
        return mesh
    weights, local = grid(level)
    faces = mesh.faces.astype(np.int64)
    nonzero = (weights > 0).sum(axis=1)
    corner, edge, inner = nonzero == 1, nonzero == 2, nonzero == 3
    count = len(mesh.positions)
    # corners: the mesh's own vertices
    point_of = np.empty((len(faces), len(weights)), dtype=np.int64)
    point_of[:, corner] = faces[:, weights[corner].argmax(axis=1)]
    # edge points: one per (edge, position along it), keyed by its end vertices
    ew = weights[edge]
    ends = np.argsort(ew == 0, axis=1, kind="stable")[:, :2]  # the two corners with weight
    va = faces[:, ends[:, 0]]
    vb = faces[:, ends[:, 1]]
    wa = np.broadcast_to(ew[np.arange(len(ew)), ends[:, 0]], va.shape)
    low, high = np.minimum(va, vb), np.maximum(va, vb)
    w_low = np.where(va <= vb, wa, level - wa)
    key = (low * count + high) * (level + 1) + w_low
    unique_keys, edge_index = np.unique(key.ravel(), return_inverse=True)
    point_of[:, edge] = count + edge_index.reshape(key.shape)
    e_low = unique_keys // (level + 1) // count
    e_high = unique_keys // (level + 1) % count
    e_t = (unique_keys % (level + 1)) / level  # weight of the lower-numbered end
    # interior points: one per triangle and grid point
    inner_count = int(inner.sum())
    start = count + len(unique_keys)
    point_of[:, inner] = start + np.arange(len(faces) * inner_count).reshape(len(faces), -1)
    iw = weights[inner] / level

    def interpolate(values: np.ndarray) -> np.ndarray:
        v = values.astype(np.float64)
        on_edges = e_t[:, None] * v[e_low] + (1.0 - e_t[:, None]) * v[e_high]
        inside = np.einsum("pk,tkc->tpc", iw, v[faces]).reshape(-1, v.shape[1])
        return np.concatenate([v, on_edges, inside]).astype(values.dtype)

    out_faces = point_of[:, local].reshape(-1, 3)
    return TriangleMesh(
        mesh.name,
        interpolate(mesh.positions),
        out_faces.astype(np.uint32),
        None if mesh.normals is None else interpolate(mesh.normals),
        None if mesh.texcoords is None else interpolate(mesh.texcoords),
        {name: interpolate(values) for name, values in mesh.attributes.items()},
    )


def displace(
    mesh: TriangleMesh,
    displacement: Displacement,
    matrix_usd: np.ndarray,
    tangents: tuple[str, ...] = (),
):
    """The mesh moved along its normals (steps 4-5); ``None`` if it has no texture coordinates
    for a textured displacement. The ``tangents`` attributes (direction fields such as the
    feather's barb tangent) are made perpendicular to the new normals again, as the converter
    does for its baked vane."""
    normals = mesh.normals
    if normals is None:
        normals = welded_normals(mesh.positions, mesh.faces, None)
    h = heights(displacement, mesh.texcoords, mesh.faces)
    if h is None:
        return None
    linear = np.asarray(matrix_usd, dtype=np.float64)[:3, :3]
    object_normals = normals.astype(np.float64) @ linear.T  # USD row vectors: n_o ∝ n_w · Mᵀ
    length = np.linalg.norm(object_normals, axis=1, keepdims=True)
    object_normals /= np.where(length > 0, length, 1.0)
    positions = mesh.positions.astype(np.float64) + (h[:, None] * object_normals) @ linear
    moved = welded_normals(positions, mesh.faces, normals)
    attributes = dict(mesh.attributes)
    for name in tangents:
        if name in attributes:
            t = attributes[name].astype(np.float64)
            t = t - np.sum(t * moved, axis=1, keepdims=True) * moved
            length = np.linalg.norm(t, axis=1, keepdims=True)
            attributes[name] = (t / np.where(length > 0, length, 1.0)).astype(np.float32)
    return replace(
        mesh,
        positions=positions.astype(np.float32),
        normals=moved.astype(np.float32),
        attributes=attributes,
    )


def welded_normals(positions: np.ndarray, faces: np.ndarray, before: np.ndarray | None):
    """Area-weighted vertex normals, summed over vertices that share a position (and, given
    ``before``, a normal before displacement: hard edges stay hard)."""
    keys = np.round(positions.astype(np.float64), 6)
    if before is not None:
        keys = np.column_stack([keys, np.round(before.astype(np.float64), 3)])
    _, group = np.unique(keys, axis=0, return_inverse=True)
    group = group.ravel()
    per_vertex = face_normals_at_vertices(positions, faces)
    area = np.zeros_like(per_vertex)
    p = positions.astype(np.float64)
    a, b, c = (p[faces[:, i]] for i in range(3))
    cross = np.cross(b - a, c - a)
    for i in range(3):
        np.add.at(area, group[faces[:, i]], cross)
    summed = area[group]
    length = np.linalg.norm(summed, axis=1, keepdims=True)
    return np.where(length > 0, summed / np.where(length > 0, length, 1.0), per_vertex)


# -- deferred meshes and views ------------------------------------------------------------------


@dataclass
class DisplacedMesh:
    """A mesh to displace once the cameras are known (a placeholder in the scene dict)."""

    where: str  # the prim
    triangles: TriangleMesh  # world space (or prototype space when not ``world``)
    matrix_usd: np.ndarray  # object → that space
    displacement: Displacement
    bsdf: object  # loaded BSDF for the displaced mesh
    fallback_bsdf: object  # loaded BSDF with the bump map, for the undisplaced fallback
    emitter: object | None
    world: bool
    tangents: tuple[str, ...] = ()  # direction attributes kept perpendicular to the normal


@dataclass(frozen=True)
class View:
    """One camera as the tessellation sees it: pixel size at a distance, near clip."""

    origin: np.ndarray
    per_distance: float  # pixel size per unit distance (perspective); 0 for orthographic
    constant: float  # pixel size (orthographic); 0 for perspective
    near: float

    def pixel(self, distance: np.ndarray) -> np.ndarray:
        d = np.maximum(distance, self.near)
        return self.constant + self.per_distance * d


def view_of(sensor: dict, to_world: np.ndarray, size: tuple[int, int]) -> View:
    """A :class:`View` of a Mitsuba sensor dict (perspective, thinlens, orthographic)."""
    width, height = (max(int(s), 1) for s in size)
    origin = np.asarray(to_world, dtype=np.float64)[:3, 3]
    near = float(sensor.get("near_clip", 1e-2))
    if sensor.get("type") == "orthographic":
        scale = np.array(sensor["to_world"].matrix, dtype=np.float64)
        return View(origin, 0.0, 2.0 * float(np.linalg.norm(scale[:3, 0])) / width, near)
    axis = sensor.get("fov_axis", "x")
    pixels = {"x": width, "y": height, "smaller": min(width, height)}.get(axis)
    pixels = pixels or {"larger": max(width, height)}.get(axis, math.hypot(width, height))
    span = 2.0 * math.tan(math.radians(float(sensor.get("fov", 39.6))) / 2.0)
    return View(origin, span / pixels, 0.0, near)


def wanted_level(
    mesh: DisplacedMesh, views: list[View], bounds, target_px: float = TARGET_EDGE_PX
) -> int:
    """The smallest level bringing the mesh's longest on-screen edge to ``target_px``."""
    p = mesh.triangles.positions.astype(np.float64)
    f = mesh.triangles.faces.astype(np.int64)
    edges = np.stack([p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 1]], p[f[:, 0]] - p[f[:, 2]]])
    longest = np.linalg.norm(edges, axis=2).max(axis=0)
    level = 1.0
    for view in views:
        if mesh.world:
            distance = np.linalg.norm(p - view.origin, axis=1)[f].min(axis=1)
        else:
            lo, hi = bounds
            distance = np.full(len(f), np.linalg.norm(np.clip(view.origin, lo, hi) - view.origin))
        px = longest / view.pixel(distance)
        level = max(level, float(px.max()) / target_px)
    return int(min(math.ceil(level - 1e-9), MAX_LEVEL))


def placeholders(node) -> Iterator[tuple[dict, str, DisplacedMesh]]:
    """``(parent dict, key, mesh)`` of every :class:`DisplacedMesh` in a scene dict."""
    if isinstance(node, dict):
        for key, value in node.items():
            if isinstance(value, DisplacedMesh):
                yield node, key, value
            elif isinstance(value, dict):
                yield from placeholders(value)


def fit_levels(wanted: list[int], counts: list[int], ceiling: int) -> list[int]:
    """Levels scaled by one factor so that ``Σ count · level²`` ≤ ``ceiling`` (never below 1)."""

    def total(levels):
        return sum(c * n * n for c, n in zip(counts, levels, strict=True))

    if total(wanted) <= ceiling:
        return list(wanted)
    lo, hi = 0.0, 1.0
    for _ in range(40):
        mid = (lo + hi) / 2
        if total([max(1, math.floor(n * mid)) for n in wanted]) <= ceiling:
            lo = mid
        else:
            hi = mid
    return [max(1, math.floor(n * lo)) for n in wanted]


@dataclass
class Report:
    """What :func:`resolve` did (for the benchmark): triangles before and after, seconds."""

    meshes: int = 0
    triangles_in: int = 0
    triangles_out: int = 0
    fallbacks: int = 0
    seconds: float = 0.0


def resolve(
    scene: dict,
    views: list[View],
    bounds,
    diag: Diagnostics,
    *,
    target_px: float | None = None,
    ceiling: int | None = None,
) -> Report:
    """Replace every :class:`DisplacedMesh` in ``scene`` by a displaced ``mi.Mesh`` (or the
    undisplaced, bump-mapped fallback beyond the ceiling), as the module docstring describes."""
    import time

    start = time.perf_counter()
    target_px = TARGET_EDGE_PX if target_px is None else target_px
    ceiling = MAX_TRIANGLES if ceiling is None else ceiling
    found = list(placeholders(scene))
    report = Report(meshes=len(found))
    counts = [len(m.triangles.faces) for _, _, m in found]
    wanted = [wanted_level(m, views, bounds, target_px) for _, _, m in found]
    levels = fit_levels(wanted, counts, ceiling)
    for (parent, key, item), want, level, count in zip(found, wanted, levels, counts, strict=True):
        report.triangles_in += count
        if want > 1 and level == 1:
            diag.warn(
                item.where,
                f"displacement tessellation ceiling ({ceiling:,} triangles) reached: rendered "
                f"undisplaced with {item.displacement.where}'s bump map instead",
            )
            parent[key] = to_mitsuba_mesh(item.triangles, item.fallback_bsdf, item.emitter)
            report.fallbacks += 1
            report.triangles_out += count
            continue
        if level < want:
            diag.warn(
                item.where,
                f"displacement tessellation ceiling ({ceiling:,} triangles) reached: edges of "
                f"about {target_px * want / level:.3g} px instead of {target_px:g} px",
            )
        moved = displace(
            tessellate(item.triangles, level), item.displacement, item.matrix_usd, item.tangents
        )
        if moved is None:
            diag.warn(
                item.where,
                f"{item.displacement.where}: a textured displacement needs texture coordinates, "
                "which the mesh lacks; rendered undisplaced with the bump map",
            )
            parent[key] = to_mitsuba_mesh(item.triangles, item.fallback_bsdf, item.emitter)
            report.fallbacks += 1
            report.triangles_out += count
            continue
        parent[key] = to_mitsuba_mesh(moved, item.bsdf, item.emitter)
        report.triangles_out += len(moved.faces)
    report.seconds = time.perf_counter() - start
    return report
