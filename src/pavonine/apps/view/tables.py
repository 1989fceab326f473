"""The feather BRDF of :mod:`pavonine.materials.brdf` tabulated for a real-time shader.

The structural BRDF (``brdf.structural_brdf``) in the barbule frame, with half-vector ``h``,
``cos θ_d = ω_i·h`` and slopes ``s_x = h_x/h_z``, ``s_y = h_y/h_z``, is

    f_s(λ) = [c R_long(λ, θ_d) + (1 − c) R_short(λ, θ_d)] · D_λ(h) · G / (4 cos θ_i cos θ_o)
    D_λ(h) = exp(−s_x²/α_x(λ)²)/α_x(λ) · exp(−s_y²/α_y²)/α_y / (π h_z⁴)         (Beckmann)

(``c = cos²ψ`` of Eq. 7, ``brdf.orientation_weight``; ``α_x`` depends on λ through the rod
ends' diffraction, ``barbule.along_sigma``; ``α_y`` does not). Everything spectral is in

    T_axis(k, t, θ_d, |s_x|) = RGB[ R_axis(λ, θ_d) · exp(−s_x²/α_x(λ)²)/α_x(λ) ]

(linear Rec. 709 under D65, :func:`pavonine.materials.colour.reflectance_to_linear_srgb`, so a
white diffuser reads 1 as in ``pavonine render``), tabulated per ocellar class ``k``, gradation
step ``t`` and barbule axis. The shader (``static/feather.js``) multiplies the interpolated
``T`` by the achromatic rest, ``exp(−s_y²/α_y²)/(α_y π h_z⁴) · G / (4 cos θ_i cos θ_o)``, with
Smith's ``G`` at :data:`G_WAVELENGTH_NM` by Walter et al.'s rational fit (:func:`smith_g1_walter`;
the approximations: ``G`` is within a few per cent of 1 except at grazing angles). :func:`table_brdf_rgb` is that shader's formula in NumPy; the
tests hold it against the BRDF itself at sample angles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pavonine.materials import barbule, colour
from pavonine.materials.arraymath import NUMPY
from pavonine.materials.brdf import (
    MaterialConstants,
    axis_reflectance,
    melanin_albedo,
    orientation_weight,
)
from pavonine.materials.optics import model_for
from pavonine.materials.parameters import FeatherParameters

#: Wavelengths of the tabulated spectra (nm): CIE 15's 10 nm grid over the visible (as the bake).
WAVELENGTHS_NM = np.arange(380.0, 781.0, 10.0)
#: Gradation steps per class (t = 0, 1/(n−1), …, 1; the shader interpolates between them).
GRADATION_STEPS = 11
#: θ_d samples over [0°, 90°].
THETA_D_STEPS = 64
#: |s_x| samples over [0, SLOPE_RANGE · max α_x].
SLOPE_STEPS = 32
SLOPE_RANGE = 3.5
#: View angles of the directional-albedo table (the sky's share, :func:`sky_albedo`), over [0°, 90°].
ALBEDO_VIEW_STEPS = 12
#: Light directions of its cosine-weighted quadrature: (sin²θ, φ) midpoints.
ALBEDO_GRID = (16, 32)
#: View azimuths (relative to the barbule) it averages over.
ALBEDO_AZIMUTHS_DEG = (0.0, 45.0, 90.0, 135.0)
#: Wavelength of the α_x used in Smith's G (the one non-spectral factor).
G_WAVELENGTH_NM = 550.0


@dataclass(frozen=True)
class BrdfTable:
    """``values[k, t, axis, θ_d, s_x, rgb]`` (see the module docstring) and what the shader needs."""

    values: np.ndarray
    albedo: np.ndarray  # [k, t, θ_o, rgb]: ∫ f_s cos θ_i dω_i (the uniform sky's share)
    slope_max: float
    alpha_x_g: float
    alpha_y: float
    melanin_rgb: tuple[float, float, float]
    classes: int

    def meta(self) -> dict:
        """The JSON the page reads next to the binary table."""
        n, g, a, nt, ns, _ = self.values.shape
        return {
            "classes": n,
            "gradations": g,
            "axes": a,
            "thetaSteps": nt,
            "slopeSteps": ns,
            "slopeMax": self.slope_max,
            "alphaXG": self.alpha_x_g,
            "alphaY": self.alpha_y,
            "melaninRgb": list(self.melanin_rgb),
            "albedoSteps": self.albedo.shape[2],
        }

    def texture_bytes(self) -> bytes:
        """RGBA half floats, x = s_x, y = θ_d, z = (axis·classes + k)·gradations + t (a 3D
        texture: its linear filtering in z is the interpolation between gradation steps)."""
        values = np.moveaxis(self.values, 2, 0)
        rgba = np.concatenate([values, np.ones_like(values[..., :1])], axis=-1)
        return np.ascontiguousarray(rgba, dtype="<f2").tobytes()

    def albedo_bytes(self) -> bytes:
        """RGBA half floats, x = θ_o, y = k·gradations + t (a 2D texture)."""
        rgba = np.concatenate([self.albedo, np.ones_like(self.albedo[..., :1])], axis=-1)
        return np.ascontiguousarray(rgba, dtype="<f2").tobytes()


def _alpha_x(constants: MaterialConstants, wavelength_nm):
    sigma = barbule.along_sigma(constants.block_sigma, constants.rod_length_nm, wavelength_nm)
    return barbule.beckmann_alpha(sigma)


def build_table(params: FeatherParameters) -> BrdfTable:
    """Tabulate the material's structural BRDF (module docstring); about a second.

    One axis only when the two barbule axes share their structure (Eq. 7 then blends equals).
    """
    model = model_for(params)
    axes = 1 if all(c.long == c.short for c in params.classes) else 2
    constants = model.constants
    lam = WAVELENGTHS_NM
    alpha_x = _alpha_x(constants, lam)  # (nλ,)
    slope_max = SLOPE_RANGE * float(alpha_x.max())
    theta = np.radians(np.linspace(0.0, 90.0, THETA_D_STEPS))
    slope = np.linspace(0.0, slope_max, SLOPE_STEPS)
    lobe = np.exp(-((slope[:, None] / alpha_x[None, :]) ** 2)) / alpha_x[None, :]  # (ns, nλ)
    cos_d = np.cos(theta)[:, None]
    n = len(params.classes)
    values = np.zeros((n, GRADATION_STEPS, axes, THETA_D_STEPS, SLOPE_STEPS, 3))
    for k in range(n):
        for g, t in enumerate(np.linspace(0.0, 1.0, GRADATION_STEPS)):
            for axis, stack in enumerate(model.stacks_nm(k, float(t))[:axes]):
                r = axis_reflectance(constants, model.table, lam[None, :], cos_d, stack, NUMPY)
                r = np.broadcast_to(r, (THETA_D_STEPS, len(lam)))
                spectra = r[:, None, :] * lobe[None, :, :]  # (nθ, ns, nλ)
                values[k, g, axis] = colour.reflectance_to_linear_srgb(lam, spectra)
    melanin = colour.reflectance_to_linear_srgb(lam, melanin_albedo(params.melanin_color, lam))
    table = BrdfTable(
        values=values,
        albedo=np.zeros((n, GRADATION_STEPS, ALBEDO_VIEW_STEPS, 3)),
        slope_max=slope_max,
        alpha_x_g=float(_alpha_x(constants, G_WAVELENGTH_NM)),
        alpha_y=barbule.SQRT2 * math.tan(constants.crescent_sigma),
        melanin_rgb=tuple(float(c) for c in melanin),
        classes=n,
    )
    table.albedo[...] = sky_albedo(table)
    return table


def _hemisphere(rows: int, columns: int) -> np.ndarray:
    """Cosine-weighted quadrature directions: midpoints in (sin²θ, φ), ``(rows·columns, 3)``."""
    u = (np.arange(rows) + 0.5) / rows
    phi = (np.arange(columns) + 0.5) / columns * 2.0 * math.pi
    sin_t = np.sqrt(u)[:, None]
    cos_t = np.sqrt(1.0 - u)[:, None]
    d = np.stack(np.broadcast_arrays(sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t), -1)
    return d.reshape(-1, 3)


def sky_albedo(table: BrdfTable) -> np.ndarray:
    """``A(k, t, θ_o) = ∫ f_s(ω_i, ω_o) cos θ_i dω_i`` of the tabulated structural BRDF (RGB),
    averaged over :data:`ALBEDO_AZIMUTHS_DEG`: a uniform sky of radiance ``L`` adds ``L·A``.

    Cosine-weighted quadrature, ``A = π · mean f`` over :func:`_hemisphere`'s directions."""
    lights = _hemisphere(*ALBEDO_GRID)
    theta = np.radians(np.linspace(0.0, 89.0, ALBEDO_VIEW_STEPS))
    phi = np.radians(np.asarray(ALBEDO_AZIMUTHS_DEG))
    views = np.stack(
        np.broadcast_arrays(
            np.sin(theta)[:, None] * np.cos(phi),
            np.sin(theta)[:, None] * np.sin(phi),
            np.cos(theta)[:, None],
        ),
        -1,
    )  # (nθ, nφ, 3)
    wi = np.broadcast_to(views[:, :, None, :], (*views.shape[:2], len(lights), 3))
    wo = np.broadcast_to(lights, wi.shape)
    n, g = table.values.shape[:2]
    out = np.zeros((n, g, len(theta), 3))
    for k in range(n):
        for j, t in enumerate(np.linspace(0.0, 1.0, g)):
            f = table_brdf_rgb(table, wi, wo, k, float(t))  # (nθ, nφ, nl, 3)
            out[k, j] = math.pi * f.mean(axis=(1, 2))
    return out


