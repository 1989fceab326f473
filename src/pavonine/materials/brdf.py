"""The feather BRDF: rod layers (Eq. 1–4) on a barbule whose normals spread (Eq. 6 + blocks),
blended over the two barbule axes (Eq. 7), mixed with melanin brown (§3.3.6).

Local frame (the *barbule frame*): ``z`` the vane normal, ``x`` the barbule's long axis, ``y``
across it. For light ``ω_i`` and view ``ω_o`` (unit vectors, pointing away from the surface) with
half-vector ``h``, each barbule axis behaves as a specular multilayer seen at ``cos θ_d = ω_i·h``:

    R_s(λ) = R₁(x_s, cos θ_d) · A(δ_s, N_s)                      (Eq. 2–4, per axis s)
    R(λ)   = cos²ψ R_long + sin²ψ R_short,  cos²ψ = h_x² / (h_x² + h_y²)            (Eq. 7)
    f_s    = R(λ) D(h) G₁(ω_i) G₁(ω_o) / (4 cos θ_i cos θ_o)   (microfacet form, Walter 2007)
    f      = w f_s + (1 − w) ρ_melanin(λ) / π                                     (§3.3.6)

with ``R₁`` the row reflectance of :func:`pavonine.materials.rod.row_reflectance`, ``A`` the
layer array factor of :func:`pavonine.materials.layers.array_factor` at the phase
``δ = 2π D (2 cos θ_d) / λ``, ``D`` the anisotropic Beckmann distribution of
:mod:`pavonine.materials.barbule`, ``w`` the melanin map's structural share. Within the facet
frame the row of Eq. 3 is met at its specular condition (phase 0, factor 1).

Every function takes an ``ops`` namespace, so this one implementation runs on NumPy (analysis) and,
JIT-compiled, on Dr.Jit inside the Mitsuba BSDF.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from pavonine.materials import barbule, glitter, layers, rod
from pavonine.materials.arraymath import NUMPY, bilinear_gather
from pavonine.materials.parameters import FeatherParameters, LayerStack
from pavonine.materials.stack import StackTable

UM_TO_NM = 1000.0
#: Half-vector tilt (degrees) over which Eq. 7's blend fades to equal weights near the normal.
ORIENTATION_FADE_DEG = 6.0
ORIENTATION_FADE_T2 = math.tan(math.radians(ORIENTATION_FADE_DEG)) ** 2


@dataclass(frozen=True)
class RowTable:
    """``R₁(x, cos θ)`` on a regular grid (flattened row-major), see :func:`rod.row_reflectance_table`."""

    values: Any
    x_max: float
    n_x: int
    n_cos: int

    @classmethod
    def build(cls, m: complex) -> RowTable:
        table, x_max, n_x, n_cos = rod.row_reflectance_table(m)
        return cls(table.ravel(), x_max, n_x, n_cos)

    def with_values(self, values) -> RowTable:
        """The same table with its values in another array type (a Dr.Jit buffer)."""
        return RowTable(values, self.x_max, self.n_x, self.n_cos)

    def lookup(self, x: Any, cos_theta: Any, ops: Any = NUMPY) -> Any:
        """Bilinear interpolation of the table at ``(x, cos θ)`` (clamped to the grid)."""
        fx = ops.minimum(ops.maximum(x * ((self.n_x - 1) / self.x_max), 0.0), self.n_x - 1.0001)
        fc = ops.minimum(ops.maximum(cos_theta * (self.n_cos - 1.0), 0.0), self.n_cos - 1.0001)
        ix, ic = ops.floor(fx), ops.floor(fc)
        tx, tc = fx - ix, fc - ic
        return bilinear_gather(self.values, ix * self.n_cos + ic, self.n_cos, tc, tx, ops)


@dataclass(frozen=True)
class MaterialConstants:
    """Material-wide constants of the BRDF, in the units the BRDF uses (nm, radians)."""

    n_rod: float
    n_medium: float
    crescent_sigma: float  # radians
    block_sigma: float  # radians
    rod_length_nm: float
    interference: str
    glitter: float = 0.0  # share of the along-barbule spread that is between blocks
    block_length_nm: float = 25_000.0  # a block's length: its speckle grains' width

    @classmethod
    def from_parameters(cls, params: FeatherParameters) -> MaterialConstants:
        return cls(
            n_rod=params.melanin_index,
            n_medium=params.medium_index,
            crescent_sigma=math.radians(params.crescent_sigma_deg),
            block_sigma=math.radians(params.block_sigma_deg),
            rod_length_nm=params.rod_length_um * UM_TO_NM,
            interference=params.interference,
            glitter=params.glitter,
            block_length_nm=params.block_length_um * UM_TO_NM,
        )


def stack_reflectance(
    constants: MaterialConstants,
    table: RowTable,
    wavelength_nm: Any,
    cos_d: Any,
    interval_nm: Any,
    radius_nm: Any,
    count: Any,
    ops: Any = NUMPY,
) -> Any:
    """Specular reflectance of one axis' rod-layer stack at local incidence ``cos θ_d`` (Eq. 1–4)."""
    d_opt = layers.optical_distance(interval_nm, radius_nm, constants.n_rod, constants.n_medium)
    x = (2.0 * math.pi * constants.n_medium) * radius_nm / wavelength_nm
    single = table.lookup(x, cos_d, ops)
    return layers.multilayer_intensity(
        single, count, d_opt, cos_d, cos_d, wavelength_nm, constants.interference, ops
    )


