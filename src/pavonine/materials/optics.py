"""Public face of the optics model: the paper's equations, presets, spectra and colours.

Everything here is NumPy; the renderer runs the same :mod:`pavonine.materials.brdf` code under
Dr.Jit. Angles at this level are in degrees, wavelengths in nm, lengths of parameters in µm.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from pavonine.materials import barbule, colour, rod
from pavonine.materials.barbule import (
    crescent_density,
    orientation_blend,
    rod_gradient_weight,
)
from pavonine.materials.brdf import FeatherModel, direction, melanin_albedo
from pavonine.materials.dispersion import KERATIN, MELANIN
from pavonine.materials.lattice import RodLattice
from pavonine.materials.layers import (
    array_factor,
    fill_factor,
    multilayer_intensity,
    optical_distance,
    rod_row_intensity,
)
from pavonine.materials.parameters import (
    PRESETS,
    FeatherParameters,
    ParameterError,
    preset,
    uniform_parameters,
)
from pavonine.materials.rod import (
    amplitude,
    cylinder_coefficients,
    efficiencies,
    n_max_for,
    unpolarised_intensity,
)
from pavonine.materials.stack import lattice_reflectance_emt
from pavonine.materials.transfer_matrix import multilayer_reflectance, rod_stack_layers

__all__ = [
    "PRESETS",
    "FeatherModel",
    "FeatherParameters",
    "ParameterError",
    "SpectrumSummary",
    "amplitude",
    "array_factor",
    "crescent_density",
    "cylinder_coefficients",
    "direction",
    "directional_albedo",
    "efficiencies",
    "fill_factor",
    "model_for",
    "multilayer_intensity",
    "multilayer_reflectance",
    "n_max_for",
    "optical_distance",
    "orientation_blend",
    "preset",
    "preview_color",
    "reflectance_spectra",
    "rod_gradient_weight",
    "rod_row_intensity",
    "rod_stack_layers",
    "stack_reflectance",
    "summarise",
    "uniform_parameters",
    "unpolarised_intensity",
]

PLOT_WAVELENGTHS_NM = np.arange(380.0, 781.0, 1.0)
COLOUR_WAVELENGTHS_NM = np.arange(360.0, 831.0, 1.0)
VALID_WAVELENGTHS_NM = (300.0, 900.0)


def check_wavelengths(wavelengths_nm: np.ndarray) -> np.ndarray:
    """Wavelengths as an array, or :class:`ParameterError` outside 300–900 nm / NaN."""
    w = np.asarray(wavelengths_nm, dtype=np.float64)
    if np.any(np.isnan(w)):
        raise ParameterError("wavelength", "is NaN")
    lo, hi = VALID_WAVELENGTHS_NM
    if np.any((w < lo) | (w > hi)):
        raise ParameterError(
            "wavelength", f"must lie in {lo:g}–{hi:g} nm, got {w.min():g}–{w.max():g}"
        )
    return w


def check_angle(name: str, degrees: float) -> float:
    """An angle from the vane normal in degrees, or :class:`ParameterError` outside (−90°, 90°)."""
    value = float(degrees)
    if math.isnan(value):
        raise ParameterError(name, "is NaN")
    if not -90.0 < value < 90.0:
        raise ParameterError(
            name, f"must lie inside the hemisphere (-90, 90) degrees, got {value:g}"
        )
    return value


def stack_reflectance(
    wavelength_nm,
    interval_nm: float,
    radius_nm: float,
    layers: float,
    *,
    n_rod=None,
    n_medium=None,
    cos_theta=1.0,
    mode: str = "physical",
) -> np.ndarray:
    """Unpolarised specular reflectance (0…1) of ``layers`` rod layers embedded in the medium.

    Broadcasts over ``wavelength_nm`` (and ``cos_theta``, the cosine of the incidence angle in the
    medium above the stack). ``n_rod``/``n_medium``: constants, or ``None`` for dispersive melanin
    (with absorption) / keratin (:mod:`pavonine.materials.dispersion`).

    ``mode="physical"``: the effective-medium transfer matrix of the staggered lattice of touching
    rods (:func:`pavonine.materials.stack.lattice_reflectance_emt`), TE and TM averaged, refraction
    and absorption included. ``mode="paper"`` (or ``"intensity"``): Eq. 2's row reflectance times
    Eq. 4's layer factor at ``θ_in = θ_out = θ`` (the paper's reading, for comparison). A
    non-integer ``layers`` interpolates between ⌊N⌋ and ⌈N⌉ layers in both.
    """
    lam = np.asarray(wavelength_nm, dtype=np.float64)
    rod_index = MELANIN.index(lam) if n_rod is None else np.asarray(n_rod, dtype=np.complex128)
    medium = KERATIN.index(lam).real if n_medium is None else np.asarray(n_medium, np.float64)
    cos_t = np.clip(np.asarray(cos_theta, dtype=np.float64), 0.0, 1.0)
    low = max(math.floor(layers), 1)
    frac = float(layers) - low
    if mode == "physical":
        sin_t = np.sqrt(1.0 - cos_t**2)

        def exact(count: int) -> np.ndarray:
            lattice = RodLattice(float(interval_nm), float(radius_nm), count)
            return lattice_reflectance_emt(
                lattice, lam, n_rod=rod_index, n_matrix=medium, sin_above=sin_t
            )

        r = exact(low)
        return r if frac <= 1e-9 else r + (exact(low + 1) - r) * frac
    if mode not in ("paper", "intensity"):
        raise ValueError(f"mode must be 'physical', 'paper' or 'intensity', got {mode!r}")
    lam_b, cos_b, m_b, n0_b = np.broadcast_arrays(lam, cos_t, rod_index / medium, medium)
    single = np.empty(lam_b.shape)
    for i in np.ndindex(lam_b.shape):
        x = 2.0 * math.pi * n0_b[i] * radius_nm / lam_b[i]
        single[i] = rod.row_reflectance(x, complex(m_b[i]), np.array([cos_b[i]]))[0]
    d_opt = optical_distance(interval_nm, radius_nm, np.real(rod_index), medium)
    return multilayer_intensity(single, float(layers), d_opt, cos_t, cos_t, lam, mode)


@functools.lru_cache(maxsize=32)
def model_for(params: FeatherParameters) -> FeatherModel:
    """A cached :class:`FeatherModel` (the row-reflectance table is built once per material)."""
    return FeatherModel(params)


def reflectance_spectra(
    params: FeatherParameters,
    incidence_deg: float,
    observe_deg: np.ndarray,
    *,
    ocellar_class: int = 0,
    gradation: float = 0.0,
    azimuth_deg: float = 90.0,
    structural_share: float = 1.0,
    wavelengths_nm: np.ndarray = PLOT_WAVELENGTHS_NM,
    barbule_tilt_deg: float = 0.0,
    barbule_twist_deg: float = 0.0,
) -> np.ndarray:
    """Reflectance factor ``π f(ω_i, ω_o, λ)`` (relative to a perfect white diffuser), shape (n_obs, n_λ).

    In-plane geometry as in the paper's Figure 5: the light at ``incidence_deg`` and the observer at
    ``observe_deg`` on the opposite side of the vane normal (negative = same side as the light), in
    the plane at ``azimuth_deg`` from the barbule's long axis (90° = across the barbule).
    ``barbule_tilt_deg`` inclines the barbule's long axis out of the vane (a rotation about its
    across axis), ``barbule_twist_deg`` turns it about its long axis (the barbule's macro-geometry,
    §2.1: "curved along their length and slightly twisted at the root").
    """
    wavelengths = check_wavelengths(wavelengths_nm)
    incidence = check_angle("incidence", incidence_deg)
    observe = np.array([check_angle("observe", o) for o in np.atleast_1d(observe_deg)])
    if not math.isfinite(azimuth_deg):
        raise ParameterError("azimuth", f"must be a finite angle, got {azimuth_deg}")
    for name, value in (("gradation", gradation), ("structural_share", structural_share)):
        if not 0.0 <= value <= 1.0:  # also rejects NaN
            raise ParameterError(name, f"must lie in [0, 1], got {value}")
    model = model_for(params)
    frame = barbule_frame(barbule_tilt_deg, barbule_twist_deg)
    wi = direction(incidence, azimuth_deg) @ frame
    wo = (direction(observe, azimuth_deg + 180.0) @ frame)[:, None, :]
    f = model.brdf(wi, wo, wavelengths[None, :], ocellar_class, gradation, structural_share)
    return math.pi * f


def barbule_frame(tilt_deg: float = 0.0, twist_deg: float = 0.0) -> np.ndarray:
    """Columns: the tilted, twisted barbule's axes (long, across, normal) in vane coordinates;
    ``v @ frame`` takes a vane-frame direction into the barbule frame."""
    for name, value in (("barbule_tilt", tilt_deg), ("barbule_twist", twist_deg)):
        if not (math.isfinite(value) and abs(value) <= 60.0):
            raise ParameterError(name, f"must lie in [-60, 60] degrees, got {value}")
    t, w = math.radians(tilt_deg), math.radians(twist_deg)
    tilt = np.array([[math.cos(t), 0, -math.sin(t)], [0, 1, 0], [math.sin(t), 0, math.cos(t)]])
    twist = np.array([[1, 0, 0], [0, math.cos(w), -math.sin(w)], [0, math.sin(w), math.cos(w)]])
    return tilt @ twist


@dataclass(frozen=True)
class SpectrumSummary:
    """Peak wavelength, full width at half maximum and display colour of one spectrum."""

    observe_deg: float
    peak_nm: float
    fwhm_nm: float | None
    srgb: tuple[float, float, float]
    peak_value: float

    def as_json(self) -> dict:
        """Stable keys: ``observe_deg``, ``peak_nm``, ``peak_reflectance`` (the peak of the plotted
        reflectance factor πf), ``fwhm_nm`` (None if the band does not close), ``srgb``."""
        return {
            "observe_deg": self.observe_deg,
            "peak_nm": round(self.peak_nm, 2),
            "peak_reflectance": round(self.peak_value, 4),
            "fwhm_nm": None if self.fwhm_nm is None else round(self.fwhm_nm, 2),
            "srgb": [round(c, 4) for c in self.srgb],
        }


def peak_and_width(wavelengths_nm: np.ndarray, values: np.ndarray) -> tuple[float, float | None]:
    """Peak wavelength (parabolic refinement) and FWHM of the band around it (None if not closed)."""
    w, v = np.asarray(wavelengths_nm, float), np.asarray(values, float)
    i = int(np.argmax(v))
    peak = w[i]
    if 0 < i < len(v) - 1:
        denom = v[i - 1] - 2 * v[i] + v[i + 1]
        if denom < 0:
            peak = w[i] + 0.5 * (v[i - 1] - v[i + 1]) / denom * (w[1] - w[0])
    half = 0.5 * v[i]
    left = np.nonzero(v[:i] < half)[0]
    right = np.nonzero(v[i:] < half)[0]
    if half <= 0 or left.size == 0 or right.size == 0:
        return float(peak), None
    j, k = left[-1], i + right[0]
    lo = w[j] + (half - v[j]) / (v[j + 1] - v[j]) * (w[j + 1] - w[j])
    hi = w[k - 1] + (half - v[k - 1]) / (v[k] - v[k - 1]) * (w[k] - w[k - 1])
    return float(peak), float(hi - lo)


def summarise(
    params: FeatherParameters,
    incidence_deg: float,
    observe_deg: np.ndarray,
    **kwargs,
) -> list[SpectrumSummary]:
    """One :class:`SpectrumSummary` per observation angle; colour over 360–830 nm under D65."""
    observe = np.atleast_1d(np.asarray(observe_deg, float))
    plot = reflectance_spectra(params, incidence_deg, observe, **kwargs)
    full = reflectance_spectra(
        params, incidence_deg, observe, wavelengths_nm=COLOUR_WAVELENGTHS_NM, **kwargs
    )
    rgb = colour.reflectance_to_linear_srgb(COLOUR_WAVELENGTHS_NM, full)
    swatches = colour.swatch(rgb)
    out = []
    for o, spectrum, sw in zip(observe, plot, swatches, strict=True):
        peak, width = peak_and_width(PLOT_WAVELENGTHS_NM, spectrum)
        out.append(
            SpectrumSummary(
                float(o), peak, width, tuple(float(c) for c in sw), float(spectrum.max())
            )
        )
    return out


def directional_albedo(
    params: FeatherParameters,
    incidence_deg: float,
    *,
    azimuth_deg: float = 90.0,
    ocellar_class: int = 0,
    gradation: float = 0.0,
    structural_share: float = 1.0,
    wavelengths_nm: np.ndarray = COLOUR_WAVELENGTHS_NM,
    n_slopes: int = 96,
) -> np.ndarray:
    """Directional albedo ``∫ f(ω_i, ω_o) cos θ_o dω_o`` per wavelength, by quadrature over slopes.

    The structural lobe is integrated in microfacet-slope space around the normal (h =
    normalize(−p, −q, 1), ``dω_o = 4 (ω_i·h) h_z³ dp dq``), which resolves narrow lobes exactly
    where the BRDF lives; the melanin part is Lambertian and integrates to ρ in closed form.
    """
    model = model_for(params)
    wavelengths = check_wavelengths(wavelengths_nm)
    wi = direction(check_angle("incidence", incidence_deg), azimuth_deg)
    constants = model.constants
    ax = barbule.beckmann_alpha(
        barbule.along_sigma(constants.block_sigma, constants.rod_length_nm, wavelengths.max())
    )
    ay = barbule.beckmann_alpha(constants.crescent_sigma)
    p = np.linspace(-7.0 * ax, 7.0 * ax, n_slopes)
    q = np.linspace(-7.0 * ay, 7.0 * ay, n_slopes)
    pp, qq = np.meshgrid(p, q, indexing="ij")
    h = np.stack([-pp, -qq, np.ones_like(pp)], -1)
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    i_dot_h = h @ wi
    wo = 2.0 * i_dot_h[..., None] * h - wi
    jac = 4.0 * np.clip(i_dot_h, 0, None) * h[..., 2] ** 3 * (p[1] - p[0]) * (q[1] - q[0])
    f = model.structural(
        np.broadcast_to(wi, wo.shape)[..., None, :],
        wo[..., None, :],
        wavelengths,
        ocellar_class,
        gradation,
    )
    weight = np.clip(wo[..., 2], 0.0, None) * jac
    structural = np.einsum("ijk,ij->k", f, weight)
    return structural_share * structural + (1.0 - structural_share) * melanin_albedo(
        params.melanin_color, wavelengths
    )


def preview_color(
    params: FeatherParameters, ocellar_class: int = 0, gradation: float = 0.5
) -> tuple[float, float, float]:
    """Linear-sRGB colour for non-spectral previews: the D65 colour of the directional albedo at 20°."""
    albedo = directional_albedo(
        params, 20.0, ocellar_class=ocellar_class, gradation=gradation, n_slopes=48
    )
    rgb = np.clip(colour.reflectance_to_linear_srgb(COLOUR_WAVELENGTHS_NM, albedo), 0.0, 1.0)
    return tuple(float(c) for c in rgb)
