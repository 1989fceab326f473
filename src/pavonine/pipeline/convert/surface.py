"""The feather's base surface and the fields on it.

*Feather space* ``(u, v) ∈ [0, 1]²`` is the space the maps are read in: ``u`` left → right
across the image, ``v`` from the image's bottom row (the feather's base) to its top row (the
apex); see :func:`pavonine.base.map_files.sample_bilinear`. *Object space* is centimetres,
Y up along the feather, X across it, the iridescent front facing +Z:

    P(u, v) = ((u - ½) W,  v L,  -bend · max(v, 0)² - cup · (2u - 1)²)

with ``L`` the mapped length and ``W = L · aspect`` (pixels are square). The displaced vane is
``P + h · d(u, v) · n(u, v)``, ``d`` the displacement map and ``h`` the displacement height.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class FeatherFrame:
    """The base surface ``P(u, v)`` (module docstring) with its dimensions in centimetres."""

    length: float
    aspect: float
    bend: float
    cup: float

    @property
    def width(self) -> float:
        return self.length * self.aspect

    def position(self, uv: np.ndarray) -> np.ndarray:
        u, v = uv[:, 0], uv[:, 1]
        x = (u - 0.5) * self.width
        y = v * self.length
        z = -self.bend * np.maximum(v, 0.0) ** 2 - self.cup * (2.0 * u - 1.0) ** 2
        return np.stack([x, y, z], axis=1)

    def derivatives(self, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(∂P/∂u, ∂P/∂v)`` at each feather-space point."""
        u, v = uv[:, 0], uv[:, 1]
        dpdu = np.zeros((len(uv), 3))
        dpdu[:, 0] = self.width
        dpdu[:, 2] = -4.0 * self.cup * (2.0 * u - 1.0)
        dpdv = np.zeros((len(uv), 3))
        dpdv[:, 1] = self.length
        dpdv[:, 2] = -2.0 * self.bend * np.maximum(v, 0.0)
        return dpdu, dpdv

    def normal(self, uv: np.ndarray) -> np.ndarray:
        dpdu, dpdv = self.derivatives(uv)
        return normalise(np.cross(dpdu, dpdv))


def normalise(vectors: np.ndarray) -> np.ndarray:
    """Each row scaled to unit length (zero rows stay zero)."""
    norms = np.linalg.norm(vectors, axis=1, keepdims=True)
    return vectors / np.where(norms > 0, norms, 1.0)


def vertex_normals(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals (unit length)."""
    a, b, c = points[faces[:, 0]], points[faces[:, 1]], points[faces[:, 2]]
    face_normals = np.cross(b - a, c - a)  # length = 2·area: area weighting
    normals = np.zeros_like(points)
    for k in range(3):
        for axis in range(3):
            normals[:, axis] += np.bincount(
                faces[:, k], weights=face_normals[:, axis], minlength=len(points)
            )
    return normalise(normals)
