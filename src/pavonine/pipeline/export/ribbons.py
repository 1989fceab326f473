"""Ribbon ``BasisCurves`` as triangle meshes, for formats with no curves (glTF).

USD draws a curve with authored ``normals`` as a ribbon facing them (UsdGeom, "Tubes and
Ribbons"): at each vertex the ribbon spans ``width`` across ``normal × tangent``. A linear
curve of ``k`` vertices becomes ``2k`` vertices (one on each edge) and ``2(k − 1)`` triangles,
wound counter-clockwise seen from the side the normals point to; vertex data (the
``displayColor``) are repeated on both edges.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pavonine.pipeline.convert.barb_curves import polyline_tangents


@dataclass
class RibbonMesh:
    """Triangles of ribbons: ``source[i]`` is the curve vertex mesh vertex ``i`` came from."""

    points: np.ndarray  # (2n, 3)
    normals: np.ndarray  # (2n, 3)
    triangles: np.ndarray  # (m, 3) uint32
    source: np.ndarray  # (2n,)


def _unit(vectors: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(vectors, axis=1, keepdims=True)
    return vectors / np.where(norm > 1e-20, norm, 1.0)


def ribbon_mesh(
    points: np.ndarray, normals: np.ndarray, widths: np.ndarray, counts: np.ndarray
) -> RibbonMesh:
    """The triangles of linear ribbons (module docstring); ``normals`` and ``widths`` per
    vertex."""
    points = np.asarray(points, dtype=np.float64)
    counts = np.asarray(counts, dtype=np.int64)
    normals = _unit(np.asarray(normals, dtype=np.float64))
    tangent = polyline_tangents(points, counts)
    side = _unit(np.cross(normals, tangent))
    half = 0.5 * np.asarray(widths, dtype=np.float64)[:, None] * side
    n = len(points)
    mesh_points = np.empty((2 * n, 3))
    mesh_points[0::2] = points - half
    mesh_points[1::2] = points + half
    last = np.zeros(n, dtype=bool)
    last[np.cumsum(counts) - 1] = True
    a = np.nonzero(~last)[0]  # each segment from vertex a to a + 1
    left, right = 2 * a, 2 * a + 1
    triangles = np.concatenate(
        [np.stack([left, left + 2, right], 1), np.stack([right, left + 2, right + 2], 1)]
    )
    return RibbonMesh(
        mesh_points,
        np.repeat(normals, 2, axis=0),
        triangles.astype(np.uint32),
        np.repeat(np.arange(n), 2),
    )


def ribbon_prim_mesh(prim) -> tuple[RibbonMesh, np.ndarray | None] | None:
    """The ribbon mesh of a ``BasisCurves`` prim with authored ``normals`` (and its per-vertex
    ``displayColor``, linear, or None); None for curves that are not ribbons (tubes) or not
    linear (this exporter tessellates polylines only)."""
    from pxr import UsdGeom

    curves = UsdGeom.BasisCurves(prim)
    normals = curves.GetNormalsAttr().Get()
    if not normals or curves.GetTypeAttr().Get() != UsdGeom.Tokens.linear:
        return None
    points = np.array(curves.GetPointsAttr().Get(), dtype=np.float64)
    counts = np.array(curves.GetCurveVertexCountsAttr().Get(), dtype=np.int64)
    widths = np.array(curves.GetWidthsAttr().Get() or [], dtype=np.float64)
    if len(widths) != len(points):
        widths = np.full(len(points), widths[0] if len(widths) else 1.0)
    normals = np.array(normals, dtype=np.float64)
    if len(normals) != len(points):
        normals = np.repeat(normals[:1], len(points), axis=0)
    mesh = ribbon_mesh(points, normals, widths, counts)
    colour = UsdGeom.PrimvarsAPI(prim).GetPrimvar("displayColor")
    values = np.array(colour.ComputeFlattened(), dtype=np.float64) if colour else None
    if values is None or len(values) != len(points):
        return mesh, None
    return mesh, values[mesh.source]


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