def smith_g1_walter(w: np.ndarray, hdotw, alpha_x: float, alpha_y: float) -> np.ndarray:
    """Beckmann Smith ``G1`` by the rational fit of Walter et al. 2007 (Eq. 27):
    ``(3.535 a + 2.181 a²) / (1 + 2.276 a + 2.577 a²)`` for ``a < 1.6``, else 1, with ``a`` of
    :func:`pavonine.materials.barbule.beckmann_smith_g1` (relative error below 0.4 %)."""
    wx, wy, wz = w[..., 0], w[..., 1], w[..., 2]
    a = wz / np.sqrt(np.maximum(wx * wx * alpha_x**2 + wy * wy * alpha_y**2, 1e-20))
    fit = np.where(a >= 1.6, 1.0, (3.535 * a + 2.181 * a * a) / (1 + 2.276 * a + 2.577 * a * a))
    return np.where((hdotw * wz > 0) & (wz > 0), fit, 0.0)


def _lookup(table: BrdfTable, k: int, t: float, axis: int, theta_d, slope) -> np.ndarray:
    """Linear interpolation of ``T`` in gradation, θ_d and |s_x| (as the GPU's filtering does)."""
    v = table.values
    g = np.clip(t, 0.0, 1.0) * (v.shape[1] - 1)
    ft = np.clip(np.degrees(theta_d) / 90.0 * (v.shape[3] - 1), 0, v.shape[3] - 1)
    fs = np.clip(np.abs(slope) / table.slope_max * (v.shape[4] - 1), 0, v.shape[4] - 1)

    g0 = min(math.floor(g), v.shape[1] - 2)
    wg = g - g0
    plane = (1 - wg) * v[k, g0, axis] + wg * v[k, g0 + 1, axis]  # (nθ, ns, 3)
    i0 = np.minimum(np.floor(ft).astype(int), v.shape[3] - 2)
    j0 = np.minimum(np.floor(fs).astype(int), v.shape[4] - 2)
    wt, ws = (ft - i0)[..., None], (fs - j0)[..., None]
    return (
        (1 - wt) * (1 - ws) * plane[i0, j0]
        + wt * (1 - ws) * plane[i0 + 1, j0]
        + (1 - wt) * ws * plane[i0, j0 + 1]
        + wt * ws * plane[i0 + 1, j0 + 1]
    )


