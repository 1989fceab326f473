"""Spectrum → colour, with the renderer's own observer, illuminant and display transform.

One colour pipeline for analysis and rendering:

* CIE 1931 2° colour-matching functions and the CIE D65 illuminant are Mitsuba's own
  (``mi.cie1931_xyz``, ``mi.cie_d65``: the CIE tables, linearly interpolated), tabulated at 1 nm in
  ``data/cie1931_d65_1nm.csv`` so that analysis needs no Mitsuba; ``tests/materials/test_colour_tables.py``
  checks the table against Mitsuba.
* XYZ → linear Rec.709/sRGB uses Mitsuba's ``mi.xyz_to_srgb`` matrix (:data:`XYZ_TO_SRGB`).
* Display encoding goes through the current OpenColorIO display transform
  (:mod:`pavonine.materials.display`): by default the pinned built-in CG config, display
  ``sRGB - Display``, view ``Un-tone-mapped`` — the same transform ``pavonine render --png`` applies.

A reflectance spectrum R(λ) lit by D65 gives tristimulus values
``X = ∫ R S x̄ dλ / ∫ S ȳ dλ`` (CIE 15:2004 §7.1), so a perfect white reflector has Y = 1 and
linear sRGB (1, 1, 1).
"""

from __future__ import annotations

import functools
import math
from pathlib import Path

import numpy as np

from pavonine.materials.display import DEFAULT_VIEW as DEFAULT_VIEW  # re-exported
from pavonine.materials.display import DISPLAY as DISPLAY
from pavonine.materials.display import SCENE_LINEAR as SCENE_LINEAR
from pavonine.materials.display import current_display, with_overrides

CIE_RANGE_NM = (360.0, 830.0)  # Mitsuba's MI_CIE_MIN, MI_CIE_MAX
CIE_TABLE = Path(__file__).with_name("data") / "cie1931_d65_1nm.csv"
#: XYZ → linear sRGB (Rec.709 primaries, D65), Mitsuba's ``xyz_to_srgb`` (float32 constants).
XYZ_TO_SRGB = np.array(
    [
        [3.240479, -1.537150, -0.498535],
        [-0.969256, 1.875991, 0.041556],
        [0.055648, -0.204043, 1.057311],
    ],
    dtype=np.float32,
).astype(np.float64)


