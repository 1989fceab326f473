"""The data maps low-passed as every reader samples them: the one implementation for the
converter's baked vane and barbs and the renderer's displacement at render time.

Maps are read in feather space (:func:`pavonine.base.map_files.sample_bilinear`); the filters
here are Gaussian low-passes sized to the spacing they are sampled at.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from pavonine.base.map_files import FILTER_MODES, area_reduce, sample_bilinear

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
    """``h · d(u, v)`` (``h`` the displacement height, ``d`` the map): the map ``values`` (H×W) low-passed to the vertex
    ``spacing_uv`` (:func:`prefilter`) and read bilinearly at ``uv`` (feather space, v up), times
    the displacement height ``height``. The one formula for the converter's baked vane and the
    renderer's displacement at render time (:mod:`pavonine.render.displacement`); ``convert``'s vane is ``P + h · d(u, v) · n(u, v)``
    (:mod:`pavonine.pipeline.convert.surface`)."""
    return float(height) * sample_bilinear(prefilter(values, spacing_uv, wrap), uv, wrap)
