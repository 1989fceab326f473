"""Implicit prims → tessellated :class:`~pavonine.render.mesh.Surface` objects.

``Cube``, ``Sphere``, ``Cylinder``, ``Cylinder_1``, ``Cone``, ``Capsule``, ``Capsule_1`` and ``Plane``
as the UsdGeom schema defines them (sizes, radii, heights, ``axis``; centred at the origin), as
polygon meshes in object space that then go through the mesh translator (materials, primvars,
``doubleSided``, transforms, instancing). Curved parts get exact per-corner normals and
:data:`SEGMENTS` segments around the axis: the silhouette of a sphere is within 0.05 % of its
radius (``1 − cos(π/96)``), below a pixel at any size this renderer is used at.

Surfaces of revolution are swept from a profile in the (r, z) half-plane running counter-clockwise
around the solid (bottom centre → rim → top), so that faces wind outwards. Capsule caps are the
spherical caps tangent to the side (``Capsule_1``: "C1 continuity" between caps and side).

Each prim's primvars are read as on meshes; the ``Cube`` is the 8-point, 6-quad mesh Hydra uses, so
its ``uniform`` and ``vertex`` primvars apply; on the other shapes only ``constant`` (and
``faceVarying``/``vertex`` primvars that happen to have the tessellation's count) can apply, and
the mesh translator warns about the rest.
"""

from __future__ import annotations

import math

import numpy as np
from pxr import Usd

from pavonine.render import attributes
from pavonine.render.diagnostics import Diagnostics
from pavonine.render.mesh import Surface, double_sided, make_topology
from pavonine.render.primvars import Primvar, read_primvars

SEGMENTS = 96  # around the axis
RINGS = 48  # pole to pole on a sphere (fewer on partial caps)
IMPLICIT = ("Cube", "Sphere", "Cylinder", "Cylinder_1", "Cone", "Capsule", "Capsule_1", "Plane")
AXES = ("Z", "X", "Y")  # the schema fallback first
# local (a, b, c), c along the axis → world: cyclic permutations, so rotations (winding kept)
AXIS_PERMUTATION = {"Z": [0, 1, 2], "X": [2, 0, 1], "Y": [1, 2, 0]}


def is_implicit(prim: Usd.Prim) -> bool:
    """True for the implicit surfaces this module tessellates."""
    return prim.GetTypeName() in IMPLICIT


def implicit_surface(prim: Usd.Prim, time: Usd.TimeCode, diag: Diagnostics) -> Surface | None:
    """The prim's tessellation, or ``None`` (with a warning) when its attributes make no surface."""
    kind = prim.GetTypeName()
    built = _GENERATORS[kind](prim, time, diag)
    if built is None:
        return None
    points, counts, indices, normals = built
    if len(points) == 0:  # every ring collapsed onto the axis (a radius like 1e-38)
        diag.warn(str(prim.GetPath()), "its sizes are too small to tessellate; skipped")
        return None
    topology = make_topology(points, counts, indices, False, str(prim.GetPath()), diag)
    if topology is None:
        return None
    return Surface(
        prim,
        topology,
        normals=Primvar(normals, "faceVarying", "Normal"),
        primvars=read_primvars(prim, time, diag),
        double_sided=double_sided(prim, time, diag),
    )


# -- generators: (points, faceVertexCounts, faceVertexIndices, faceVarying normals) -----------------

Mesh = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def cube(prim: Usd.Prim, time: Usd.TimeCode, diag: Diagnostics) -> Mesh | None:
    """``Cube``: edge ``size`` (fallback 2), 8 points, 6 quads with flat normals."""
    size = attributes.real(prim, "size", time, diag, 2.0, positive=True)
    if size is None:
        return None
    h = size / 2.0
    points = h * np.array(
        [
            [1, 1, 1],
            [-1, 1, 1],
            [-1, -1, 1],
            [1, -1, 1],
            [-1, -1, -1],
            [-1, 1, -1],
            [1, 1, -1],
            [1, -1, -1],
        ],
        dtype=np.float64,
    )
    quads = np.array(
        [[0, 1, 2, 3], [4, 5, 6, 7], [0, 6, 5, 1], [4, 7, 3, 2], [0, 3, 7, 6], [4, 2, 1, 5]]
    )
    normals = np.repeat(
        np.array([[0, 0, 1], [0, 0, -1], [0, 1, 0], [0, -1, 0], [1, 0, 0], [-1, 0, 0]], float),
        4,
        axis=0,
    )
    return points, np.full(6, 4), quads.ravel(), normals


