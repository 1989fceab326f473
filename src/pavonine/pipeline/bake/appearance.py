"""The model's appearance per texel: base colour under the reference light and view, and a
thin-film stand-in (thickness, index, weight) with a roughness, for non-spectral viewers.

**Reference illumination and view** (in the asset's object space, where the vane's iridescent
front faces +Z, +X is the feather's right and +Y runs up the shaft): a CIE D65 distant light (the
white of Pavonine's spectral renderer) from ``(sin 25°, 0, cos 25°)``, 25° off the front toward
the right, and the viewer straight in front, along +Z: the shipped scene
``assets/scenes/eye_feather_sun.usda`` (its sun; its camera looks at the feather face-on) and,
within a degree, ``pavonine render``'s default sun for a bare asset. Each texel sees them in its
own frame: its interpolated normal, its barbule axis (the barb direction turned by the angle
map), so the feather's curvature and its barbules' directions are in the bake.

**Base colour** is the reflectance factor ``π f(ω_i, ω_o)`` there (a white diffuser reads 1) as
linear Rec. 709 under D65: a Lambertian surface of that albedo returns exactly the model's
radiance in the reference configuration. It is ``w·S + (1 − w)·M`` with ``w`` the melanin map's
structural share, ``S`` the structural colour and ``M`` the melanin brown. ``S`` is the BRDF of
:mod:`pavonine.materials.brdf` evaluated per texel and wavelength (380–780 nm, 10 nm) exactly as
the renderer's feather BSDF does (``pavonine.materials.jit.JitMaterial``, JIT-compiled by
Dr.Jit; a NumPy fallback through ``pavonine.materials.optics.model_for(params).brdf`` where no
LLVM variant is available), whatever the model's interference mode. Colours outside the sRGB
gamut are clipped to it.

**Thin film.** Index: the rod layer's effective index ``n_eff = n_0 + f·(n_ml − n_0)``,
``f = π a / (2 d)`` (Eq. 1; in the physical mode with the real parts of the dispersive melanin
and keratin indices at the texel's peak wavelength), of the two barbule axes weighted by ``cos²ψ : sin²ψ`` of the
reference half-vector (Eq. 7). Thickness: ``t = ¾ λ_peak / n_eff``, the film whose first-order
reflection peak (``2 n t = (m + ½) λ``, ``m = 1``: one π shift, at the air/film interface, as in
``materials/pavonine_feather.mtlx``) falls on the texel's peak wavelength ``λ_peak`` of ``S``.
Weight: the structural share ``w``. Roughness: the preview's GGX roughness of the crescent
spread (``pavonine.schemas.authoring.preview_roughness``) where the colour is structural, 1 where
it is melanin: ``w·r + (1 − w)``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from pavonine.base.map_files import sample_bilinear, sample_nearest
from pavonine.materials import colour, optics
from pavonine.materials.parameters import FeatherParameters
from pavonine.pipeline.bake.texels import SurfaceTexels
from pavonine.pipeline.maps.paint import ocellar_class

#: Reference light: degrees off the front (+Z) toward the right (+X).
REFERENCE_INCIDENCE_DEG = 25.0
REFERENCE_LIGHT = np.array(
    [
        math.sin(math.radians(REFERENCE_INCIDENCE_DEG)),
        0.0,
        math.cos(math.radians(REFERENCE_INCIDENCE_DEG)),
    ]
)
REFERENCE_VIEW = np.array([0.0, 0.0, 1.0])
#: Wavelengths of the per-texel spectra (nm): CIE 15's 10 nm grid over the visible.
WAVELENGTHS_NM = np.arange(380.0, 781.0, 10.0)
#: Thin-film order whose peak is matched: 2 n t = (m + ½) λ.
FILM_ORDER = 1
#: Lanes (texels × wavelengths) per Dr.Jit evaluation (2²² rather than 2²⁴: the glTF fit's
#: 728k texels × 6 views, 22 s instead of 30 s CPU and 0.80 instead of 0.92 GB peak).
LANES = 1 << 22
#: Gradation steps of the NumPy fallback (texels are grouped by class and gradation step).
FALLBACK_STEPS = 64


@dataclass
class TexelAppearance:
    """Per covered texel: ``base_color`` (linear Rec. 709, clipped to [0, 1]), ``alpha``,
    ``roughness``, film ``thickness_nm``, ``film_ior`` and ``film_weight``."""

    base_color: np.ndarray
    alpha: np.ndarray
    roughness: np.ndarray
    thickness_nm: np.ndarray
    film_ior: np.ndarray
    film_weight: np.ndarray


@dataclass
class Structure:
    """Per texel: structural reflectance factor spectra ``π f`` (``(n, len(WAVELENGTHS_NM))``)
    and the long and short axes' stacks as ``(interval_nm, radius_nm)`` arrays."""

    spectra: np.ndarray
    long: tuple[np.ndarray, np.ndarray]
    short: tuple[np.ndarray, np.ndarray]