def axis_reflectance(
    constants: MaterialConstants, table: Any, wavelength_nm: Any, cos_d: Any, stack: tuple, ops: Any
) -> Any:
    """Specular reflectance of one barbule axis at outside incidence ``cos θ_d``.

    Paper modes: Eq. 1–4 from the stack's ``(interval_nm, radius_nm, count)`` and the
    :class:`RowTable`. Physical mode: the :class:`StackTable` at ``stack = (entry, gradation)``.
    """
    if constants.interference == "physical":
        return table.lookup(stack[0], stack[1], wavelength_nm, cos_d, ops)
    return stack_reflectance(constants, table, wavelength_nm, cos_d, *stack, ops=ops)


def orientation_weight(hx: Any, hy: Any, hz: Any, ops: Any = NUMPY) -> Any:
    """``cos²ψ`` of Eq. 7 from the half-vector, fading to ½ as its tilt goes to zero.

    ``cos²ψ = ½ + ½ (h_x² − h_y²) / (h_x² + h_y² + t₀² h_z²)``, ``t₀ = tan(ORIENTATION_FADE_DEG)``:
    the azimuth ``ψ`` of the half-vector is undefined on the normal, so the blend goes smoothly to
    equal weights there instead of jumping between the axes (no seams inside the highlight);
    beyond a few degrees of tilt it is the plain ``h_x² / (h_x² + h_y²)``. Depends on ``h`` only,
    so the BRDF stays reciprocal.
    """
    hxx, hyy = hx * hx, hy * hy
    return 0.5 + 0.5 * (hxx - hyy) / (hxx + hyy + ORIENTATION_FADE_T2 * hz * hz + 1e-30)


