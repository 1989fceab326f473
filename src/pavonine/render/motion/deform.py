"""Skinned meshes moved by their points alone: the fast path of a frame's or a slice's move.

A mesh that only a skeleton deforms keeps, from one time to the next, its topology, its primvars,
its material groups and the split of its points into Mitsuba vertices; what changes are its
points and the normals smoothed from them (``mesh.with_points``). Translating it again from USD
reads and splits all of that anew (most of a moved frame's sync on the rattle shot). A
:class:`PointsMove` keeps, for each Mitsuba mesh of the prim, the surface point each vertex is
(``TriangleMesh.point_of_vertex``) and the prim's transform within its prototype, and moves the
vertices from the skinned points with the translation's own functions (``transform_points``,
``smooth_normals``, ``transform_normals``): the same arrays, bit for bit. :func:`learn` makes one
only where that holds at the plan's own time (checked there, on the arrays the translation
made); a prim it declines is translated again at every move, as before.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from pxr import Usd

from pavonine.render.mesh import Topology, smooth_normals
from pavonine.render.xform import transform_normals, transform_points


@dataclass
class PointsMove:
    """How one skinned prim's meshes follow its points (module docstring)."""

    topology: Topology  # the surface as translated (its points replaced at each move)
    #: per Mitsuba mesh of the prim: (surface point of each vertex, prim-to-prototype matrix,
    #: whether the mesh has vertex normals)
    meshes: list[tuple[np.ndarray, np.ndarray, bool]]

    def arrays(self, points: np.ndarray) -> list[tuple[np.ndarray, np.ndarray | None]] | None:
        """Each mesh's ``(positions, normals)`` (float32) at the skinned ``points`` (the prim's
        local space, as :mod:`pavonine.render.skel` gives them); ``None`` when a normal
        degenerates (zero area: the translation would mend it with face normals, so the prim is
        translated)."""
        if len(points) != len(self.topology.points):
            return None
        moved = replace(self.topology, points=np.asarray(points, dtype=np.float64))
        normals = smooth_normals(moved).values if any(n for *_, n in self.meshes) else None
        out = []
        for source, matrix, has_normals in self.meshes:
            positions = transform_points(moved.points[source], matrix).astype(np.float32)
            if not has_normals:
                out.append((positions, None))
                continue
            turned = transform_normals(normals[source], matrix)
            if np.any(np.linalg.norm(turned, axis=1) < 0.5):
                return None
            out.append((positions, turned.astype(np.float32)))
        return out


def learner(delegate):
    """A view of ``delegate`` at its own time that records what it translates (for :func:`learn`;
    one per plan: making it skins the stage)."""
    view = delegate.at_time(delegate.time)
    view.recorded = {}
    return view


def learn(view, root: Usd.Prim, prim: Usd.Prim) -> PointsMove | None:
    """A :class:`PointsMove` for ``prim`` inside the prototype ``root`` when a skeleton alone
    deforms it (skinned points, no subdivision) and it reproduces the translation's arrays at the
    time of ``view`` (:func:`learner`) exactly; else ``None``."""
    path = str(prim.GetPath())
    skinned = view.skinning.points.get(path)
    if skinned is None or prim.GetTypeName() != "Mesh":
        return None
    view.prototype_prim_shapes(root, prim)
    made = view.recorded.get(path, [])
    if not made or any(t.point_of_vertex is None for _, t, _ in made):
        return None
    surface = made[0][0]
    if any(s is not surface for s, _, _ in made) or surface.topology.points is None:
        return None
    move = PointsMove(
        surface.topology,
        [(t.point_of_vertex, m, t.normals is not None) for _, t, m in made],
    )
    arrays = move.arrays(skinned)
    if arrays is None:
        return None
    for (positions, normals), (_, triangles, _) in zip(arrays, made, strict=True):
        if not np.array_equal(positions, triangles.positions):
            return None
        if (normals is None) != (triangles.normals is None):
            return None
        if normals is not None and not np.array_equal(normals, triangles.normals):
            return None
    return move
