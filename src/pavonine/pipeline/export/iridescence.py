"""The glTF feather material's look, fitted to the one BRDF: what a glTF viewer draws for
``KHR_materials_iridescence`` over a substrate of ``KHR_materials_specular`` colour and a Lambertian
base, and the film that makes it match Pavonine's reflectance at the face-on and tilted views.

**What a viewer draws** (glTF 2.0 metallic-roughness, ``metallic`` 0; ``KHR_materials_specular``
with ``specularFactor`` 1 and a colour that makes the dielectric F0 the substrate's ``F_s`` per
channel): for a distant light the reflectance factor (``π f``, a white diffuser reads 1) is,
per channel,

    ρ = b · (1 − S) + π D V · M · [(1 − w) · S + w · I(cos θ_o; η, t, F_s)]               (1)

with ``S = Schlick(F_s, 1, v·h)``, ``D`` the GGX distribution and ``V`` the height-correlated
Smith visibility at ``α = r²`` (three.js r187 ``BRDF_GGX``; Walter et al. 2007 Eq. 33, Heitz 2014
Eq. 99), ``M = 1 + F_s (1/E − 1)`` three.js' multiple-scattering compensation of the direct
light (Turquin 2019 Eq. 16; ``E`` the lobe's white-furnace albedo at the view,
:func:`specular_albedo`), ``w`` the iridescence factor and ``I`` the film's RGB Fresnel term of the
``KHR_materials_iridescence`` reference (Belcour & Barla 2017, "A practical extension to
microfacet theory for the modeling of varying iridescence": an Airy sum whose first two orders
are integrated against Gaussian fits of the CIE 1931 functions in Fourier space, then XYZ →
linear Rec. 709) for a film of index ``η`` and thickness ``t`` over a substrate of
normal-incidence reflectance ``F_s``, evaluated at the *view* angle, as the extension specifies.
The base is dimmed by ``1 − S``, the light the substrate's dielectric lobe takes (glTF's
``fresnel_mix``). ``F_s = 0`` is a free-standing film. In the barbule the film is the keratin
cortex and the substrate the melanin rods' layer under it, which reflects more, and by channel:
that colour is ``F_s``.

**The fit** (:func:`fit_film`): per texel, the model's reflectance factors ``ρ_k`` at the
reference light and views ``k`` (face-on and tilted, and their neighbours: :data:`FIT_TILTS_DEG`,
of a viewer at a finite distance, :func:`pavonine.pipeline.export.look.viewer_views`) are
matched by (1) over grids of film thickness ``t``, roughness ``r``, weight ``w`` and, per channel,
substrate ``F_s``; the base is the weighted least-squares rest (clipped to [0, 1]). The
error is relative (``1 / (ρ + 0.1)``, :data:`ERROR_FLOOR`) and weighs the face-on and tilted views
:data:`VIEW_WEIGHTS`. The base is view-independent, so the film carries all of the angle
dependence; the base alone holds what the film cannot.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

#: Tilt of the second reference view about the feather's vertical (+Y) axis, degrees (negative:
#: the viewer moves to the feather's left, away from the reference sun).
TILT_DEG = -40.0
#: Tilts (degrees) :func:`fit_film` matches: the face-on and tilted views and, 8° either side of
#: each, their neighbourhoods (a camera's field of view and a curved vane spread the view
#: directions; two views alone would let the fit pick a lobe that overshoots between them).
FIT_TILTS_DEG = (8.0, 0.0, -8.0, TILT_DEG + 8.0, TILT_DEG, TILT_DEG - 8.0)
#: Weights of :data:`FIT_TILTS_DEG` in the fit's error: the two reference views count fully, their
#: neighbours (there to keep the lobe from overshooting between them) a third as much.
VIEW_WEIGHTS = np.array([0.3, 1.0, 0.3, 0.3, 1.0, 0.3])


def tilted_views(tilts_deg) -> np.ndarray:
    """Unit vectors toward the viewer (object space; +Z faces the viewer face-on) for viewers
    turned by ``tilts_deg`` about +Y."""
    angles = np.radians(np.asarray(tilts_deg, dtype=np.float64))
    return np.stack([np.sin(angles), np.zeros_like(angles), np.cos(angles)], axis=-1)


#: The views of :data:`FIT_TILTS_DEG` for a distant viewer (the limit of the per-texel views
#: :mod:`pavonine.pipeline.export.look` gives :func:`fit_film`).
VIEWS = tilted_views(FIT_TILTS_DEG)
#: Thickness grid searched by :func:`fit_film` (nm); the glTF range is ``[0, THICKNESS_MAX]``.
THICKNESS_MAX_NM = 1000.0
THICKNESS_STEP_NM = 5.0
#: Coarser step of the free (first) search; the second searches its neighbourhood at
#: :data:`THICKNESS_STEP_NM`.
FREE_STEP_NM = 10.0
#: Substrate reflectances ``F_s`` the fit chooses from, per channel; the glTF range is
#: ``[0, SUBSTRATE_F0_MAX]``.
SUBSTRATE_F0 = np.array([0.0, 0.03, 0.07, 0.12, 0.18, 0.25, 0.35, 0.5])
SUBSTRATE_F0_MAX = 0.5
#: Added to the target in the fit's relative error, ``(ρ̂ − ρ) / (ρ + ERROR_FLOOR)``: near-black
#: channels are held to an absolute error of about that much.
ERROR_FLOOR = 0.1
#: Iridescence factors ``w`` the fit chooses from.
WEIGHT_GRID = np.array([0.25, 0.5, 0.75, 1.0])
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
    cos_theta: np.ndarray, film_ior: float, thickness_nm: np.ndarray, base_f0=0.0
) -> np.ndarray:
    """RGB reflectance of a film of index ``film_ior`` and ``thickness_nm`` in air over a base of
    normal-incidence reflectance ``base_f0`` (a number, or per channel: last axis 3) seen at
    ``cos_theta``: the extension's ``evalIridescence`` (Belcour & Barla 2017, Eqs. 4–11; orders
    0–2), elementwise; returns ``(..., 3)``. As in the reference code, the base's phase shift of
    channel R, G, B shifts the X, Y, Z sensitivity."""
    cos1 = np.asarray(cos_theta, dtype=np.float64)
    t = np.asarray(thickness_nm, dtype=np.float64)
    x = np.clip(t / 0.03, 0.0, 1.0)
    eta = 1.0 + (film_ior - 1.0) * x * x * (3.0 - 2.0 * x)  # → air as t → 0 (smoothstep)
    cos2_sq = 1.0 - (1.0 / eta) ** 2 * (1.0 - cos1**2)
    cos2 = np.sqrt(np.maximum(cos2_sq, 0.0))
    r12 = schlick(((eta - 1.0) / (eta + 1.0)) ** 2, 1.0, cos1)[..., None]
    t121 = 1.0 - r12
    root = np.sqrt(np.clip(np.asarray(base_f0, dtype=np.float64), 0.0, 0.9999))
    base_ior = np.broadcast_to((1.0 + root) / (1.0 - root), (3,) if root.ndim == 0 else root.shape)
    eta_c = eta[..., None]
    r23 = schlick(((base_ior - eta_c) / (base_ior + eta_c)) ** 2, 1.0, cos2[..., None])
    # eta > 1: no shift entering the film, π on its inside reflection; π at the base if lower
    phi = math.pi + np.where(base_ior < eta_c, math.pi, 0.0)
    opd = 2.0 * eta * t * cos2
    r123 = np.clip(r12 * r23, 1e-5, 0.9999)
    rs = t121**2 * r23 / (1.0 - r123)
    total = r12 + rs
    cm = rs - t121
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
    return math.pi * d * smith_visibility(nl, nv, a2)


def smith_visibility(nl: np.ndarray, nv: np.ndarray, a2) -> np.ndarray:
    """Height-correlated Smith visibility of three.js' ``V_GGX_SmithCorrelated`` at ``α² = a2``
    (Heitz 2014 Eq. 99, the 1 / (4 n·l n·v) included)."""
    gv = nl * np.sqrt(a2 + (1.0 - a2) * nv**2)
    gl = nv * np.sqrt(a2 + (1.0 - a2) * nl**2)
    return 0.5 / np.maximum(gv + gl, 1e-6)


def compensation(f0, albedo):
    """three.js' multiple-scattering compensation of direct light, ``1 + F0 (1/E − 1)`` (Turquin
    2019 Eq. 16), for the substrate's ``f0`` and the lobe's white-furnace ``albedo`` ``E``."""
    return 1.0 + f0 * (1.0 / albedo - 1.0)


@lru_cache(maxsize=64)
def _albedo_table(roughness: float) -> np.ndarray:
    """:func:`specular_albedo` at ``roughness`` on the view cosines :data:`COSINES`: importance
    sampled (h drawn from D(h) cos θ_h, a fixed stratified set of 128² directions), so the
    estimate is ``mean(4 V (n·l)(v·h) / (n·h))`` over the reflected ``l`` above the surface."""
    alpha = max(roughness, MIN_ROUGHNESS) ** 2
    count = 128
    u1, u2 = np.meshgrid((np.arange(count) + 0.5) / count, (np.arange(count) + 0.5) / count)
    cos_h = np.sqrt((1.0 - u1) / (1.0 + (alpha**2 - 1.0) * u1)).ravel()
    sin_h, phi = np.sqrt(1.0 - cos_h**2), 2.0 * math.pi * u2.ravel()
    half = np.stack([sin_h * np.cos(phi), sin_h * np.sin(phi), cos_h], axis=-1)
    out = np.empty(len(COSINES))
    for i, nv in enumerate(np.maximum(COSINES, 1e-3)):
        view = np.array([math.sqrt(1.0 - nv * nv), 0.0, nv])
        vh = half @ view
        light = 2.0 * vh[:, None] * half - view
        nl = light[:, 2]
        vis = smith_visibility(nl, nv, alpha**2)
        out[i] = np.mean(np.where(nl > 0.0, 4.0 * vis * nl * vh / cos_h, 0.0))
    return out


def specular_albedo(roughness: np.ndarray, cos_view: np.ndarray) -> np.ndarray:
    """White-furnace albedo ``E = ∫ D V (n·l) dω_l`` of three.js' GGX lobe (F = 1) at perceptual
    ``roughness`` seen at ``cos_view`` (elementwise; three.js reads it from its DFG table as
    ``dfg.x + dfg.y``; Karis 2013)."""
    roughness, cos_view = np.broadcast_arrays(np.asarray(roughness, float), cos_view)
    out = np.empty(roughness.shape)
    for r in np.unique(roughness):
        at = roughness == r
        out[at] = np.interp(cos_view[at], COSINES, _albedo_table(float(r)))
    return out


@dataclass
class FilmFit:
    """Per texel: view-independent ``base`` (linear Rec. 709, ``(n, 3)``), iridescence
    ``weight``, ``thickness_nm``, perceptual ``roughness`` and the ``substrate`` F0 ``(n, 3)``;
    and the fitted model's ``reflectance`` at the views ``(n, views, 3)``."""

    base: np.ndarray
    weight: np.ndarray
    thickness_nm: np.ndarray
    roughness: np.ndarray
    substrate: np.ndarray
    reflectance: np.ndarray


