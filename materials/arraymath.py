"""The few array operations the BRDF needs, for NumPy (analysis) and Dr.Jit (Mitsuba renderer).

The feather BRDF (:mod:`pavonine.materials.brdf`) is written once against this small interface,
so the analysis model and the renderer's JIT-compiled BSDF run the *same* code.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy import special


class NumpyOps:
    """NumPy implementation (float64, broadcasting)."""

    sqrt = staticmethod(np.sqrt)
    exp = staticmethod(np.exp)
    sin = staticmethod(np.sin)
    cos = staticmethod(np.cos)
    tan = staticmethod(np.tan)
    abs = staticmethod(np.abs)
    floor = staticmethod(np.floor)
    maximum = staticmethod(np.maximum)
    minimum = staticmethod(np.minimum)
    select = staticmethod(np.where)
    erf = staticmethod(special.erf)

    @staticmethod
    def asarray(x: Any) -> np.ndarray:
        return np.asarray(x, dtype=np.float64)

    @staticmethod
    def gather(table: np.ndarray, index: Any) -> np.ndarray:
        return np.asarray(table)[np.asarray(index, dtype=np.int64)]


class DrJitOps:
    """Dr.Jit implementation over the current Mitsuba variant's ``Float`` (JIT-compiled in llvm)."""

    def __init__(self) -> None:
        import drjit as dr
        import mitsuba as mi

        self.dr = dr
        self.Float = mi.Float
        self.UInt32 = mi.UInt32
        self.sqrt = dr.sqrt
        self.exp = dr.exp
        self.sin = dr.sin
        self.cos = dr.cos
        self.tan = dr.tan
        self.abs = dr.abs
        self.floor = dr.floor
        self.maximum = dr.maximum
        self.minimum = dr.minimum
        self.select = dr.select
        self.erf = dr.erf

    def asarray(self, x: Any):
        return self.Float(x)

    def gather(self, table, index):
        return self.dr.gather(self.Float, table, self.UInt32(index))


NUMPY = NumpyOps()
