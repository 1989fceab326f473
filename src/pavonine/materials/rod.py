"""Scattering by one infinitely long melanin rod, and the reflectance of one row of rods.

Paper Eq. 2 (after van de Hulst 1957 §15; Bohren & Huffman 1983 §8.4, "BH" below): a cylinder of
radius ``a`` and relative index ``m = n_rod / n_medium`` lit at normal incidence to its axis, size
parameter ``x = k a = 2π n_medium a / λ``. The far field is ``√(2/(πkr))·T(Θ)`` with
``T(Θ) = c_0 + 2 Σ_{n≥1} c_n cos(nΘ)`` (``Θ = 0`` forward, ``π`` back), ``c_n = b_n`` for TM
(E ∥ axis, BH case I) and ``a_n`` for TE (E ⊥ axis, BH case II).
"""

from __future__ import annotations

import functools

import numpy as np
from scipy.special import h1vp, hankel1, jv, jvp


def n_max_for(x: float) -> int:
    """Series truncation ``x + 4 x^{1/3} + 2`` (BH §4.8, Wiscombe 1980)."""
    return int(np.ceil(x + 4.0 * np.cbrt(x) + 2.0))


def cylinder_coefficients(x: float, m: complex, n_max: int) -> tuple[np.ndarray, np.ndarray]:
    """Scattering coefficients ``(a_n, b_n)`` for n = 0..n_max of an infinite cylinder (BH Eq. 8.30, 8.38).

    ``a_n``: TE (E ⊥ axis); ``b_n``: TM (E ∥ axis). ``x`` = 2π n_medium a / λ (dimensionless),
    ``m`` = n_rod / n_medium (complex allowed, absorbing for Im m > 0).

    TM: b_n = [J_n(mx) J_n'(x) − m J_n'(mx) J_n(x)] / [J_n(mx) H_n'(x) − m J_n'(mx) H_n(x)]
    TE: a_n = [m J_n'(x) J_n(mx) − J_n(x) J_n'(mx)] / [m J_n(mx) H_n'(x) − J_n'(mx) H_n(x)]
    """
    if not (np.isfinite(x) and x > 0):
        raise ValueError(f"size parameter x must be positive and finite, got {x}")
    if n_max < 0:
        raise ValueError(f"n_max must be >= 0, got {n_max}")
    n = np.arange(n_max + 1)
    mx = m * x
    j_mx, jp_mx = jv(n, mx), jvp(n, mx)
    j_x, jp_x = jv(n, x), jvp(n, x)
    h_x, hp_x = hankel1(n, x), h1vp(n, x)
    b = (j_mx * jp_x - m * jp_mx * j_x) / (j_mx * hp_x - m * jp_mx * h_x)
    a = (m * jp_x * j_mx - j_x * jp_mx) / (m * j_mx * hp_x - jp_mx * h_x)
    return a.astype(np.complex128), b.astype(np.complex128)


def amplitude(coefficients: np.ndarray, scattering_angle: np.ndarray) -> np.ndarray:
    """``T(Θ) = c_0 + 2 Σ c_n cos(nΘ)`` (paper Eq. 2; BH Eq. 8.33), Θ in radians."""
    c = np.asarray(coefficients)
    theta = np.asarray(scattering_angle, dtype=np.float64)
    n = np.arange(c.shape[-1])
    weights = np.where(n == 0, 1.0, 2.0) * c
    return np.cos(np.multiply.outer(theta, n)) @ weights


def efficiencies(x: float, coefficients: np.ndarray) -> tuple[float, float]:
    """``(Q_sca, Q_ext)`` per polarisation (BH Eq. 8.32, 8.36): (2/x)[|c0|²+2Σ|cn|²], (2/x)Re[c0+2Σcn]."""
    c = np.asarray(coefficients)
    q_sca = (2.0 / x) * (abs(c[0]) ** 2 + 2.0 * np.sum(np.abs(c[1:]) ** 2))
    q_ext = (2.0 / x) * float(np.real(c[0] + 2.0 * np.sum(c[1:])))
    return float(q_sca), q_ext


def unpolarised_intensity(x: float, m: complex, scattering_angle: np.ndarray) -> np.ndarray:
    """``|T(Θ)|²`` averaged over TE and TM: the intensity pattern of Eq. 2 for natural light."""
    a, b = cylinder_coefficients(x, m, n_max_for(x))
    return 0.5 * (
        np.abs(amplitude(a, scattering_angle)) ** 2 + np.abs(amplitude(b, scattering_angle)) ** 2
    )


def row_reflectance(x: float, m: complex, cos_theta: np.ndarray) -> np.ndarray:
    """Specular reflectance of one row of touching rods (spacing L = 2a), lit at angle θ.

    Summing the cylindrical waves of Eq. 2 over a row of period ``L`` (stationary phase, as for
    a grating's zeroth order; BH §8.4, Twersky 1962) gives a plane wave of amplitude
    ``ρ = 2 T(π − 2θ) / (k L cos θ) = T(π − 2θ) / (x cos θ)`` for ``L = 2a``. The single-scattering
    amplitude is unbounded for dense rows, so the sheet's own re-radiation is included to lowest
    order. For a lossless sheet whose single-scattering amplitude is purely imaginary, ρ = −i|ρ|, the
    radiation-damping closure ``r = ρ / (1 − iρ)`` gives exactly ``R₁ = |ρ|² / (1 + |ρ|²)``; Pavonine
    uses this form for every ρ as an approximation. It is bounded by 1 and → 1 at grazing incidence.
    """
    cos_theta = np.clip(np.asarray(cos_theta, dtype=np.float64), 0.0, 1.0)
    theta = np.arccos(cos_theta)
    intensity = unpolarised_intensity(x, m, np.pi - 2.0 * theta)
    with np.errstate(divide="ignore", invalid="ignore"):
        rho2 = intensity / (x * cos_theta) ** 2
        r1 = rho2 / (1.0 + rho2)
    return np.where(cos_theta > 0.0, r1, 1.0)


@functools.cache
def row_reflectance_table(
    m: complex, x_max: float = 6.0, n_x: int = 384, n_cos: int = 96
) -> tuple[np.ndarray, float, int, int]:
    """``R₁(x, cos θ)`` sampled on a regular grid: ``(table[n_x, n_cos] float32, x_max, n_x, n_cos)``.

    Rows: x = 0 … x_max (R₁ = 0 at x = 0, the Rayleigh limit); columns: cos θ = 0 … 1.
    """
    xs = np.linspace(0.0, x_max, n_x)
    cos_grid = np.linspace(0.0, 1.0, n_cos)
    table = np.zeros((n_x, n_cos), dtype=np.float64)
    for i, x in enumerate(xs[1:], start=1):
        table[i] = row_reflectance(x, m, cos_grid)
    table[0, 0] = 1.0
    return table.astype(np.float32), x_max, n_x, n_cos
