"""The glTF feather material's look, fitted to the one BRDF: what a glTF viewer draws for
``KHR_materials_iridescence`` over a Lambertian base, and the film that makes it match
Pavonine's reflectance at the face-on and tilted reference views.

**What a viewer draws** (glTF 2.0 metallic-roughness, ``metallic`` 0, with
``KHR_materials_specular`` ``specularFactor`` 0 so that glTF's default dielectric F0 = 0.04 does
not add a white lobe the BRDF has not got): for a distant light the reflectance factor (``π f``,
a white diffuser reads 1) is

    ρ(ω_i, ω_o) = base + w · π · I(cos θ_o) · D(n·h) · V(n·l, n·v)                       (1)

with ``D`` the GGX distribution and ``V`` the height-correlated Smith visibility at ``α = r²``
(three.js r187 ``BRDF_GGX``; Walter et al. 2007 Eq. 33, Heitz 2014 Eq. 99), ``w`` the
iridescence factor and ``I`` the film's RGB Fresnel term of the ``KHR_materials_iridescence``
reference (Belcour & Barla 2017, "A practical extension to microfacet theory for the modeling of
varying iridescence": an Airy sum whose first two orders are integrated against Gaussian fits of
the CIE 1931 functions in Fourier space, then XYZ → linear Rec. 709), evaluated at the *view*
angle, as the extension specifies. With ``specularFactor`` 0 the film's substrate index is 1 (the
extension derives it from F0 = 0): a free-standing film, which is what a barbule's keratin
cortex over its melanin rods is closest to among the films one can say in glTF.

**The fit** (:func:`fit_film`): per texel, the model's reflectance factors ``ρ_k`` at the
reference light and views ``k`` (face-on and tilted, see :data:`VIEWS`) are matched by (1) over a
grid of film thicknesses ``t``: for each ``t`` the least-squares ``w`` (clipped to [0, 1])
explains the change between the views, the base takes the rest (mean over the views, clipped to
[0, 1]); the ``t`` of the smallest relative residual wins. The base is view-independent, so the
film carries all of the angle dependence; the base alone holds what the film cannot.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Tilt of the second reference view about the feather's vertical (+Y) axis, degrees (negative:
#: the viewer moves to the feather's left, away from the reference sun).
TILT_DEG = -40.0
#: Tilts (degrees) :func:`fit_film` matches: the face-on and tilted views and, 8° either side of
#: each, their neighbourhoods (a camera's field of view and a curved vane spread the view
#: directions; two views alone would let the fit pick a lobe that overshoots between them).
FIT_TILTS_DEG = (8.0, 0.0, -8.0, TILT_DEG + 8.0, TILT_DEG, TILT_DEG - 8.0)


def tilted_views(tilts_deg) -> np.ndarray:
    """Unit vectors toward the viewer (object space; +Z faces the viewer face-on) for viewers
    turned by ``tilts_deg`` about +Y."""
    angles = np.radians(np.asarray(tilts_deg, dtype=np.float64))
    return np.stack([np.sin(angles), np.zeros_like(angles), np.cos(angles)], axis=-1)


#: The views :func:`fit_film` is given by :mod:`pavonine.pipeline.export.look`.
VIEWS = tilted_views(FIT_TILTS_DEG)
#: Thickness grid searched by :func:`fit_film` (nm); the glTF range is ``[0, THICKNESS_MAX]``.
THICKNESS_MAX_NM = 1000.0
THICKNESS_STEP_NM = 5.0
#: three.js' floor on the perceptual roughness of punctual lights (``BRDF_GGX``).
MIN_ROUGHNESS = 0.045

#: CIE XYZ → linear Rec. 709 (IEC 61966-2-1), as the extension's reference code uses it.
XYZ_TO_REC709 = np.array(
    [
        [3.2404542, -1.5371385, -0.4985314],
        [-0.9692660, 1.8760108, 0.0415560],
        [0.0556434, -0.2040259, 1.0572252],
    ]
)


def schlick(f0, f90, cos_theta):
    """Schlick's Fresnel in the spherical-Gaussian form three.js uses (Karis 2013):
    ``f0 + (f90 − f0)·2^{(−5.55473 c − 6.98316) c}``."""
    return f0 + (f90 - f0) * np.exp2((-5.55473 * cos_theta - 6.98316) * cos_theta)


def sensitivity(opd_nm: np.ndarray, shift: np.ndarray) -> np.ndarray:
    """Belcour & Barla 2017 Eq. 11 (supplemental Gaussian fits): the Fourier transform of the
    CIE XYZ functions at optical path difference ``opd_nm`` and phase ``shift`` (per channel,
    last axis 3), as linear Rec. 709."""
    phase = 2.0 * math.pi * np.asarray(opd_nm)[..., None] * 1.0e-9
    val = np.array([5.4856e-13, 4.4201e-13, 5.2481e-13])
    pos = np.array([1.6810e06, 1.7953e06, 2.2084e06])
    var = np.array([4.3278e09, 9.3046e09, 6.6121e09])
    xyz = (
        val * np.sqrt(2.0 * math.pi * var) * np.cos(pos * phase + shift) * np.exp(-(phase**2) * var)
    )
    xyz[..., 0] += (
        9.7470e-14
        * math.sqrt(2.0 * math.pi * 4.5282e09)
        * np.cos(2.2399e06 * phase[..., 0] + shift[..., 0])
        * np.exp(-4.5282e09 * phase[..., 0] ** 2)
    )
    return (xyz / 1.0685e-7) @ XYZ_TO_REC709.T


def film_fresnel(
    cos_theta: np.ndarray, film_ior: float, thickness_nm: np.ndarray, base_f0: float = 0.0
) -> np.ndarray:
    """RGB reflectance of a film of index ``film_ior`` and ``thickness_nm`` in air over a base of
    normal-incidence reflectance ``base_f0`` seen at ``cos_theta``: the extension's
    ``evalIridescence`` (Belcour & Barla 2017, Eqs. 4–11; orders 0–2), elementwise."""
    cos1 = np.asarray(cos_theta, dtype=np.float64)
    t = np.asarray(thickness_nm, dtype=np.float64)
    x = np.clip(t / 0.03, 0.0, 1.0)
    eta = 1.0 + (film_ior - 1.0) * x * x * (3.0 - 2.0 * x)  # → air as t → 0 (smoothstep)
    cos2_sq = 1.0 - (1.0 / eta) ** 2 * (1.0 - cos1**2)
    cos2 = np.sqrt(np.maximum(cos2_sq, 0.0))
    r12 = schlick(((eta - 1.0) / (eta + 1.0)) ** 2, 1.0, cos1)
    t121 = 1.0 - r12
    phi21 = math.pi  # eta > 1: no shift entering the film, π on its inside reflection
    root = math.sqrt(min(max(base_f0, 0.0), 0.9999))
    base_ior = (1.0 + root) / (1.0 - root)
    r23 = schlick(((base_ior - eta) / (base_ior + eta)) ** 2, 1.0, cos2)
    phi23 = np.where(base_ior < eta, math.pi, 0.0)
    opd = 2.0 * eta * t * cos2
    phi = (phi21 + phi23)[..., None] * np.ones(3)
    r123 = np.clip(r12 * r23, 1e-5, 0.9999)[..., None]
    rs = (t121**2 * r23)[..., None] / (1.0 - r123)
    total = r12[..., None] + rs
    cm = rs - t121[..., None]
    for m in (1, 2):
        cm = cm * np.sqrt(r123)
        total = total + cm * 2.0 * sensitivity(m * opd, m * phi)
    total = np.maximum(total, 0.0)
    return np.where((cos2_sq < 0.0)[..., None], 1.0, total)


def ggx_lobe(light: np.ndarray, view: np.ndarray, roughness: np.ndarray) -> np.ndarray:
    """``π · D(n·h) · V(n·l, n·v)`` of three.js' ``BRDF_GGX`` in frames whose normal is +Z
    (``light``, ``view``: ``(..., 3)`` unit vectors; perceptual ``roughness``, floored at
    :data:`MIN_ROUGHNESS`): D = α² / (π ((n·h)²(α² − 1) + 1)²) (Walter et al. 2007 Eq. 33),
    V = ½ / (n·l √(α² + (1 − α²)(n·v)²) + n·v √(α² + (1 − α²)(n·l)²)) (Heitz 2014 Eq. 99)."""
    alpha = np.maximum(roughness, MIN_ROUGHNESS) ** 2
    a2 = alpha**2
    half = light + view
    half = half / np.linalg.norm(half, axis=-1, keepdims=True)
    nl = np.clip(light[..., 2], 0.0, 1.0)
    nv = np.clip(view[..., 2], 0.0, 1.0)
    nh = np.clip(half[..., 2], 0.0, 1.0)
    d = a2 / (math.pi * (nh**2 * (a2 - 1.0) + 1.0) ** 2)
    gv = nl * np.sqrt(a2 + (1.0 - a2) * nv**2)
    gl = nv * np.sqrt(a2 + (1.0 - a2) * nl**2)
    return math.pi * d * 0.5 / np.maximum(gv + gl, 1e-6)


@dataclass
class FilmFit:
    """Per texel: view-independent ``base`` (linear Rec. 709, ``(n, 3)``), iridescence
    ``weight``, ``thickness_nm`` and perceptual ``roughness``; and the fitted model's
    ``reflectance`` at the views ``(n, views, 3)``."""

    base: np.ndarray
    weight: np.ndarray
    thickness_nm: np.ndarray
    roughness: np.ndarray
    reflectance: np.ndarray


def glTF_reflectance(fit_base, weight, thickness_nm, light, views, roughness, film_ior):
    """Eq. (1) per texel and view: ``light`` ``(n, 3)``, ``views`` ``(n, k, 3)`` in frames whose
    normal is +Z; returns ``(n, k, 3)``."""
    lobe = ggx_lobe(light[:, None, :], views, np.asarray(roughness)[:, None])
    film = film_fresnel(views[..., 2], film_ior, np.asarray(thickness_nm)[:, None])
    return fit_base[:, None, :] + np.asarray(weight)[:, None, None] * film * lobe[..., None]


def film_table(film_ior: float, cosines: np.ndarray, thickness_nm: np.ndarray) -> np.ndarray:
    """:func:`film_fresnel` on a grid: ``(len(cosines), len(thickness_nm), 3)``."""
    return film_fresnel(cosines[:, None], film_ior, thickness_nm[None, :])


def _film_at(table: np.ndarray, cos_theta: np.ndarray) -> np.ndarray:
    """``table`` (over :data:`COSINES`) linearly interpolated at ``cos_theta`` ``(...)``:
    ``(..., thicknesses, 3)``."""
    x = np.clip(cos_theta, 0.0, 1.0) * (len(COSINES) - 1)
    low = np.minimum(x.astype(np.int64), len(COSINES) - 2)
    frac = (x - low)[..., None, None]
    return table[low] * (1.0 - frac) + table[low + 1] * frac


#: View cosines of the film table :func:`fit_film` interpolates (linear in cos θ).
COSINES = np.linspace(0.0, 1.0, 65)
#: Perceptual roughness values :func:`fit_film` searches.
ROUGHNESS_GRID = np.array([0.25, 0.35, 0.5, 0.7, 1.0])


def _search_chunk(rho, light, views, table, far):
    """The grid search of :func:`fit_film` for one chunk of texels: base, weight, thickness
    index and roughness of the smallest error.

    For thickness ``t`` and roughness ``r`` the film's term at view ``k`` is
    ``s_k = I_k(t) L_k(r)`` (film Fresnel times lobe); ``w`` is the least-squares weight of the
    views' deviations from their mean, ``b = clip(mean_k ρ_k − w mean_k s_k, 0, 1)`` and the
    error ``Σ_k ((b + w s_k − ρ_k) u_k)²`` with ``u = 1 / (ρ + 0.02)``. Every sum over the views
    is a contraction of the film table ``(m, T, k, 3)`` with per-texel weights, and the error is
    expanded in them, so no ``(m, T, k, 3)`` temporary is made per roughness."""
    film = np.moveaxis(_film_at(table, views[:, :, 2]), 1, 2)  # (m, T, k, 3)
    film_sq = film * film
    count = rho.shape[1]
    mean_rho = rho.mean(axis=1)  # (m, 3)
    d_rho = rho - mean_rho[:, None]
    u2 = 1.0 / (rho + 0.02) ** 2  # (m, k, 3)
    u2_sum = u2.sum(axis=1)  # (m, 3)
    rho_u2 = (rho * u2).sum(axis=1)
    rho2_u2 = (rho * rho * u2).sum(axis=1)
    m = len(rho)
    rows = np.arange(m)
    best_error = np.full(m, np.inf)
    base, weight, pick, roughness = np.zeros((m, 3)), np.zeros(m), np.zeros(m, int), np.zeros(m)
    for r in ROUGHNESS_GRID:
        lobe = ggx_lobe(light[:, None, :], views, np.full((m, 1), r))[..., None]  # (m, k, 1)

        def over_views(table_, weights):
            return np.einsum("mtkc,mkc->mtc", table_, np.broadcast_to(weights, rho.shape))

        mean_spec = over_views(film, lobe) / count  # (m, T, 3)
        spec2 = over_views(film_sq, lobe * lobe)  # Σ_k s²
        cross = over_views(film, lobe * d_rho).sum(axis=2)  # Σ_k,c s d_rho
        d_spec2 = (spec2 - count * mean_spec**2).sum(axis=2)  # Σ_k,c (s − mean s)²
        w = np.clip(cross / np.maximum(d_spec2, 1e-12), 0.0, 1.0)  # (m, T)
        b = np.clip(mean_rho[:, None] - w[..., None] * mean_spec, 0.0, 1.0)  # (m, T, 3)
        s_u2 = over_views(film, lobe * u2)  # Σ_k s u²
        rho_s_u2 = over_views(film, lobe * rho * u2)  # Σ_k ρ s u²
        s2_u2 = over_views(film_sq, lobe * lobe * u2)  # Σ_k s² u²
        wc = w[..., None]
        error = (
            b * b * u2_sum[:, None]
            - 2.0 * b * rho_u2[:, None]
            + rho2_u2[:, None]
            + 2.0 * wc * (b * s_u2 - rho_s_u2)
            + wc * wc * s2_u2
        ).sum(axis=2)
        if far is not None:
            error = np.where(far, np.inf, error)
        at = np.argmin(error, axis=1)
        better = error[rows, at] < best_error
        chosen = rows[better], at[better]
        best_error[better] = error[chosen]
        base[better], weight[better] = b[chosen], w[chosen]
        pick[better], roughness[better] = at[better], r
    return base, weight, pick, roughness


def fit_film(
    target: np.ndarray,
    light: np.ndarray,
    views: np.ndarray,
    film_ior: float,
    prior_nm: np.ndarray | None = None,
    window_nm: float = 30.0,
    chunk: int = 2048,
) -> FilmFit:
    """The film, roughness and base of Eq. (1) matching ``target`` (``(n, k, 3)`` reflectance
    factors at ``k`` views) per texel (module docstring). ``light`` ``(n, 3)``, ``views``
    ``(n, k, 3)``: unit vectors in each texel's frame (normal +Z). With ``prior_nm`` (per
    texel) only thicknesses within ``window_nm`` of it are searched."""
    grid = np.arange(0.0, THICKNESS_MAX_NM + 0.5 * THICKNESS_STEP_NM, THICKNESS_STEP_NM)
    table = film_table(film_ior, COSINES, grid)
    n = len(target)
    base = np.empty((n, 3))
    weight = np.empty(n)
    thickness = np.empty(n)
    roughness = np.empty(n)
    for start in range(0, n, chunk):
        s = slice(start, min(n, start + chunk))
        far = None
        if prior_nm is not None:
            far = np.abs(grid[None, :] - prior_nm[s, None]) > window_nm
        b, w, pick, r = _search_chunk(target[s], light[s], views[s], table, far)
        base[s], weight[s], thickness[s], roughness[s] = b, w, grid[pick], r
    fitted = glTF_reflectance(base, weight, thickness, light, views, roughness, film_ior)
    return FilmFit(base, weight, thickness, roughness, fitted)


def fit_base(
    target, light, views, weight, thickness_nm, roughness, film_ior, chunk: int = 1 << 16
) -> FilmFit:
    """The view-independent base that best completes a given film (``weight``,
    ``thickness_nm``, ``roughness`` per texel) to ``target`` ``(n, k, 3)``: the mean over the
    views of what the film leaves, clipped to [0, 1] (least squares in linear RGB); ``chunk``
    texels at a time (the film's temporaries are ``(chunk, k, 3)``)."""
    film = np.empty_like(target, dtype=np.float64)
    for start in range(0, len(target), chunk):
        s = slice(start, start + chunk)
        film[s] = glTF_reflectance(
            np.zeros((len(film[s]), 3)),
            weight[s],
            thickness_nm[s],
            light[s],
            views[s],
            roughness[s],
            film_ior,
        )
    base = np.clip((target - film).mean(axis=1), 0.0, 1.0)
    return FilmFit(base, weight, thickness_nm, roughness, film + base[:, None, :])