def _half_cosines(light: np.ndarray, views: np.ndarray) -> np.ndarray:
    """``v·h`` for ``light`` ``(n, 3)`` and ``views`` ``(n, k, 3)``: ``(n, k)``."""
    half = light[:, None, :] + views
    half = half / np.linalg.norm(half, axis=-1, keepdims=True)
    return np.clip(np.einsum("nkc,nkc->nk", half, views), 0.0, 1.0)


def glTF_reflectance(
    fit_base, weight, thickness_nm, light, views, roughness, film_ior, substrate=None
):
    """Eq. (1) per texel and view: ``light`` ``(n, 3)``, ``views`` ``(n, k, 3)`` in frames whose
    normal is +Z, ``substrate`` ``(n, 3)`` (default 0: a free-standing film); returns
    ``(n, k, 3)``."""
    fit_base = np.asarray(fit_base, dtype=np.float64)
    f0 = np.zeros_like(fit_base) if substrate is None else np.asarray(substrate, float)
    f0 = f0[:, None, :]
    rough = np.asarray(roughness, dtype=np.float64)[:, None]
    lobe = ggx_lobe(light[:, None, :], views, rough)[..., None]
    energy = compensation(f0, specular_albedo(rough, views[..., 2])[..., None])
    dielectric = schlick(f0, 1.0, _half_cosines(light, views)[..., None])
    film = film_fresnel(views[..., 2], film_ior, np.asarray(thickness_nm)[:, None], f0)
    w = np.asarray(weight, dtype=np.float64)[:, None, None]
    specular = (1.0 - w) * dielectric + w * film
    return fit_base[:, None, :] * (1.0 - dielectric) + lobe * energy * specular


