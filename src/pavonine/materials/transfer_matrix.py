"""Exact reflectance of a planar multilayer by the characteristic-matrix method — the independent
physical reference for the rod-layer model.

Born & Wolf, *Principles of Optics* (7th ed.) §1.6.2, Eq. 1.6(33); Macleod, *Thin-Film Optical
Filters* (4th ed.) §2.2. Each layer j (index n_j, thickness d_j, angle θ_j from Snell's law)
contributes ``M_j = [[cos δ_j, −i sin δ_j / η_j], [−i η_j sin δ_j, cos δ_j]]`` with phase thickness
``δ_j = 2π n_j d_j cos θ_j / λ`` and tilted admittance ``η_j = n_j cos θ_j`` (s / TE) or
``n_j / cos θ_j`` (p / TM). With ``[B, C] = M [1, η_s]``, ``r = (η_0 B − C) / (η_0 B + C)``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from pavonine.materials.layers import fill_factor


def _admittance(n: np.ndarray, cos_t: np.ndarray, polarisation: str) -> np.ndarray:
    if polarisation == "s":
        return n * cos_t
    if polarisation == "p":
        return n / cos_t
    raise ValueError(f"polarisation must be 's' or 'p', got {polarisation!r}")


def multilayer_reflectance(
    indices: Sequence[complex],
    thicknesses_nm: Sequence[float],
    wavelength_nm: np.ndarray,
    incidence_rad: float = 0.0,
    n_ambient: complex = 1.0,
    n_substrate: complex = 1.0,
    polarisation: str = "unpolarised",
) -> np.ndarray:
    """Reflectance |r|² of a stack of planar layers, for each wavelength.

    ``indices``/``thicknesses_nm`` list the layers from the ambient side; ``incidence_rad`` is the
    angle in the ambient medium; ``polarisation`` is ``"s"``, ``"p"`` or ``"unpolarised"`` (mean).
    """
    if polarisation == "unpolarised":
        args = (indices, thicknesses_nm, wavelength_nm, incidence_rad, n_ambient, n_substrate)
        return 0.5 * (multilayer_reflectance(*args, "s") + multilayer_reflectance(*args, "p"))
    lam = np.asarray(wavelength_nm, dtype=np.float64)
    n0 = complex(n_ambient)
    sin0 = n0 * np.sin(incidence_rad)

    def cos_in(n: complex) -> complex:
        return np.sqrt(1.0 - (sin0 / n) ** 2 + 0j)

    eta0 = _admittance(n0, cos_in(n0), polarisation)
    eta_s = _admittance(complex(n_substrate), cos_in(complex(n_substrate)), polarisation)
    m11 = np.ones_like(lam, dtype=np.complex128)
    m12 = np.zeros_like(m11)
    m21 = np.zeros_like(m11)
    m22 = np.ones_like(m11)
    for n, d in zip(indices, thicknesses_nm, strict=True):
        n = complex(n)
        cos_t = cos_in(n)
        delta = 2.0 * np.pi * n * d * cos_t / lam
        eta = _admittance(n, cos_t, polarisation)
        c, s = np.cos(delta), np.sin(delta)
        a11, a12, a21, a22 = c, -1j * s / eta, -1j * eta * s, c
        m11, m12, m21, m22 = (
            m11 * a11 + m12 * a21,
            m11 * a12 + m12 * a22,
            m21 * a11 + m22 * a21,
            m21 * a12 + m22 * a22,
        )
    b = m11 + m12 * eta_s
    c = m21 + m22 * eta_s
    r = (eta0 * b - c) / (eta0 * b + c)
    return np.abs(r) ** 2


def rod_stack_layers(
    interval_nm: float, radius_nm: float, count: int, n_rod: complex = 2.0, n_medium: complex = 1.0
) -> tuple[list[complex], list[float]]:
    """The planar multilayer equivalent to ``count`` rod layers (Eq. 1 geometry).

    Each period of thickness d becomes a melanin slab of thickness ``f d`` and a medium slab of
    ``(1 − f) d``, ``f = π a / (2 d)``: the same optical distance per layer as Eq. 1.
    """
    f = float(fill_factor(interval_nm, radius_nm))
    indices = [n_rod, n_medium] * int(count)
    thicknesses = [f * interval_nm, (1.0 - f) * interval_nm] * int(count)
    return indices, thicknesses