def barbule_frames(texels: SurfaceTexels, angle_grey: np.ndarray) -> np.ndarray:
    """``(n, 3, 3)`` rows x (barbule long axis), y = n × x, n: the barb direction turned by
    ``angle_grey · 180°`` counter-clockwise about the normal (seen from the front), as the
    feather BSDF reads the angle map."""
    turn = math.pi * np.asarray(angle_grey, dtype=np.float64)
    side = np.cross(texels.normal, texels.barb)
    x = np.cos(turn)[:, None] * texels.barb + np.sin(turn)[:, None] * side
    return np.stack([x, np.cross(texels.normal, x), texels.normal], axis=1)


def structure(
    params: FeatherParameters, k: np.ndarray, t: np.ndarray, wi: np.ndarray, wo: np.ndarray
) -> Structure:
    """The structural BRDF per texel (class ``k``, gradation ``t``, barbule-frame ``wi``/``wo``)
    at :data:`WAVELENGTHS_NM`, through the renderer's JIT path or the NumPy model."""
    from pavonine.base.backend import select_variant

    try:
        variant = select_variant().variant
    except ImportError:  # no Mitsuba: `pip install pavonine[convert]` without [render]
        variant = None
    if variant is not None and variant.startswith("llvm_"):
        return _structure_jit(params, k, t, wi, wo)
    return _structure_numpy(params, k, t, wi, wo)