def sphere(prim: Usd.Prim, time: Usd.TimeCode, diag: Diagnostics) -> Mesh | None:
    """``Sphere``: ``radius`` (fallback 1)."""
    radius = attributes.real(prim, "radius", time, diag, 1.0, positive=True)
    if radius is None:
        return None
    theta = np.linspace(-math.pi / 2, math.pi / 2, RINGS + 1)
    profile = [
        (radius * math.cos(t), radius * math.sin(t), math.cos(t), math.sin(t)) for t in theta
    ]
    return revolve([profile], "Z")


def cylinder(prim: Usd.Prim, time: Usd.TimeCode, diag: Diagnostics) -> Mesh | None:
    """``Cylinder`` (``radius``) and ``Cylinder_1`` (``radiusBottom``/``radiusTop``), capped."""
    height = attributes.real(prim, "height", time, diag, 2.0, positive=True)
    bottom, top = _radii(prim, time, diag, fallback=1.0)
    if height is None or bottom is None or top is None:
        return None
    z0, z1 = -height / 2.0, height / 2.0
    slope = math.atan2(bottom - top, height)  # side normal tilts up when the top is narrower
    side = (math.cos(slope), math.sin(slope))
    parts = [
        [(0.0, z0, 0.0, -1.0), (bottom, z0, 0.0, -1.0)],
        [(bottom, z0, *side), (top, z1, *side)],
        [(top, z1, 0.0, 1.0), (0.0, z1, 0.0, 1.0)],
    ]
    return revolve([p for p in parts if p[0][0] > 0 or p[1][0] > 0], _axis(prim, time, diag))


def cone(prim: Usd.Prim, time: Usd.TimeCode, diag: Diagnostics) -> Mesh | None:
    """``Cone``: base ``radius`` at −height/2, apex at +height/2, base capped."""
    height = attributes.real(prim, "height", time, diag, 2.0, positive=True)
    radius = attributes.real(prim, "radius", time, diag, 1.0, positive=True)
    if height is None or radius is None:
        return None
    z0, z1 = -height / 2.0, height / 2.0
    slope = math.atan2(radius, height)
    side = (math.cos(slope), math.sin(slope))
    parts = [
        [(0.0, z0, 0.0, -1.0), (radius, z0, 0.0, -1.0)],
        [(radius, z0, *side), (0.0, z1, *side)],
    ]
    return revolve(parts, _axis(prim, time, diag))


def capsule(prim: Usd.Prim, time: Usd.TimeCode, diag: Diagnostics) -> Mesh | None:
    """``Capsule`` (``radius``, fallback 0.5) and ``Capsule_1`` (``radiusBottom``/``radiusTop``).

    ``height`` (fallback 1) is the distance between the two cap centres. With radii r₀, r₁ the
    side's outward normal makes the angle α = asin((r₀ − r₁)/height) with the radial direction;
    each cap is its sphere's arc from the pole to that angle, so caps and side are tangent.
    """
    height = attributes.real(prim, "height", time, diag, 1.0, minimum=0.0)
    bottom, top = _radii(prim, time, diag, fallback=0.5)
    if height is None or bottom is None or top is None:
        return None
    z0, z1 = -height / 2.0, height / 2.0
    if abs(bottom - top) >= height:
        diag.warn(
            str(prim.GetPath()),
            "the radii differ by more than the height: the larger cap encloses the smaller; "
            "rendered as the larger sphere",
        )
        r, z = (bottom, z0) if bottom >= top else (top, z1)
        theta = np.linspace(-math.pi / 2, math.pi / 2, RINGS + 1)
        profile = [(r * math.cos(t), z + r * math.sin(t), math.cos(t), math.sin(t)) for t in theta]
        return revolve([profile], _axis(prim, time, diag))
    alpha = math.asin((bottom - top) / height) if height > 0 else 0.0
    low = np.linspace(
        -math.pi / 2, alpha, max(2, round(RINGS / 2 * (alpha + math.pi / 2) / math.pi * 2))
    )
    high = np.linspace(
        alpha, math.pi / 2, max(2, round(RINGS / 2 * (math.pi / 2 - alpha) / math.pi * 2))
    )
    profile = [
        (bottom * math.cos(t), z0 + bottom * math.sin(t), math.cos(t), math.sin(t)) for t in low
    ]
    profile += [(top * math.cos(t), z1 + top * math.sin(t), math.cos(t), math.sin(t)) for t in high]
    return revolve([profile], _axis(prim, time, diag))


