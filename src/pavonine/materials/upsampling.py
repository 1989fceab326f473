"""sRGB → reflectance spectrum without Mitsuba: Jakob & Hanika's sigmoid-polynomial fit.

W. Jakob and J. Hanika, "A Low-Dimensional Function Space for Efficient Spectral Upsampling",
Computer Graphics Forum 38(2), 2019. A reflectance spectrum is ``S(c0 λ² + c1 λ + c2)`` with
``S(x) = ½ + x / (2√(1 + x²))`` (Eq. 3, :func:`pavonine.materials.brdf.srgb_model_eval`); the three
coefficients of an sRGB colour minimise the CIE 1976 ΔE*ab between the colour and the spectrum's
colour under the colour space's illuminant (§4: Gauss-Newton on a normalised wavelength axis, as
their ``rgb2spec_opt``).

Mitsuba looks the coefficients up in a table of such fits (``mi.srgb_model_fetch``); Pavonine uses
Mitsuba's when it is installed and this fit otherwise (``pip install pavonine`` without
``[render]``). ``tests/materials/test_upsampling.py`` checks that both give the same spectrum.
"""

from __future__ import annotations

import numpy as np

from pavonine.materials import colour

LAMBDA_MIN, LAMBDA_MAX = colour.CIE_RANGE_NM  # nm, the CMFs' range
_GRID = np.arange(LAMBDA_MIN, LAMBDA_MAX + 0.5, 1.0)


def _sigmoid(x: np.ndarray) -> np.ndarray:
    """Jakob & Hanika 2019, Eq. 3: S(x) = ½ + x / (2√(1 + x²))."""
    return 0.5 + 0.5 * x / np.sqrt(1.0 + x * x)


def _lab_of(coefficients: np.ndarray, t: np.ndarray) -> np.ndarray:
    """CIELAB (D65) of the spectrum ``S(c0 t² + c1 t + c2)`` on the normalised axis ``t``."""
    c0, c1, c2 = coefficients
    spectrum = _sigmoid((c0 * t + c1) * t + c2)
    return colour.xyz_to_lab(colour.reflectance_to_xyz(_GRID, spectrum))


def fit_sigmoid_polynomial(
    linear_srgb: tuple[float, float, float], iterations: int = 50
) -> np.ndarray:
    """Coefficients ``(c0, c1, c2)`` over λ in nm whose spectrum has the colour ``linear_srgb``.

    Gauss-Newton with a finite-difference Jacobian on ``t = (λ − 360 nm) / 470 nm`` (their
    ``rgb2spec_opt``), stopping when ΔE*ab < 1e-6; then the polynomial is re-expressed in nm.
    """
    target = colour.xyz_to_lab(colour.linear_srgb_to_xyz(np.clip(linear_srgb, 0.0, 1.0)))
    width = LAMBDA_MAX - LAMBDA_MIN
    t = (_GRID - LAMBDA_MIN) / width
    c = np.zeros(3)
    for _ in range(iterations):
        residual = _lab_of(c, t) - target
        if np.linalg.norm(residual) < 1e-6:
            break
        jacobian = np.empty((3, 3))
        for j in range(3):
            step = np.zeros(3)
            step[j] = 1e-4
            jacobian[:, j] = (_lab_of(c + step, t) - _lab_of(c - step, t)) / 2e-4
        delta = np.linalg.lstsq(jacobian, residual, rcond=None)[0]
        c = c - delta
        if np.max(np.abs(c)) > 200.0:  # diverging (a colour out of reach): stop where it is
            break
    c0, c1, c2 = c
    a = LAMBDA_MIN
    return np.array(
        [
            c0 / width**2,
            c1 / width - 2.0 * c0 * a / width**2,
            c0 * a * a / width**2 - c1 * a / width + c2,
        ]
    )
