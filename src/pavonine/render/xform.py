"""``Xform`` hierarchies: world transforms at the render time code, in Mitsuba's convention.

USD matrices act on row vectors (``p' = p · M``, translation in the last row); Mitsuba's act on
column vectors (``p' = M · p``). The conversion is a transpose.
"""

from __future__ import annotations

import numpy as np
from pxr import Gf, Usd, UsdGeom


class TransformCache:
    """World and relative transforms of prims at one time code (wraps ``UsdGeom.XformCache``)."""

    def __init__(self, time: Usd.TimeCode):
        self.time = time
        self._cache = UsdGeom.XformCache(time)

    def world(self, prim: Usd.Prim) -> np.ndarray:
        """Local-to-world matrix of ``prim`` in USD (row-vector) layout, float64 4×4."""
        return np.array(self._cache.GetLocalToWorldTransform(prim), dtype=np.float64)

    def relative(self, prim: Usd.Prim, ancestor: Usd.Prim) -> np.ndarray:
        """Transform of ``prim`` relative to ``ancestor`` (USD layout); honours ``!resetXformStack!``."""
        matrix, _reset = self._cache.ComputeRelativeTransform(prim, ancestor)
        return np.array(matrix, dtype=np.float64)


def to_mitsuba(matrix_usd: np.ndarray | Gf.Matrix4d) -> np.ndarray:
    """A USD row-vector matrix as a Mitsuba column-vector matrix (the transpose)."""
    return np.array(matrix_usd, dtype=np.float64).T.copy()


def transform_points(points: np.ndarray, matrix_usd: np.ndarray) -> np.ndarray:
    """Points (N, 3) through a USD matrix (affine part; projective rows are not used by USD xforms)."""
    return points @ matrix_usd[:3, :3] + matrix_usd[3, :3]


def transform_directions(vectors: np.ndarray, matrix_usd: np.ndarray) -> np.ndarray:
    """Tangent-like directions (N, 3) through the linear part of a USD matrix, renormalised."""
    return normalize(vectors @ matrix_usd[:3, :3])


def transform_normals(normals: np.ndarray, matrix_usd: np.ndarray) -> np.ndarray:
    """Normals (N, 3) through the inverse transpose of the linear part, renormalised."""
    linear = matrix_usd[:3, :3]
    try:
        inverse_t = np.linalg.inv(linear).T
    except np.linalg.LinAlgError:
        return normalize(normals)
    return normalize(normals @ inverse_t)


def flips_handedness(matrix_usd: np.ndarray) -> bool:
    """True when the transform mirrors space (negative determinant): triangle winding must flip."""
    return bool(np.linalg.det(matrix_usd[:3, :3]) < 0.0)


def normalize(vectors: np.ndarray) -> np.ndarray:
    """Unit vectors; zero vectors stay zero."""
    length = np.linalg.norm(vectors, axis=-1, keepdims=True)
    return np.where(length > 0, vectors / np.where(length > 0, length, 1.0), 0.0)


def usable_transform(matrix_usd: np.ndarray, bound: float) -> bool:
    """The matrix is finite and its entries within ±``bound`` (see :mod:`pavonine.render.limits`)."""
    return bool(np.all(np.isfinite(matrix_usd)) and np.all(np.abs(matrix_usd) <= bound))


def transform_source(prim: Usd.Prim, time: Usd.TimeCode, bound: float) -> str:
    """``/prim.xformOp:…`` of the nearest op (on ``prim`` or an ancestor) with a value that is NaN,
    infinite or beyond ±``bound``: what to name when a world transform is unusable."""
    while prim and not prim.IsPseudoRoot():
        xformable = UsdGeom.Xformable(prim)
        if xformable:
            for op in xformable.GetOrderedXformOps():
                value = op.Get(time)
                try:
                    array = np.asarray(value, dtype=np.float64)
                except (TypeError, ValueError):
                    continue
                if not np.all(np.isfinite(array)) or np.any(np.abs(array) > bound):
                    return f"{prim.GetPath()}.{op.GetOpName()}"
        prim = prim.GetParent()
    return "its xformOps"