def _structure_jit(params, k, t, wi, wo) -> Structure:
    import drjit as dr
    import mitsuba as mi

    from pavonine.materials.jit import JitMaterial

    material = JitMaterial(params)
    n, count = len(k), len(WAVELENGTHS_NM)
    spectra = np.empty((n, count), dtype=np.float64)
    table = mi.Float(WAVELENGTHS_NM.astype(np.float32))
    step = max(1, LANES // count)
    for start in range(0, n, step):
        end = min(n, start + step)
        # One lane per (texel, wavelength): texel data are gathered inside the kernel.
        lane = dr.arange(mi.UInt32, (end - start) * count)
        texel, band = lane // count, lane % count

        def per_lane(values: np.ndarray, kind=mi.Float, s=start, e=end, index=texel):
            return dr.gather(kind, kind(np.ascontiguousarray(values[s:e])), index)

        long_stack, short_stack = material.stacks(
            per_lane(k.astype(np.uint32), mi.UInt32), per_lane(t.astype(np.float32))
        )
        directions = [
            mi.Vector3f(*(per_lane(v[:, i].astype(np.float32)) for i in range(3))) for v in (wi, wo)
        ]
        wavelengths = dr.gather(mi.Float, table, band)
        value = material.brdf(*directions, wavelengths, long_stack, short_stack, mi.Float(1.0))
        dr.eval(value)
        spectra[start:end] = math.pi * np.asarray(value, dtype=np.float64).reshape(-1, count)
    return Structure(spectra, *stack_dimensions(params, k, t))


def _structure_numpy(params, k, t, wi, wo) -> Structure:
    model = optics.model_for(params)
    steps = np.rint(np.clip(t, 0.0, 1.0) * FALLBACK_STEPS).astype(np.int64)
    spectra = np.empty((len(k), len(WAVELENGTHS_NM)))
    for key in np.unique(k * (FALLBACK_STEPS + 1) + steps):
        klass, step = divmod(int(key), FALLBACK_STEPS + 1)
        group = (k == klass) & (steps == step)
        gradation = step / FALLBACK_STEPS
        f = model.brdf(wi[group, None, :], wo[group, None, :], WAVELENGTHS_NM, klass, gradation)
        spectra[group] = math.pi * f
    return Structure(spectra, *stack_dimensions(params, k, t))


def stack_dimensions(
    params: FeatherParameters, k: np.ndarray, t: np.ndarray
) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """Per texel, the long and short axes' ``(interval_nm, radius_nm)``: each class's black and
    white ends interpolated by the gradation ``t`` (Table 1 / the preset), in every mode."""
    arrays = params.class_arrays()
    t = np.clip(np.asarray(t, dtype=np.float64), 0.0, 1.0)

    def lerp(name: str) -> np.ndarray:
        black, white = arrays[name][k, 0], arrays[name][k, 1]
        return 1e3 * (black + (white - black) * t)  # µm → nm

    return tuple(  # type: ignore[return-value]
        (lerp(f"{axis}_interval"), lerp(f"{axis}_radius")) for axis in ("long", "short")
    )


def effective_index(
    params: FeatherParameters, interval_nm, radius_nm, wavelength_nm=None
) -> np.ndarray:
    """``n_eff = D / d`` of a rod layer (Eq. 1); in the physical mode with the dispersive
    melanin and keratin indices (real parts) at ``wavelength_nm``."""
    if params.interference == "physical" and wavelength_nm is not None:
        n_rod, n_medium = params.melanin.real(wavelength_nm), params.keratin.real(wavelength_nm)
    else:
        n_rod, n_medium = params.melanin_index, params.medium_index
    distance = optics.optical_distance(interval_nm, radius_nm, n_rod, n_medium)
    return distance / interval_nm


def texel_appearance(
    texels: SurfaceTexels,
    maps: Mapping[str, np.ndarray],
    params: FeatherParameters,
    roughness: float,
) -> TexelAppearance:
    """The appearance of every covered texel from the six maps (module docstring).

    ``maps``: grey images ``[row, column]`` in [0, 1] keyed by map name (a missing map is
    uniform: alpha 1, class 0, gradation 0, angle 0, structural share 1). ``roughness``: the
    structural part's GGX roughness.
    """
    inputs = _texel_inputs(texels, maps, params)
    share, frames = inputs["share"], inputs["frames"]
    wi = frames @ REFERENCE_LIGHT
    wo = frames @ REFERENCE_VIEW
    base, found = _reflectance(params, inputs, REFERENCE_LIGHT, REFERENCE_VIEW)
    # Eq. 7's weight of the long axis at the reference half-vector: cos²ψ = h_x² / (h_x² + h_y²).
    h = wi + wo
    across = h[:, 0] ** 2 + h[:, 1] ** 2
    cos2_psi = np.where(across > 1e-12, h[:, 0] ** 2 / np.maximum(across, 1e-12), 0.5)
    peak = WAVELENGTHS_NM[np.argmax(found.spectra, axis=1)]
    film_ior = cos2_psi * effective_index(params, *found.long, peak) + (
        1.0 - cos2_psi
    ) * effective_index(params, *found.short, peak)
    return TexelAppearance(
        base_color=np.clip(base, 0.0, 1.0),
        alpha=inputs["alpha"],
        roughness=share * roughness + (1.0 - share),
        thickness_nm=(FILM_ORDER + 0.5) * peak / (2.0 * film_ior),
        film_ior=film_ior,
        film_weight=share,
    )


def _texel_inputs(texels: SurfaceTexels, maps: Mapping[str, np.ndarray], params) -> dict:
    """Per covered texel: class ``k``, ``gradation``, structural ``share``, ``alpha`` and the
    barbule ``frames``, sampled from the maps (a missing map is uniform, as documented in
    :func:`texel_appearance`)."""
    uv = texels.feather_uv
    n = len(uv)

    def bilinear(name: str, default: float) -> np.ndarray:
        values = maps.get(name)
        grey = np.full(n, default) if values is None else sample_bilinear(values, uv)
        return np.clip(grey, 0.0, 1.0).astype(np.float64)

    grey = maps.get("ocellar")
    k = np.zeros(n, dtype=np.int64)
    if grey is not None:
        k = ocellar_class(sample_nearest(grey, uv), classes=len(params.classes)).astype(np.int64)
    return {
        "k": k,
        "gradation": bilinear("gradation", 0.0),
        "share": bilinear("melanin", 1.0),
        "alpha": bilinear("alpha", 1.0),
        "frames": barbule_frames(texels, bilinear("angle", 0.0)),
    }


def _reflectance(params, inputs: dict, light: np.ndarray, view: np.ndarray):
    """The model's reflectance factor ``π f`` (linear Rec. 709, unclipped) of every texel for a
    distant ``light`` (object space) and a ``view`` (object space: one direction ``(3,)``, or one
    per texel ``(n, 3)``), and the structural part's :class:`Structure`."""
    frames = inputs["frames"]
    local_view = frames @ view if view.ndim == 1 else np.einsum("nij,nj->ni", frames, view)
    found = structure(params, inputs["k"], inputs["gradation"], frames @ light, local_view)
    structural = colour.reflectance_to_linear_srgb(WAVELENGTHS_NM, found.spectra)
    model = optics.model_for(params)

    def melanin_rgb(toward: np.ndarray) -> np.ndarray:
        melanin = model.brdf(light, toward, WAVELENGTHS_NM, 0, 0.0, structural_share=0.0)
        return colour.reflectance_to_linear_srgb(WAVELENGTHS_NM, math.pi * melanin)

    if view.ndim == 1:
        melanin = melanin_rgb(view)
    else:
        # The melanin term is Lambertian, ρ/π on the light's side and 0 behind (paper §3.3.6,
        # materials/brdf.py feather_brdf): it depends on a view only through its side, so the
        # views straight out of either side serve every texel (a grazing view gets none).
        front, back = (
            melanin_rgb(np.array([0.0, 0.0, 1.0])),
            melanin_rgb(np.array([0.0, 0.0, -1.0])),
        )
        side = view[:, 2:3]
        melanin = np.where(side > 0.0, front, np.where(side < 0.0, back, 0.0))
    share = inputs["share"][:, None]
    return share * structural + (1.0 - share) * melanin, found


def reflectance_at_views(
    texels: SurfaceTexels,
    maps: Mapping[str, np.ndarray],
    params: FeatherParameters,
    light: np.ndarray,
    views: np.ndarray,
) -> tuple[np.ndarray, dict]:
    """``(n, k, 3)``: every covered texel's reflectance factor ``π f`` (linear Rec. 709,
    unclipped) for the distant ``light`` and ``k`` views (object-space unit vectors toward the
    light and the viewer: ``views`` ``(k, 3)`` the same for every texel, or ``(n, k, 3)`` one
    set per texel, as a viewer at a finite distance sees them), as :func:`texel_appearance`
    computes it for the reference pair; and the texels' inputs (``alpha``, ``share``,
    ``frames``: rows tangent, bitangent, normal)."""
    inputs = _texel_inputs(texels, maps, params)
    views = np.asarray(views, dtype=np.float64)
    per_texel = views.ndim == 3
    found = [
        _reflectance(params, inputs, light, views[:, j] if per_texel else views[j])[0]
        for j in range(views.shape[-2])
    ]
    return np.stack(found, axis=1), inputs
