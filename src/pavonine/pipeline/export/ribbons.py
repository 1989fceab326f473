"""Ribbon ``BasisCurves`` as triangle meshes, for hosts with no ribbons (glTF, the portable USD).

USD draws a curve with authored ``normals`` as a ribbon facing them (UsdGeom, "Tubes and
Ribbons"): at each point the ribbon spans ``width`` across ``normal × tangent``. The triangles are
the ones Pavonine's renderer draws for such curves
(:func:`pavonine.render.curves.ribbons.ribbon_surface`, its plain ribbon: the authored width, no
barbules), so every host gets the renderer's own geometry, not a second tessellation: each
segment evaluated in its basis (linear: its two ends; cubic: a few steps), two vertices across
each sample, two triangles per piece, wound counter-clockwise seen from the side the normals
point to, the curves' primvars carried to the vertices (``vertex``) and triangles (``uniform``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class RibbonMesh:
    """Triangles of ribbons, in the curves' object space."""

    points: np.ndarray  # (n, 3)
    normals: np.ndarray  # (n, 3) per vertex: the ribbon's normal made perpendicular to the curve
    triangles: np.ndarray  # (m, 3) uint32


def ribbon_prim_surface(prim):
    """The renderer's plain ribbon surface (:class:`pavonine.render.mesh.Surface`) of a
    ``BasisCurves`` prim with authored ``normals`` at the default time; None for curves that
    are not ribbons (tubes) or have no renderable curve."""
    from pxr import Usd

    from pavonine.render.curves.ribbons import has_normals, ribbon_surface
    from pavonine.render.diagnostics import Diagnostics

    if not has_normals(prim):
        return None
    return ribbon_surface(prim, Usd.TimeCode.Default(), Diagnostics(), barbules=False)


def ribbon_prim_mesh(prim) -> tuple[RibbonMesh, np.ndarray | None] | None:
    """The ribbon mesh of a ``BasisCurves`` prim with authored ``normals`` (and its per-vertex
    ``displayColor``, linear, or None); None for curves that are not ribbons
    (:func:`ribbon_prim_surface`)."""
    surface = ribbon_prim_surface(prim)
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
