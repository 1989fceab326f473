"""The barbule's shape: spread of layer normals across it (crescent, Eq. 6) and along it (saddle
blocks, rod ends), the weight of Eq. 5, and the orientation blend of Eq. 7.

The renderer's normal distribution is an anisotropic Beckmann distribution (Gaussian in slope):
across the barbule its slope deviation is ``tan θ0`` (the crescent's θ0 = 15°, paper §3.2), along
it ``tan σ_along``. Eq. 6 is then the density of *visible* normals of that distribution in the
plane of incidence (Heitz 2014, "Understanding the masking-shadowing function", Eq. 2), which
:func:`crescent_density` evaluates for Figure 10.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pavonine.materials.arraymath import NUMPY

SQRT2 = math.sqrt(2.0)
SQRT_PI = math.sqrt(math.pi)
# σ of a Gaussian fitted to the central lobe of a slit's sinc² pattern: FWHM 0.886 λ/ℓ / 2.355.
SLIT_SIGMA_PER_LAMBDA_OVER_LENGTH = 0.886 / 2.3548


def rod_gradient_weight(phi: Any, theta_in: Any, theta_out: Any) -> np.ndarray:
    """Eq. 5: ``I_φ = cos φ · √((1 − tan θ_in / tan θ_out) / 2)`` (angles in radians).

    Defined everywhere: the radicand is clamped to [0, 1] (negative → no light reaches that
    gradient), ``θ_out = 0`` gives 0, and ``cos φ < 0`` (facing away) gives 0.
    """
    phi, t_in, t_out = (np.asarray(v, dtype=np.float64) for v in (phi, theta_in, theta_out))
    tan_in, tan_out = np.tan(t_in), np.tan(t_out)
    with np.errstate(divide="ignore", invalid="ignore"):
        radicand = np.where(np.abs(tan_out) > 1e-12, (1.0 - tan_in / tan_out) / 2.0, 0.0)
    radicand = np.clip(np.nan_to_num(radicand, nan=0.0, posinf=1.0, neginf=0.0), 0.0, 1.0)
    return np.maximum(np.cos(phi), 0.0) * np.sqrt(radicand)


def crescent_density(tilt: Any, incidence: Any, sigma: float = math.radians(15.0)) -> np.ndarray:
    """Eq. 6: density of normal tilt θ across the barbule, ``k(θ_in) cos(θ_in − θ) N(θ; 0, θ0²)``.

    Radians throughout. ``k`` normalises over the tilts that face the light (``cos(θ_in − θ) > 0``),
    so the density integrates to 1 over θ for every incidence.
    """
    tilt = np.asarray(tilt, dtype=np.float64)
    incidence = np.asarray(incidence, dtype=np.float64)
    grid = np.linspace(-math.pi / 2, math.pi / 2, 4001)

    def unnormalised(theta, theta_in):
        gauss = np.exp(-0.5 * (theta / sigma) ** 2) / (math.sqrt(2 * math.pi) * sigma)
        return np.maximum(np.cos(theta_in - theta), 0.0) * gauss

    norm = np.trapezoid(unnormalised(grid[:, None], np.ravel(incidence)[None, :]), grid, axis=0)
    norm = norm.reshape(incidence.shape)
    return unnormalised(tilt, incidence) / norm


def orientation_blend(f_long: Any, f_short: Any, cos2_psi: Any) -> Any:
    """Eq. 7 with the misprint fixed: ``I = cos²ψ · f_long + sin²ψ · f_short``."""
    return cos2_psi * f_long + (1.0 - cos2_psi) * f_short


def beckmann_alpha(sigma: Any, ops: Any = NUMPY) -> Any:
    """Beckmann roughness for a slope deviation ``tan σ``: ``α = √2 tan σ`` (σ in radians).

    Beckmann slopes are Gaussian with variance α²/2 per axis (Walter et al. 2007, Eq. 25).
    """
    return SQRT2 * ops.tan(sigma)


def along_sigma(block_sigma: Any, rod_length: Any, wavelength: Any, ops: Any = NUMPY) -> Any:
    """Angular spread along the barbule (radians): saddle blocks ⊕ diffraction at rod ends.

    The rod ends act as a slit of length ℓ (paper §3.2); its central lobe is approximated by a
    Gaussian of σ = 0.376 λ/ℓ, added in quadrature to the blocks' Gaussian spread.
    ``wavelength`` and ``rod_length`` in the same unit.
    """
    diffraction = diffraction_sigma(rod_length, wavelength)
    return ops.sqrt(block_sigma * block_sigma + diffraction * diffraction)


def diffraction_sigma(length: Any, wavelength: Any) -> Any:
    """σ (radians) of the Gaussian fitted to the central lobe of a slit of ``length``:
    ``0.376 λ/ℓ`` (sinc² FWHM 0.886 λ/ℓ over 2.355; same units for both lengths)."""
    return SLIT_SIGMA_PER_LAMBDA_OVER_LENGTH * wavelength / length


def beckmann_ndf(hx: Any, hy: Any, hz: Any, alpha_x: Any, alpha_y: Any, ops: Any = NUMPY) -> Any:
    """Anisotropic Beckmann ``D(h) = exp(−(h_x²/α_x² + h_y²/α_y²)/h_z²) / (π α_x α_y h_z⁴)``.

    Walter et al. 2007 Eq. 25 extended anisotropically (Heitz 2014 Eq. 81); ``∫ D(h) h_z dω = 1``.
    Zero for ``h_z ≤ 0``.
    """
    hz2 = hz * hz
    safe = ops.maximum(hz2, 1e-12)
    exponent = -(hx * hx / (alpha_x * alpha_x) + hy * hy / (alpha_y * alpha_y)) / safe
    value = ops.exp(exponent) / (math.pi * alpha_x * alpha_y * safe * safe)
    return ops.select(hz > 0.0, value, 0.0)


def shifted_beckmann_ndf(
    hx: Any, hy: Any, hz: Any, alpha_x: Any, alpha_y: Any, slope_x: Any, ops: Any = NUMPY
) -> Any:
    """Beckmann ``D(h)`` of a microsurface whose mean slope along ``x`` is ``slope_x`` (one block).

    The Beckmann slope density ``P₂₂(x̃, ỹ) = exp(−x̃²/α_x² − ỹ²/α_y²) / (π α_x α_y)`` shifted to
    ``x̃ − slope_x``, with ``(x̃, ỹ) = (−h_x/h_z, −h_y/h_z)`` and ``D = P₂₂ / h_z⁴`` (Heitz 2014,
    Eq. 8 and 79): still ``∫ D(h) h_z dω = 1``; ``slope_x = 0`` is :func:`beckmann_ndf`. The mean
    normal of the block is ``∝ (−slope_x, 0, 1)``.
    """
    hz2 = hz * hz
    safe = ops.maximum(hz2, 1e-12)
    inv_z = 1.0 / ops.maximum(hz, 1e-6)
    sx = -hx * inv_z - slope_x
    sy = hy * inv_z
    exponent = -(sx * sx / (alpha_x * alpha_x) + sy * sy / (alpha_y * alpha_y))
    value = ops.exp(exponent) / (math.pi * alpha_x * alpha_y * safe * safe)
    return ops.select(hz > 0.0, value, 0.0)


def beckmann_smith_g1(
    wx: Any, wy: Any, wz: Any, hdotw: Any, alpha_x: Any, alpha_y: Any, ops: Any = NUMPY
) -> Any:
    """Smith masking ``G1 = 1 / (1 + Λ)`` for Beckmann, ``Λ = (erf(a) − 1)/2 + e^{−a²}/(2a√π)``.

    ``a = 1 / (α_ω tan θ)``, ``α_ω² = (w_x² α_x² + w_y² α_y²) / (w_x² + w_y²)`` (Heitz 2014, Eq. 72, 86).
    Zero when the microfacet is back-facing for ``w`` (``h·w · w_z ≤ 0``).
    """
    xy = wx * wx * alpha_x * alpha_x + wy * wy * alpha_y * alpha_y
    # a = w_z / sqrt(w_x² α_x² + w_y² α_y²) = 1 / (α_ω tan θ)
    a = wz / ops.sqrt(ops.maximum(xy, 1e-20))
    a_safe = ops.maximum(a, 1e-6)
    lam = 0.5 * (ops.erf(a_safe) - 1.0) + ops.exp(-a_safe * a_safe) / (2.0 * a_safe * SQRT_PI)
    g1 = ops.select(a >= 6.0, 1.0, 1.0 / (1.0 + lam))
    return ops.select((hdotw * wz > 0.0) & (wz > 0.0), g1, 0.0)
