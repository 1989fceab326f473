"""Ribbon ``BasisCurves`` as triangle meshes, for hosts with no ribbons (glTF, the portable USD).

USD draws a curve with authored ``normals`` as a ribbon facing them (UsdGeom, "Tubes and
Ribbons"): at each point the ribbon spans ``width`` across ``normal × tangent``. The triangles are
the ones Pavonine's renderer draws for such curves, its plain ribbon (the authored width, no
barbules): each segment evaluated in its basis (linear: its two ends; cubic: a few steps), two
vertices across each sample, two triangles per piece, wound counter-clockwise seen from the side
the normals point to, the curves' primvars carried to the vertices (``vertex``) and triangles
(``uniform``). The pipeline does not import the renderer (pipeline and render stand side by side,
docs/house.md): the application hands the exporters the renderer's tessellation,
:func:`pavonine.render.curves.ribbons.plain_ribbons`, as a :data:`Tessellate`, so every host gets
the renderer's own vertices and there is one implementation.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

#: A ribbon ``BasisCurves`` prim → the renderer's plain ribbon surface (``topology.points``,
#: ``topology.face_vertex_indices`` of triangles, vertex ``normals``, carried ``primvars``), or
#: None when the prim is not ribbons: :func:`pavonine.render.curves.ribbons.plain_ribbons`.
Tessellate = Callable[[Any], Any]


@dataclass
class RibbonMesh:
    """Triangles of ribbons, in the curves' object space."""

    points: np.ndarray  # (n, 3)
    normals: np.ndarray  # (n, 3) per vertex: the ribbon's normal made perpendicular to the curve
    triangles: np.ndarray  # (m, 3) uint32


def ribbon_prim_mesh(prim, tessellate: Tessellate) -> tuple[RibbonMesh, np.ndarray | None] | None:
    """The ribbon mesh of a ``BasisCurves`` prim with authored ``normals`` (and its per-vertex
    ``displayColor``, linear, or None), as ``tessellate`` draws it; None for curves that are not
    ribbons (tubes) or have no renderable curve."""
    surface = tessellate(prim)
    if surface is None:
        return None
    mesh = RibbonMesh(
        surface.topology.points,
        surface.normals.values,
        surface.topology.face_vertex_indices.reshape(-1, 3).astype(np.uint32),
    )
    colour = surface.primvars.get("displayColor")
    if colour is None or colour.interpolation != "vertex":
        return mesh, None
    return mesh, np.asarray(colour.values, dtype=np.float64)


def vertex_colour_material(out, material, name: str) -> int:
    """A glTF material for geometry whose colour is its ``COLOR_0`` (the barbs' displayColor):
    white base colour factor, the preview surface's roughness and metallic constants."""
    gl = out.gl
    shader = None
    if material:
        source = material.ComputeSurfaceSource()[0]
        shader = source if source else None

    def constant(input_name: str, fallback: float) -> float:
        inp = shader.GetInput(input_name) if shader else None
        value = inp.Get() if inp and not inp.HasConnectedSource() else None
        return float(fallback if value is None else value)

    out.doc.materials.append(
        gl.Material(
            name=name,
            pbrMetallicRoughness=gl.PbrMetallicRoughness(
                baseColorFactor=[1.0, 1.0, 1.0, 1.0],
                metallicFactor=constant("metallic", 0.0),
                roughnessFactor=constant("roughness", 0.5),
            ),
            doubleSided=True,
        )
    )
    return len(out.doc.materials) - 1