def plane(prim: Usd.Prim, time: Usd.TimeCode, diag: Diagnostics) -> Mesh | None:
    """``Plane``: ``width`` × ``length`` (fallback 2 × 2), facing +``axis``.

    Width lies along x for axis Z or Y and along z for axis X; length along y for axis Z or X and
    along z for axis Y (UsdGeomPlane).
    """
    width = attributes.real(prim, "width", time, diag, 2.0, positive=True)
    length = attributes.real(prim, "length", time, diag, 2.0, positive=True)
    if width is None or length is None:
        return None
    axis = _axis(prim, time, diag)
    half_w, half_l = width / 2.0, length / 2.0
    # in-plane axes (u along width, v along length) with u × v = +axis
    u, v = {"Z": (0, 1), "X": (2, 1), "Y": (0, 2)}[axis]
    normal_index = "XYZ".index(axis)
    corners = [(-half_w, -half_l), (half_w, -half_l), (half_w, half_l), (-half_w, half_l)]
    points = np.zeros((4, 3))
    for i, (a, b) in enumerate(corners):
        points[i, u], points[i, v] = a, b
    normal = np.zeros(3)
    normal[normal_index] = 1.0
    e1, e2 = points[1] - points[0], points[3] - points[0]
    quad = np.arange(4) if np.dot(np.cross(e1, e2), normal) > 0 else np.array([0, 3, 2, 1])
    return points, np.array([4]), quad, np.tile(normal, (4, 1))


def revolve(parts: list[list[tuple[float, float, float, float]]], axis: str) -> Mesh:
    """Sweep profiles ``[(r, z, n_r, n_z), ...]`` around the axis in :data:`SEGMENTS` segments.

    Each part is swept on its own (hard edges between parts); consecutive profile points make a
    ring of quads, or triangles where the profile touches the axis (r = 0).
    """
    phi = np.linspace(0.0, 2.0 * math.pi, SEGMENTS + 1)[:-1]
    mid = phi + math.pi / SEGMENTS
    points, counts, indices, normals = [], [], [], []
    base = 0
    scale = max(abs(v) for part in parts for point in part for v in point[:2])
    for part in parts:
        profile = np.asarray(part, dtype=np.float64)
        profile[np.abs(profile[:, 0]) < 1e-12 * scale, 0] = 0.0  # on the axis (cos 90° ≠ 0)
        for i in range(len(profile) - 1):
            (r0, z0, nr0, nz0), (r1, z1, nr1, nz1) = profile[i], profile[i + 1]
            if r0 <= 0 and r1 <= 0:
                continue
            for j in range(SEGMENTS):
                a, b = phi[j], phi[(j + 1) % SEGMENTS]
                ring = [
                    (r0, z0, nr0, nz0, a),
                    (r0, z0, nr0, nz0, b),
                    (r1, z1, nr1, nz1, b),
                    (r1, z1, nr1, nz1, a),
                ]
                if r0 <= 0:
                    ring = [ring[0], ring[2], ring[3]]
                elif r1 <= 0:
                    ring = ring[:3]
                for r, z, nr, nz, angle in ring:
                    normal_angle = mid[j] if r <= 0 else angle  # at the axis: the face's mid angle
                    points.append((r * math.cos(angle), r * math.sin(angle), z))
                    normals.append((nr * math.cos(normal_angle), nr * math.sin(normal_angle), nz))
                counts.append(len(ring))
                indices.extend(range(base, base + len(ring)))
                base += len(ring)
    perm = AXIS_PERMUTATION[axis]  # world[:, k] = local[:, perm[k]]
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)[:, perm]
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)[:, perm]
    return p, np.asarray(counts), np.asarray(indices), n


def _axis(prim: Usd.Prim, time: Usd.TimeCode, diag: Diagnostics) -> str:
    return attributes.token(prim, "axis", time, diag, AXES)


def _radii(
    prim: Usd.Prim, time: Usd.TimeCode, diag: Diagnostics, fallback: float
) -> tuple[float | None, float | None]:
    """(bottom, top) radii: ``radius`` for Cylinder/Capsule, ``radiusBottom``/``radiusTop`` for *_1."""
    if prim.GetTypeName().endswith("_1"):
        bottom = attributes.real(prim, "radiusBottom", time, diag, fallback, minimum=0.0)
        top = attributes.real(prim, "radiusTop", time, diag, fallback, minimum=0.0)
        if bottom is not None and top is not None and bottom == 0 and top == 0:
            diag.warn(str(prim.GetPath()), "radiusBottom and radiusTop are both 0; skipped")
            return None, None
        return bottom, top
    radius = attributes.real(prim, "radius", time, diag, fallback, positive=True)
    return radius, radius


_GENERATORS = {
    "Cube": cube,
    "Sphere": sphere,
    "Cylinder": cylinder,
    "Cylinder_1": cylinder,
    "Cone": cone,
    "Capsule": capsule,
    "Capsule_1": capsule,
    "Plane": plane,
}