#: View cosines of the film table :func:`fit_film` interpolates (linear in cos θ).
COSINES = np.linspace(0.0, 1.0, 65)
#: Perceptual roughness values :func:`fit_film` searches.
ROUGHNESS_GRID = np.array([0.25, 0.35, 0.5, 0.7, 1.0])


def film_table(film_ior: float, cosines: np.ndarray, thickness_nm, substrate) -> np.ndarray:
    """:func:`film_fresnel` on a grid, every channel over the same ``substrate`` F0:
    ``(len(cosines), len(thickness_nm), len(substrate), 3)``."""
    f0 = np.repeat(np.asarray(substrate, float)[:, None], 3, axis=1)
    return film_fresnel(
        cosines[:, None, None], film_ior, np.asarray(thickness_nm)[None, :, None], f0[None, None]
    )


def _at_views(table: np.ndarray, cos_theta: np.ndarray) -> np.ndarray:
    """``table`` (over :data:`COSINES`) linearly interpolated at ``cos_theta`` ``(...)``:
    ``(..., thicknesses, substrates, 3)``."""
    x = np.clip(cos_theta, 0.0, 1.0) * (len(COSINES) - 1)
    low = np.minimum(x.astype(np.int64), len(COSINES) - 2)
    frac = (x - low)[..., None, None, None]
    return table[low] * (1.0 - frac) + table[low + 1] * frac