def table_brdf_rgb(
    table: BrdfTable, wi: np.ndarray, wo: np.ndarray, k: int, t: float, share: float = 1.0
) -> np.ndarray:
    """The shader's BRDF (linear RGB, 1/sr) for barbule-frame unit vectors ``(..., 3)``."""
    wi, wo = np.asarray(wi, float), np.asarray(wo, float)
    h = wi + wo
    h = h / np.linalg.norm(h, axis=-1, keepdims=True)
    hx, hy, hz = h[..., 0], h[..., 1], h[..., 2]
    cos_d = np.clip(np.sum(wi * h, axis=-1), 0.0, 1.0)
    theta_d = np.arccos(cos_d)
    sx, sy = hx / hz, hy / hz
    c = orientation_weight(hx, hy, hz)[..., None]
    long = _lookup(table, k, t, 0, theta_d, sx)
    short = _lookup(table, k, t, table.values.shape[2] - 1, theta_d, sx)
    spectral = c * long + (1 - c) * short
    ay, ax = table.alpha_y, table.alpha_x_g
    rest = np.exp(-((sy / ay) ** 2)) / (ay * math.pi * hz**4)
    g = smith_g1_walter(wi, cos_d, ax, ay) * smith_g1_walter(wo, np.sum(wo * h, axis=-1), ax, ay)
    structural = spectral * (rest * g / (4.0 * wi[..., 2] * wo[..., 2]))[..., None]
    melanin = np.asarray(table.melanin_rgb) / math.pi
    return share * structural + (1.0 - share) * melanin


def brdf_rgb(
    params: FeatherParameters, wi: np.ndarray, wo: np.ndarray, k: int, t: float, share: float = 1.0
) -> np.ndarray:
    """The BRDF itself (:class:`pavonine.materials.brdf.FeatherModel`) as linear RGB (1/sr)."""
    f = model_for(params).brdf(
        np.asarray(wi)[..., None, :], np.asarray(wo)[..., None, :], WAVELENGTHS_NM, k, t, share
    )
    return colour.reflectance_to_linear_srgb(WAVELENGTHS_NM, f)
