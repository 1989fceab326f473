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

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from pavonine.base.map_files import FILTER_MODES, sample_bilinear


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


#: Blur width (σ, texels) per texel of a map reduced before :func:`prefilter` blurs it: a blur
#: of σ ≥ 16 texels keeps nothing a map reduced to σ / 8 of its texels does not hold.
REDUCED_SIGMA = 8.0


def prefilter(values: np.ndarray, spacing_uv: float, wrap: str = "clamp") -> np.ndarray:
    """Low-pass a map to a mesh whose vertices are ``spacing_uv`` (feather v units) apart,
    so displacement sampled at vertices does not alias (Gaussian, σ = ½ vertex spacing).
    ``wrap``: how the map continues beyond its edges (:data:`~pavonine.base.map_files.FILTER_MODES`).
    A wide blur is done on a reduced map (:func:`gaussian_blur`): the result may then be smaller
    than ``values``; sample it by feather coordinates (:func:`sample_bilinear`)."""
    sigma = 0.5 * spacing_uv * values.shape[0]
    if sigma < 0.5:
        return values
    return gaussian_blur(values, sigma, FILTER_MODES[wrap])


def gaussian_blur(values: np.ndarray, sigma: float, mode: str = "reflect") -> np.ndarray:
    """``ndimage.gaussian_filter(values, sigma, mode=mode)``, of the same extent but possibly
    fewer texels: a wide blur (σ ≥ 2 · :data:`REDUCED_SIGMA` texels: a coarse mesh, or a barb
    spacing, on a big map) is done on the map box-reduced by the largest power of two
    ``f ≤ σ / REDUCED_SIGMA`` with ``σ' = √(σ² − (f² − 1)/12) / f``, the box's own variance taken
    off: the same blur within a fraction of a texel for ``f³`` times less work (``f²`` fewer
    texels, ``f`` times fewer taps each). Sample the result by feather coordinates."""
    from pavonine.base.map_files import area_reduce

    factor = 1
    while factor * 2 <= sigma / REDUCED_SIGMA and min(values.shape[:2]) // (factor * 2) >= 8:
        factor *= 2
    if factor > 1:
        values = area_reduce(values, factor)
        sigma = math.sqrt(sigma**2 - (factor**2 - 1) / 12.0) / factor
    return ndimage.gaussian_filter(values, sigma, mode=mode)


def displacement_heights(
    values: np.ndarray, uv: np.ndarray, height: float, spacing_uv: float, wrap: str = "clamp"
) -> np.ndarray:
    """``h · d(u, v)`` (module docstring): the map ``values`` (H×W) low-passed to the vertex
    ``spacing_uv`` (:func:`prefilter`) and read bilinearly at ``uv`` (feather space, v up), times
    the displacement height ``height``. The one formula for the converter's baked vane and the
    renderer's displacement at render time (:mod:`pavonine.render.displacement`)."""
    return float(height) * sample_bilinear(prefilter(values, spacing_uv, wrap), uv, wrap)