def structural_brdf(
    constants: MaterialConstants,
    table: RowTable,
    wi: tuple[Any, Any, Any],
    wo: tuple[Any, Any, Any],
    wavelength_nm: Any,
    long_stack: tuple[Any, Any, Any],
    short_stack: tuple[Any, Any, Any],
    ops: Any = NUMPY,
    block: Any = None,
) -> Any:
    """Structural-colour BRDF (1/sr) in the barbule frame; stacks are ``(interval_nm, radius_nm, count)``.

    Two-sided: light from below the vane is treated as the mirror image from above. Zero when
    ``ω_i`` and ``ω_o`` lie on opposite sides. ``block``: the tilt and speckle grains of the block
    the point lies on (:class:`pavonine.materials.glitter.Block`), or what the pixel's footprint holds
    there (:class:`pavonine.materials.glitter.Footprint`); ``None`` (or glitter 0) is the smooth
    average over blocks. Masking is the whole microsurface's (Smith G of the smooth lobe), so the
    average over blocks is exactly the smooth BRDF.
    """
    flip = ops.select(wi[2] < 0.0, -1.0, 1.0)
    ix, iy, iz = wi[0], wi[1], wi[2] * flip
    ox, oy, oz = wo[0], wo[1], wo[2] * flip
    hx, hy, hz = ix + ox, iy + oy, iz + oz
    inv_len = 1.0 / ops.sqrt(ops.maximum(hx * hx + hy * hy + hz * hz, 1e-20))
    hx, hy, hz = hx * inv_len, hy * inv_len, hz * inv_len
    cos_d = ops.minimum(ops.maximum(ix * hx + iy * hy + iz * hz, 0.0), 1.0)

    r_long = axis_reflectance(constants, table, wavelength_nm, cos_d, long_stack, ops)
    if getattr(table, "shared_axes", False):
        reflectance = r_long  # one structure along both axes: Eq. 7 blends two equal values
    else:
        r_short = axis_reflectance(constants, table, wavelength_nm, cos_d, short_stack, ops)
        weight = orientation_weight(hx, hy, hz, ops)
        reflectance = barbule.orientation_blend(r_long, r_short, weight)

    sigma_x = barbule.along_sigma(
        constants.block_sigma, constants.rod_length_nm, wavelength_nm, ops
    )
    alpha_x = barbule.beckmann_alpha(sigma_x, ops)
    alpha_y = barbule.SQRT2 * math.tan(constants.crescent_sigma)
    if block is None or constants.glitter == 0.0:
        d = barbule.beckmann_ndf(hx, hy, hz, alpha_x, alpha_y, ops)
    else:
        speckle, within = glitter.grain_split(
            constants, constants.glitter, sigma_x, wavelength_nm, ops
        )
        if isinstance(block, glitter.Footprint):
            d = glitter.footprint_ndf(
                hx, hy, hz, alpha_x, alpha_y, within, speckle, constants, block, ops
            )
        else:
            d = glitter.block_ndf(hx, hy, hz, barbule.SQRT2 * within, alpha_y, block, speckle, ops)
    g = barbule.beckmann_smith_g1(ix, iy, iz, cos_d, alpha_x, alpha_y, ops)
    g = g * barbule.beckmann_smith_g1(
        ox, oy, oz, ox * hx + oy * hy + oz * hz, alpha_x, alpha_y, ops
    )
    denom = 4.0 * iz * oz
    value = reflectance * d * g / ops.maximum(denom, 1e-12)
    return ops.select((iz > 0.0) & (oz > 0.0), value, 0.0)


def feather_brdf(
    constants: MaterialConstants,
    table: RowTable,
    wi: tuple[Any, Any, Any],
    wo: tuple[Any, Any, Any],
    wavelength_nm: Any,
    long_stack: tuple[Any, Any, Any],
    short_stack: tuple[Any, Any, Any],
    structural_share: Any,
    melanin_albedo: Any,
    ops: Any = NUMPY,
    block: Any = None,
) -> Any:
    """Full BRDF (1/sr): ``w f_structural + (1 − w) ρ_melanin / π`` (paper §3.3.6), two-sided."""
    structural = structural_brdf(
        constants, table, wi, wo, wavelength_nm, long_stack, short_stack, ops, block
    )
    same_side = wi[2] * wo[2] > 0.0
    diffuse = ops.select(same_side, melanin_albedo * (1.0 / math.pi), 0.0)
    return structural_share * structural + (1.0 - structural_share) * diffuse


@functools.lru_cache(maxsize=16)
def reflectance_table(params: FeatherParameters) -> RowTable | StackTable:
    """The material's reflectance table: Eq. 2's row table (paper modes) or the physical stack
    table (built once per material, about 0.1 s per class and axis)."""
    if params.interference == "physical":
        return StackTable(params)
    return RowTable.build(complex(params.melanin_index / params.medium_index))


def stack_in_nm(stack: LayerStack) -> tuple[float, float, float]:
    """``(interval_nm, radius_nm, count)`` of a :class:`LayerStack` (µm in the parameters)."""
    return stack.interval * UM_TO_NM, stack.radius * UM_TO_NM, stack.count


@functools.cache
def _melanin_coefficients(color: tuple[float, float, float]) -> np.ndarray:
    """Mitsuba's upsampling coefficients of ``color``; without Mitsuba (not installed, or unable
    to load a system library), the same fit in NumPy (:mod:`pavonine.materials.upsampling`,
    checked against Mitsuba's in the tests)."""
    from pavonine.base.backend import select_variant
    from pavonine.materials.upsampling import fit_sigmoid_polynomial

    try:
        select_variant()
    except ImportError:  # not installed (ModuleNotFoundError), or cannot load (RendererUnavailable)
        return fit_sigmoid_polynomial(color)
    import mitsuba as mi

    return np.array(mi.srgb_model_fetch(mi.ScalarColor3f(*color)), dtype=np.float64)


