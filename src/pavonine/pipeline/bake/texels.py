"""The surface behind every texel of the ``st`` atlas: which triangle covers it, and the
feather coordinate, normal, barb direction and feather "+u" direction there.

Triangles are rasterised at the atlas resolution (texel centres, :func:`rasterise`); per-vertex
data are interpolated with the texel's barycentric weights. Texels no triangle covers (gutters
between charts, other meshes' charts) are filled afterwards with their nearest covered texel
(:func:`dilate`), so bilinear filtering and mipmaps never pull in an undefined colour at a seam.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from pavonine.pipeline.convert.atlas import rasterise, st_to_pixels
from pavonine.pipeline.convert.mesh import MeshData


@dataclass
class SurfaceTexels:
    """Surface samples at the covered texels of a ``resolution²`` atlas image (row 0 = top).

    ``index``: flat texel indices (``row · resolution + column``); the other arrays have one
    row per covered texel: ``feather_uv`` (map coordinates), unit ``normal``, unit
    ``barb`` (barb direction in the surface), unit ``across`` (the feather's +u direction,
    ``∂P/∂u``, in the surface) and, where known, the surface point ``position`` (the mesh's
    space and units).
    """

    resolution: int
    index: np.ndarray
    feather_uv: np.ndarray
    normal: np.ndarray
    barb: np.ndarray
    across: np.ndarray
    position: np.ndarray | None = None

    @property
    def covered(self) -> np.ndarray:
        """Boolean ``resolution²`` image of the texels a triangle covers."""
        mask = np.zeros(self.resolution * self.resolution, dtype=bool)
        mask[self.index] = True
        return mask.reshape(self.resolution, self.resolution)


def _unit(vectors: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(vectors, axis=-1, keepdims=True)
    return vectors / np.where(norm > 1e-20, norm, 1.0)


def _in_surface(vectors: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """``vectors`` projected into the plane perpendicular to ``normal``, unit length."""
    return _unit(vectors - np.sum(vectors * normal, axis=-1, keepdims=True) * normal)


def feather_u_directions(
    points: np.ndarray, faces: np.ndarray, feather_uv: np.ndarray
) -> np.ndarray:
    """``∂P/∂u`` per triangle from positions and feather coordinates (Lengyel 2001,
    "Computing tangent space basis vectors"): ``(Δv₂ e₁ − Δv₁ e₂) / (Δu₁ Δv₂ − Δu₂ Δv₁)``."""
    p = points[faces]
    t = feather_uv[faces]
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    d1, d2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    safe = np.where(np.abs(det) > 1e-20, det, 1.0)
    dpdu = (d2[:, 1, None] * e1 - d1[:, 1, None] * e2) / safe[:, None]
    return np.where(np.abs(det)[:, None] > 1e-20, dpdu, 0.0)


def surface_texels(mesh: MeshData, resolution: int) -> SurfaceTexels:
    """Rasterise ``mesh`` (its face-varying ``st``) into a ``resolution²`` atlas image."""
    corners = mesh.st_values[mesh.st_indices.reshape(-1, 3)]
    coverage = rasterise(st_to_pixels(corners, resolution, resolution), resolution, resolution)
    # One triangle per texel (a valid atlas has no overlaps; keep the last if one does).
    _, last = np.unique(coverage.texel[::-1], return_index=True)
    keep = len(coverage.texel) - 1 - last
    texel, triangle = coverage.texel[keep], coverage.triangle[keep]
    weights = coverage.barycentric[keep]
    vertices = mesh.faces[triangle]  # (n, 3) welded vertex indices

    def interpolate(values: np.ndarray) -> np.ndarray:
        return np.einsum("nk,nkc->nc", weights, values[vertices])

    normal = _unit(interpolate(mesh.normals))
    across = feather_u_directions(mesh.points, mesh.faces, mesh.feather_uv)[triangle]
    return SurfaceTexels(
        resolution=resolution,
        index=texel,
        feather_uv=np.clip(interpolate(mesh.feather_uv), 0.0, 1.0),
        normal=normal,
        barb=_in_surface(interpolate(mesh.barb_tangent), normal),
        across=_in_surface(across, normal),
        position=interpolate(mesh.points),
    )


def scatter(texels: SurfaceTexels, values: np.ndarray, fill: float = 0.0) -> np.ndarray:
    """Per-texel ``values`` (``(n,)`` or ``(n, c)``) as a ``resolution²`` image (``fill`` elsewhere)."""
    values = np.asarray(values, dtype=np.float32)
    shape = (texels.resolution * texels.resolution, *values.shape[1:])
    image = np.full(shape, fill, dtype=np.float32)
    image[texels.index] = values
    return image.reshape(texels.resolution, texels.resolution, *values.shape[1:])


def nearest_covered(covered: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For every texel, the (row, column) of its nearest covered texel (itself if covered)."""
    if covered.all() or not covered.any():
        return np.indices(covered.shape)
    _, (rows, cols) = ndimage.distance_transform_edt(~covered, return_indices=True)
    return rows, cols


def dilate(image: np.ndarray, nearest: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """``image`` with every texel replaced by its nearest covered texel's value
    (``nearest`` from :func:`nearest_covered`): covered texels keep theirs."""
    rows, cols = nearest
    return image[rows, cols]