def substrate_grid(film_ior: float) -> tuple[np.ndarray, np.ndarray]:
    """The substrates :func:`fit_film` tries over a film of ``film_ior``: 0 (free-standing) on
    every channel, or per channel one of :data:`SUBSTRATE_F0` above the film's own F0 (the
    reference's phase shift at the base is π below the film's index and 0 above, and shifts X,
    Y, Z by R, G, B: channels are chosen independently only on one side)."""
    own = ((film_ior - 1.0) / (film_ior + 1.0)) ** 2
    return np.array([0.0]), SUBSTRATE_F0[SUBSTRATE_F0 > own]


def error_weights(target: np.ndarray, view_weights=None) -> np.ndarray:
    """``(n, k, 3)``: the weight ``u = g_k / (ρ + ERROR_FLOOR)²`` of each view and channel of
    ``target`` in the fit's error ``Σ u (ρ̂ − ρ)²`` (``g`` = ``view_weights``, default
    :data:`VIEW_WEIGHTS`): the one weighting the search, :func:`fit_base` and
    :func:`fit_error` share."""
    g = VIEW_WEIGHTS if view_weights is None else np.asarray(view_weights, dtype=np.float64)
    return g[None, :, None] / (target + ERROR_FLOOR) ** 2


def _search_chunk(rho, light, views, tables, grids, far, view_weights):
    """The grid search of :func:`fit_film` for one chunk of ``m`` texels: base, weight,
    thickness index, roughness and substrate of the smallest error.

    Per channel, substrate ``f`` and thickness ``t`` Eq. (1) is ``ρ_k ≈ a_k b + p_k + w q_k``
    with ``a = 1 − S``, ``p = P S``, ``q = P (I − S)`` and ``P = π D V M``; the error
    ``Σ_k u_k (a_k b + p_k − ρ_k + w q_k)²`` (``u = view weight / (ρ + ERROR_FLOOR)²``) is
    expanded in sums over the views, so each ``w`` costs arrays of ``(m, T, F, 3)``; ``b`` is its
    least-squares value, clipped to [0, 1]. Channels pick their substrates independently within each of
    :func:`substrate_grid`'s two sides."""
    m = len(rho)
    u = error_weights(rho, view_weights)  # (m, k, 3)
    vh = _half_cosines(light, views)
    best = {
        "error": np.full(m, np.inf),
        "base": np.zeros((m, 3)),
        "weight": np.zeros(m),
        "pick": np.zeros(m, int),
        "roughness": np.zeros(m),
        "substrate": np.zeros((m, 3)),
    }
    rows = np.arange(m)
    for table, f0 in zip(tables, grids, strict=True):
        film = _at_views(table, views[..., 2])  # (m, k, T, F, 3)
        dielectric = schlick(f0[None, None, :], 1.0, vh[..., None])[..., None]  # (m, k, F, 1)
        a = 1.0 - dielectric
        uf = u[:, :, None, :]  # (m, k, 1, 3)
        ua = uf * a
        aa = (ua * a).sum(axis=1)  # (m, F, 3)
        for r in ROUGHNESS_GRID:
            lobe = ggx_lobe(light[:, None, :], views, np.full((m, 1), r))
            albedo = specular_albedo(np.full(views.shape[:2], r), views[..., 2])
            power = lobe[..., None, None] * compensation(
                f0[None, None, :, None], albedo[..., None, None]
            )
            p = power * dielectric - rho[:, :, None, :]  # p − ρ: (m, k, F, 3)
            q = power[:, :, None] * (film - dielectric[:, :, None])  # (m, k, T, F, 3)
            ap = (ua * p).sum(axis=1)
            pp = (uf * p * p).sum(axis=1)
            aq = np.einsum("mkfc,mktfc->mtfc", ua, q)
            pq = np.einsum("mkfc,mktfc->mtfc", uf * p, q)
            qq = np.einsum("mkc,mktfc->mtfc", u, q * q)
            for w in WEIGHT_GRID:
                lin = ap[:, None] + w * aq  # (m, T, F, 3)
                b = np.clip(-lin / aa[:, None], 0.0, 1.0)
                error = b * b * aa[:, None] + 2.0 * b * lin + pp[:, None] + w * (2.0 * pq + w * qq)
                choice = error.argmin(axis=2)  # (m, T, 3)
                per_t = np.take_along_axis(error, choice[:, :, None], 2)[:, :, 0].sum(axis=-1)
                if far is not None:
                    per_t = np.where(far, np.inf, per_t)
                at = per_t.argmin(axis=1)
                better = per_t[rows, at] < best["error"]
                i, t_at = rows[better], at[better]
                pick = choice[i, t_at]  # (i, 3)
                best["error"][i] = per_t[i, t_at]
                best["base"][i] = np.take_along_axis(b[i, t_at], pick[:, None], 1)[:, 0]
                best["substrate"][i] = f0[pick]
                best["weight"][i], best["pick"][i], best["roughness"][i] = w, t_at, r
    return best