def srgb_model_eval(coefficients: Any, wavelength_nm: Any, ops: Any = NUMPY) -> Any:
    """Jakob & Hanika 2019 sigmoid-polynomial spectrum: ``½ + v / (2√(1 + v²))``, ``v = c0 λ² + c1 λ + c2``.

    The spectral upsampling Mitsuba applies to every sRGB reflectance (``mi.srgb_model_eval``).
    """
    v = (coefficients[0] * wavelength_nm + coefficients[1]) * wavelength_nm + coefficients[2]
    return 0.5 + 0.5 * v / ops.sqrt(1.0 + v * v)


def melanin_albedo(color: tuple[float, float, float], wavelength_nm: Any) -> np.ndarray:
    """Melanin-brown diffuse albedo spectrum, upsampled from ``melanin_color`` like Mitsuba does."""
    return srgb_model_eval(_melanin_coefficients(tuple(color)), np.asarray(wavelength_nm, float))


class FeatherModel:
    """The feather BRDF for one :class:`FeatherParameters`, evaluated with NumPy.

    ``brdf(wi, wo, λ, ocellar_class, gradation, structural_share)`` broadcasts over arrays; vectors
    are ``(..., 3)`` arrays in the barbule frame.
    """

    def __init__(self, params: FeatherParameters):
        self.params = params.validate()
        self.constants = MaterialConstants.from_parameters(params)
        self.table = reflectance_table(params)

    def stacks_nm(self, ocellar_class: int, gradation: float):
        """``(long, short)`` stacks: ``(interval_nm, radius_nm, count)`` tuples in the paper
        modes, ``(table entry, gradation)`` in the physical mode."""
        long_stack, short_stack = self.params.stacks(ocellar_class, gradation)
        if self.constants.interference == "physical":
            t = min(max(float(gradation), 0.0), 1.0)
            return tuple((self.table.entry(ocellar_class, axis), t) for axis in (0, 1))
        return stack_in_nm(long_stack), stack_in_nm(short_stack)

    def structural(
        self,
        wi,
        wo,
        wavelength_nm,
        ocellar_class: int = 0,
        gradation: float = 0.0,
        block=None,
    ):
        """Structural-colour BRDF only (1/sr); ``block`` as in :func:`structural_brdf`."""
        wi, wo = np.asarray(wi, float), np.asarray(wo, float)
        long_stack, short_stack = self.stacks_nm(ocellar_class, gradation)
        return structural_brdf(
            self.constants,
            self.table,
            (wi[..., 0], wi[..., 1], wi[..., 2]),
            (wo[..., 0], wo[..., 1], wo[..., 2]),
            np.asarray(wavelength_nm, float),
            long_stack,
            short_stack,
            block=block,
        )

    def brdf(
        self,
        wi,
        wo,
        wavelength_nm,
        ocellar_class: int = 0,
        gradation: float = 0.0,
        structural_share: float = 1.0,
        block=None,
    ) -> np.ndarray:
        """Full BRDF (1/sr), melanin mix included; ``block`` as in :func:`structural_brdf`."""
        wi, wo = np.asarray(wi, float), np.asarray(wo, float)
        wavelength_nm = np.asarray(wavelength_nm, float)
        long_stack, short_stack = self.stacks_nm(ocellar_class, gradation)
        return feather_brdf(
            self.constants,
            self.table,
            (wi[..., 0], wi[..., 1], wi[..., 2]),
            (wo[..., 0], wo[..., 1], wo[..., 2]),
            wavelength_nm,
            long_stack,
            short_stack,
            structural_share,
            melanin_albedo(self.params.melanin_color, wavelength_nm),
            block=block,
        )


def direction(theta_deg: Any, phi_deg: Any) -> np.ndarray:
    """Unit vector(s) at polar angle θ from the vane normal and azimuth φ from the barbule axis."""
    t, p = np.radians(theta_deg), np.radians(phi_deg)
    return np.stack(
        np.broadcast_arrays(np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)), -1
    )
