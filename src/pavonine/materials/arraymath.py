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
    log = staticmethod(np.log)

    @staticmethod
    def asarray(x: Any) -> np.ndarray:
        return np.asarray(x, dtype=np.float64)

    @staticmethod
    def to_uint32(x: Any) -> np.ndarray:
        """Whole numbers (floats) as unsigned 32-bit values, negatives wrapped (held in ``uint64``
        so that the hashes' products do not overflow)."""
        return (np.asarray(x, dtype=np.float64).astype(np.int64) & 0xFFFFFFFF).astype(np.uint64)

    @staticmethod
    def to_float(x: Any) -> np.ndarray:
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
        self.log = dr.log
        self.jit = dr.is_jit_v(mi.Float)
        self.Int32 = mi.Int32

        # A table to gather from: the dynamic array of the variant (scalar variants' Float is a
        # plain Python float, so their tables are ``dr.scalar.ArrayXf``).
        self.Buffer = mi.Float if dr.is_jit_v(mi.Float) else dr.scalar.ArrayXf

    def asarray(self, x: Any):
        return self.Float(x)

    def to_uint32(self, x):
        """Whole numbers (``Float``) as ``UInt32``, negatives wrapped."""
        if self.jit:
            return self.dr.reinterpret_array(self.UInt32, self.Int32(x))
        return int(x) & 0xFFFFFFFF

    def to_float(self, x):
        return self.Float(x)

    def buffer(self, values: Any):
        """A gather table holding ``values`` (a 1-D NumPy array or sequence)."""
        return self.Buffer(np.asarray(values, dtype=np.float32).ravel())

    def gather(self, table, index):
        """``table[index]``, the index clamped to the table: a NaN index (NaN inputs) reads entry
        0 instead of converting to 0x80000000 and reading 8 GiB past the table (SIGSEGV)."""
        if self.Buffer is self.Float:
            dr = self.dr
            last = dr.width(table) - 1.0
            safe = dr.select(index >= 0.0, dr.minimum(index, last), 0.0)  # False for NaN
            return dr.gather(self.Float, table, self.UInt32(safe))
        return table[int(index)]  # scalar variant: one lane, plain indexing


NUMPY = NumpyOps()


def bilinear_gather(
    values: Any, base: Any, stride: float, t_fast: Any, t_slow: Any, ops: Any
) -> Any:
    """Bilinear interpolation in a flat row-major table: ``base`` indexes the lower corner, the
    fast axis steps by 1 (weight ``t_fast``), the slow axis by ``stride`` (weight ``t_slow``)."""
    v00 = ops.gather(values, base)
    v01 = ops.gather(values, base + 1.0)
    v10 = ops.gather(values, base + stride)
    v11 = ops.gather(values, base + (stride + 1.0))
    v0 = v00 + (v01 - v00) * t_fast
    v1 = v10 + (v11 - v10) * t_fast
    return v0 + (v1 - v0) * t_slow