def fit_error(reflectance: np.ndarray, target: np.ndarray, view_weights=None) -> np.ndarray:
    """The search's error per texel: ``Σ_k g_k ((ρ̂_k − ρ_k) / (ρ_k + ERROR_FLOOR))²`` over views
    and channels of ``(n, k, 3)`` arrays, ``g`` = ``view_weights`` (default
    :data:`VIEW_WEIGHTS`)."""
    residual = reflectance - target
    return (error_weights(target, view_weights) * residual * residual).sum(axis=(1, 2))


def fit_film(
    target: np.ndarray,
    light: np.ndarray,
    views: np.ndarray,
    film_ior: float,
    prior_nm: np.ndarray | None = None,
    window_nm: float = 30.0,
    view_weights: np.ndarray | None = None,
    chunk: int = 128,
) -> FilmFit:
    """The film, roughness, substrate and base of Eq. (1) matching ``target`` (``(n, k, 3)``
    reflectance factors at ``k`` views) per texel (module docstring). ``light`` ``(n, 3)``,
    ``views`` ``(n, k, 3)``: unit vectors in each texel's frame (normal +Z). Without ``prior_nm``
    thicknesses are searched every :data:`FREE_STEP_NM`; with it (per texel) every
    :data:`THICKNESS_STEP_NM` within ``window_nm`` of it. ``view_weights``: the error's weight
    of each view (default :data:`VIEW_WEIGHTS`, for :data:`FIT_TILTS_DEG`)."""
    step = FREE_STEP_NM if prior_nm is None else THICKNESS_STEP_NM
    grid = np.arange(0.0, THICKNESS_MAX_NM + 0.5 * step, step)
    grids = substrate_grid(film_ior)
    tables = [film_table(film_ior, COSINES, grid, f0) for f0 in grids]
    n = len(target)
    fields = {"base": (n, 3), "weight": n, "thickness": n, "roughness": n, "substrate": (n, 3)}
    out = {key: np.empty(shape) for key, shape in fields.items()}
    for start in range(0, n, chunk):
        s = slice(start, min(n, start + chunk))
        near, far, chunk_tables = slice(None), None, tables
        if prior_nm is not None:  # only the thicknesses within some texel's window
            far = np.abs(grid[None, :] - prior_nm[s, None]) > window_nm
            near = np.flatnonzero(~far.all(axis=0))
            far, chunk_tables = far[:, near], [table[:, near] for table in tables]
        best = _search_chunk(target[s], light[s], views[s], chunk_tables, grids, far, view_weights)
        for key in ("base", "weight", "roughness", "substrate"):
            out[key][s] = best[key]
        out["thickness"][s] = grid[near][best["pick"]]
    fitted = glTF_reflectance(
        out["base"],
        out["weight"],
        out["thickness"],
        light,
        views,
        out["roughness"],
        film_ior,
        out["substrate"],
    )
    return FilmFit(
        out["base"], out["weight"], out["thickness"], out["roughness"], out["substrate"], fitted
    )


def fit_base(
    target,
    light,
    views,
    weight,
    thickness_nm,
    roughness,
    film_ior,
    substrate,
    view_weights=None,
    chunk: int = 1 << 16,
) -> FilmFit:
    """The view-independent base that best completes a given film (``weight``,
    ``thickness_nm``, ``roughness``, ``substrate`` per texel) to ``target`` ``(n, k, 3)``: the
    base of Eq. (1) of least :func:`fit_error` (the search's weights, ``view_weights`` default
    :data:`VIEW_WEIGHTS`, and its relative error), clipped to [0, 1] (in linear RGB), as
    :func:`fit_film` completes each film it tries; ``chunk`` texels at a time (the film's
    temporaries are ``(chunk, k, 3)``)."""
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
            substrate[s],
        )
    dim = 1.0 - schlick(substrate[:, None, :], 1.0, _half_cosines(light, views)[..., None])
    u = error_weights(target, view_weights)
    base = np.clip((u * (target - film) * dim).sum(axis=1) / (u * dim * dim).sum(axis=1), 0.0, 1.0)
    return FilmFit(base, weight, thickness_nm, roughness, substrate, film + base[:, None, :] * dim)