@functools.cache
def _tables() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(λ grid, CMFs (n, 3), D65 (n,)) read once from :data:`CIE_TABLE`."""
    table = np.loadtxt(CIE_TABLE, delimiter=",", comments="#", skiprows=5, dtype=np.float64)
    return table[:, 0], table[:, 1:4], table[:, 4]


def cmfs(wavelengths_nm: np.ndarray) -> np.ndarray:
    """CIE 1931 2° x̄, ȳ, z̄ at ``wavelengths_nm`` (shape (..., 3)); zero outside 360–830 nm."""
    grid, cmf, _ = _tables()
    w = np.asarray(wavelengths_nm, dtype=np.float64)
    return np.stack([np.interp(w, grid, cmf[:, i], left=0.0, right=0.0) for i in range(3)], -1)


def d65(wavelengths_nm: np.ndarray) -> np.ndarray:
    """Relative spectral power of CIE D65 at ``wavelengths_nm`` (Mitsuba's normalisation)."""
    grid, _, spd = _tables()
    return np.interp(np.asarray(wavelengths_nm, dtype=np.float64), grid, spd, left=0.0, right=0.0)


def reflectance_to_xyz(wavelengths_nm: np.ndarray, reflectance: np.ndarray) -> np.ndarray:
    """XYZ of a reflectance spectrum under D65 (CIE 15:2004 §7.1); last axis of ``reflectance`` is λ.

    Normalised over the same wavelength samples, so R ≡ 1 gives Y = 1 exactly.
    """
    w = np.asarray(wavelengths_nm, dtype=np.float64)
    weights = cmfs(w) * d65(w)[:, None]  # (n, 3)
    dw = np.gradient(w) if w.size > 1 else np.ones(1)
    weights = weights * dw[:, None]
    return np.asarray(reflectance, dtype=np.float64) @ weights / weights[:, 1].sum()


def xyz_to_linear_srgb(xyz: np.ndarray) -> np.ndarray:
    """XYZ → scene-linear Rec.709 (sRGB primaries, D65 white), Mitsuba's matrix."""
    return np.asarray(xyz, dtype=np.float64) @ XYZ_TO_SRGB.T


def reflectance_to_linear_srgb(wavelengths_nm: np.ndarray, reflectance: np.ndarray) -> np.ndarray:
    """Scene-linear Rec.709 colour of a reflectance spectrum lit by D65."""
    return xyz_to_linear_srgb(reflectance_to_xyz(wavelengths_nm, reflectance))


def display_encode(linear_rgb: np.ndarray, view: str | None = None) -> np.ndarray:
    """Scene-linear Rec.709 → display-referred values in [0, 1] through the current display
    transform (:func:`pavonine.materials.display.current_display`), with ``view`` if given."""
    return with_overrides(current_display(), view=view).encode(linear_rgb)


def swatch(linear_rgb: np.ndarray) -> np.ndarray:
    """Display sRGB swatch of a colour, scaled down (hue kept) so no channel exceeds 1, negatives clipped."""
    rgb = np.clip(np.asarray(linear_rgb, dtype=np.float64), 0.0, None)
    peak = np.max(rgb, axis=-1, keepdims=True)
    rgb = np.where(peak > 1.0, rgb / np.where(peak > 0, peak, 1.0), rgb)
    return display_encode(rgb)


def xyz_to_lab(xyz: np.ndarray, white: np.ndarray | None = None) -> np.ndarray:
    """CIE 1976 L*a*b* (CIE 15:2004 §8.2.1) relative to ``white`` (default: D65 with Y = 1)."""
    if white is None:
        white = linear_srgb_to_xyz(np.ones(3))
    t = np.asarray(xyz, dtype=np.float64) / np.asarray(white, dtype=np.float64)
    delta = 6.0 / 29.0
    f = np.where(t > delta**3, np.cbrt(t), t / (3 * delta**2) + 4.0 / 29.0)
    return np.stack(
        [
            116.0 * f[..., 1] - 16.0,
            500.0 * (f[..., 0] - f[..., 1]),
            200.0 * (f[..., 1] - f[..., 2]),
        ],
        -1,
    )


def linear_srgb_to_xyz(linear_rgb: np.ndarray) -> np.ndarray:
    """Linear Rec.709 → XYZ (inverse of :func:`xyz_to_linear_srgb`)."""
    return np.asarray(linear_rgb, dtype=np.float64) @ np.linalg.inv(XYZ_TO_SRGB).T


def delta_e76(rgb_a: np.ndarray, rgb_b: np.ndarray) -> np.ndarray:
    """CIE 1976 colour difference ΔE*ab between two scene-linear Rec.709 colours."""
    return np.linalg.norm(linear_srgb_to_lab(rgb_a) - linear_srgb_to_lab(rgb_b), axis=-1)


def delta_e2000(lab_a: np.ndarray, lab_b: np.ndarray) -> np.ndarray:
    """CIEDE2000 colour difference of two CIE L*a*b* colours (CIE 142-2001; the formulas and
    test data of Sharma, Wu & Dalal 2005, "The CIEDE2000 color-difference formula",
    Color Res. Appl. 30(1)), with k_L = k_C = k_H = 1."""
    lab_a, lab_b = np.asarray(lab_a, dtype=np.float64), np.asarray(lab_b, dtype=np.float64)
    l1, a1, b1 = lab_a[..., 0], lab_a[..., 1], lab_a[..., 2]
    l2, a2, b2 = lab_b[..., 0], lab_b[..., 1], lab_b[..., 2]
    c_mean = 0.5 * (np.hypot(a1, b1) + np.hypot(a2, b2))
    g = 0.5 * (1.0 - np.sqrt(c_mean**7 / (c_mean**7 + 25.0**7)))  # Eq. 3
    a1p, a2p = (1.0 + g) * a1, (1.0 + g) * a2
    c1p, c2p = np.hypot(a1p, b1), np.hypot(a2p, b2)
    h1p = np.degrees(np.arctan2(b1, a1p)) % 360.0
    h2p = np.degrees(np.arctan2(b2, a2p)) % 360.0
    dlp, dcp = l2 - l1, c2p - c1p
    dh = h2p - h1p
    dh = np.where(dh > 180.0, dh - 360.0, np.where(dh < -180.0, dh + 360.0, dh))
    dh = np.where(c1p * c2p == 0.0, 0.0, dh)  # Eq. 10
    dhp = 2.0 * np.sqrt(c1p * c2p) * np.sin(np.radians(dh) / 2.0)  # Eq. 11
    lp, cp = 0.5 * (l1 + l2), 0.5 * (c1p + c2p)
    hsum = h1p + h2p
    hp = np.where(
        np.abs(h1p - h2p) <= 180.0,
        hsum / 2.0,
        np.where(hsum < 360.0, (hsum + 360.0) / 2.0, (hsum - 360.0) / 2.0),
    )
    hp = np.where(c1p * c2p == 0.0, hsum, hp)  # Eq. 14
    t = (
        1.0
        - 0.17 * np.cos(np.radians(hp - 30.0))
        + 0.24 * np.cos(np.radians(2.0 * hp))
        + 0.32 * np.cos(np.radians(3.0 * hp + 6.0))
        - 0.20 * np.cos(np.radians(4.0 * hp - 63.0))
    )  # Eq. 15
    d_theta = 30.0 * np.exp(-(((hp - 275.0) / 25.0) ** 2))  # Eq. 16
    rc = 2.0 * np.sqrt(cp**7 / (cp**7 + 25.0**7))  # Eq. 17
    sl = 1.0 + 0.015 * (lp - 50.0) ** 2 / np.sqrt(20.0 + (lp - 50.0) ** 2)  # Eq. 18
    sc = 1.0 + 0.045 * cp  # Eq. 19
    sh = 1.0 + 0.015 * cp * t  # Eq. 20
    rt = -np.sin(np.radians(2.0 * d_theta)) * rc  # Eq. 21
    return np.sqrt(
        (dlp / sl) ** 2 + (dcp / sc) ** 2 + (dhp / sh) ** 2 + rt * (dcp / sc) * (dhp / sh)
    )  # Eq. 22


def linear_srgb_to_lab(linear_rgb: np.ndarray) -> np.ndarray:
    """CIE L*a*b* (D65 white with Y = 1) of scene-linear Rec. 709 colours."""
    return xyz_to_lab(linear_srgb_to_xyz(linear_rgb))


#: CIE D65 white point, CIE 1931 2° chromaticity (CIE 15:2004 Table T.3).
D65_WHITE_XY = (0.31271, 0.32902)


def dominant_wavelength(xyz: np.ndarray, white_xy: tuple[float, float] = D65_WHITE_XY) -> float:
    """Dominant wavelength (nm) of a colour: where the line from the white point through its
    chromaticity meets the spectral locus (CIE 15:2004 §9.1). For purples, which have none, the
    complementary wavelength is returned negated. NaN for the white point itself."""
    xyz = np.asarray(xyz, dtype=np.float64)
    total = xyz.sum()
    if total <= 0:
        return math.nan
    point = xyz[:2] / total - np.asarray(white_xy)
    if np.hypot(*point) < 1e-9:
        return math.nan
    lam = np.arange(CIE_RANGE_NM[0], CIE_RANGE_NM[1] - 99.5, 0.5)  # 360–730 nm: monotone locus
    bar = cmfs(lam)
    locus = bar[:, :2] / bar.sum(axis=1, keepdims=True) - np.asarray(white_xy)
    cross = locus[:, 0] * point[1] - locus[:, 1] * point[0]
    dot = locus @ point
    for sign in (1.0, -1.0):
        change = np.nonzero((np.sign(cross[:-1]) != np.sign(cross[1:])) & (sign * dot[:-1] > 0))[0]
        if change.size:
            i = int(change[0])
            t = cross[i] / (cross[i] - cross[i + 1])
            return sign * float(lam[i] + t * (lam[i + 1] - lam[i]))
    return math.nan
