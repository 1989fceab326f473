"""Refractive indices of the barbule's materials as functions of wavelength (λ in nm).

A material is a Cauchy law with an exponential absorption tail,
``n(λ) = A + B / λ²``, ``k(λ) = k₀ exp(−λ / λ_k)``, ``ñ = n + i k``:

* melanin: ``A = 1.648``, ``B = 23 700 nm²``, ``k₀ = 0.56``, ``λ_k = 270 nm``
  (Stavenga, Leertouwer, Osorio & Wilts 2015, "High refractive index of melanin in shiny occipital
  feathers of a bird of paradise", Light Sci. Appl. 4:e243);
* keratin: ``A = 1.532``, ``B = 5 890 nm²``, no absorption
  (Leertouwer, Wilts & Stavenga 2011, "Refractive index and dispersion of butterfly chitin and
  bird keratin measured by polarizing interference microscopy", Opt. Express 19:24061);
* a constant index is ``B = 0``, ``k₀ = 0`` (the paper's melanin 2.0 and air 1.0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Dispersion:
    """``n(λ) = A + B/λ²`` (λ in nm, B in nm²) and ``k(λ) = k₀ exp(−λ/λ_k)`` (λ_k in nm)."""

    cauchy_a: float
    cauchy_b: float = 0.0
    extinction: float = 0.0
    extinction_scale: float = 270.0

    @classmethod
    def constant(cls, n: float) -> Dispersion:
        """A non-dispersive, non-absorbing index ``n``."""
        return cls(float(n))

    def real(self, wavelength_nm: Any) -> Any:
        """Real part ``A + B/λ²`` (works on NumPy and Dr.Jit arrays alike)."""
        return self.cauchy_a + self.cauchy_b / (wavelength_nm * wavelength_nm)

    def index(self, wavelength_nm: Any) -> np.ndarray:
        """Complex index ``n + i k`` at ``wavelength_nm`` (NumPy)."""
        lam = np.asarray(wavelength_nm, dtype=np.float64)
        k = self.extinction * np.exp(-lam / self.extinction_scale) if self.extinction else 0.0
        return self.real(lam) + 1j * k

    def check(self, name: str) -> Dispersion:
        """Raise ``ValueError`` naming ``name`` unless the index is finite and ≥ 1 over 300–900 nm."""
        values = (self.cauchy_a, self.cauchy_b, self.extinction, self.extinction_scale)
        if not all(math.isfinite(v) for v in values):
            raise ValueError(f"{name}: coefficients must be finite, got {values}")
        if self.extinction < 0.0 or self.extinction_scale <= 0.0:
            raise ValueError(f"{name}: absorption k0 must be >= 0 and its scale > 0 nm")
        n = self.real(np.array([300.0, 900.0]))
        if np.any(n < 1.0):
            raise ValueError(f"{name}: index must stay >= 1 over 300-900 nm, got {n.min():.4g}")
        return self


MELANIN = Dispersion(1.648, 23700.0, 0.56, 270.0)
KERATIN = Dispersion(1.532, 5890.0)
AIR = Dispersion.constant(1.0)
