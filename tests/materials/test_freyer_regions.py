"""The literature preset against Freyer & Stavenga 2020, one eye-feather region at a time.

Freyer & Stavenga 2020, "Biophotonics of diversely coloured peacock tail feathers", Faraday
Discuss. 223:49-62, doi:10.1039/d0fd00033g (docs/model.md, "Measured reflectance per eye region").
What is checked, and where it comes from:

* the structure of each region (lattice a, b, cortex c, melanosome D_m, air channel D_a in nm;
  layers N_m), the article's Table 1 as quoted in MODEL-NOTES (an independent transcription,
  github.com/kdkishore77-alt/Peacock-without-iridescence, gives the same 36 numbers);
* the colour each region is named for: the model's band at normal incidence must lie in that
  colour. The article's measured spectra (its figures) could not be read from here, so no
  measured peak wavelength or reflectance is asserted;
* the heart, which the article calls black-violet: darker than the blue-green ring, both as a
  structure and as the shipped eye feather mixes it with melanin brown (paper §3.3.6);
* the eye's fringe (its loose barb tips beyond the outer ring): bronze-green as the painted maps
  mix it with melanin brown, not tan (issue 33).

Spectra: ``stack.structure_reflectance`` (effective-medium transfer matrix, literature melanin
and keratin, air-keratin surface included) at normal incidence, 360-830 nm every 2 nm; colour
under D65 with the project's CIE tables (``materials/colour.py``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pavonine.base.map_files import read_map
from pavonine.materials import colour
from pavonine.materials.brdf import melanin_albedo
from pavonine.materials.optics import peak_and_width
from pavonine.materials.parameters import FREYER_2020_CLASSES, preset, preset_gradation
from pavonine.materials.stack import structure_reflectance
from pavonine.pipeline.maps.paint import generate_maps, ocellar_class

PRESET = "freyer2020"
WAVELENGTHS_NM = np.arange(360.0, 831.0, 2.0)
VISIBLE = (WAVELENGTHS_NM >= 380.0) & (WAVELENGTHS_NM <= 780.0)
SHIPPED_MAPS = Path(__file__).parents[2] / "assets" / "feathers" / "eye_feather" / "maps"

#: Table 1 of the article: a, b, c, D_m, D_a (nm), N_m per region.
ARTICLE_TABLE1 = {
    "black-violet": (140, 150, 100, 100, 33, 10),
    "blue-green": (160, 170, 100, 110, 33, 9),
    "brown": (190, 150, 70, 110, 50, 5),
    "green-yellow": (195, 150, 130, 120, 55, 5),
    "purple": (185, 190, 140, 100, 70, 3),
    "brass-green": (185, 160, 130, 120, 70, 4),
}

#: The spectral band each single-coloured region's name stands for (nm): violet below 450 nm,
#: blue-green 480-510 nm, yellow-green to yellow 530-590 nm. The model's peaks sit 7-15 nm inside
#: (443, 497, 545, 581 nm); a 3 % change of the lattice moves them 12-17 nm.
NAMED_BANDS_NM = {
    "black-violet": (400.0, 450.0),
    "blue-green": (480.0, 510.0),
    "brass-green": (530.0, 560.0),
    "green-yellow": (560.0, 590.0),
}

#: The heart (black-violet) must be at least this much darker (CIELAB L*) than the blue-green
#: ring around it. Structure alone: 19.0 against 33.2 (ΔL* 14.2). The shipped scene's render
#: (128x192, 16 spp) measured the heart at L* 31.8 and the ring at 34.4 (ΔL* 2.6) with the
#: shipped maps, L* 23.1 and 34.4 (ΔL* 11.3) with the heart's structural share left at 1.
HEART_DARKER_BY = 10.0
SHIPPED_HEART_DARKER_BY = 8.0
#: Mixing in melanin brown (paper §3.3.6) may not make the heart lighter than its structure by
#: more than this (L*): the brown, linear sRGB (0.22, 0.12, 0.06), is L* 43.8, far lighter than
#: the heart's structural colour (L* 19.0), so every 10 % of brown lifts the heart by about 3.5.
MIXING_MAY_LIGHTEN_BY = 3.0


def _reflectance(region: str) -> np.ndarray:
    params = preset(PRESET)
    k = FREYER_2020_CLASSES.index(region)
    t = preset_gradation(PRESET)
    stack, cortex = params.classes[k].at(t)[0], params.classes[k].cortex_at(t)
    r = structure_reflectance(
        stack, params.lattice, cortex, WAVELENGTHS_NM, np.ones(1), params.melanin, params.keratin
    )
    return np.asarray(r, dtype=np.float64).ravel()


def _lab(reflectance: np.ndarray) -> np.ndarray:
    return colour.xyz_to_lab(colour.reflectance_to_xyz(WAVELENGTHS_NM, reflectance))


def _chroma(lab: np.ndarray) -> float:
    return float(np.hypot(lab[1], lab[2]))


def test_preset_holds_the_article_table1():
    params = preset(PRESET)
    t = preset_gradation(PRESET)
    assert set(FREYER_2020_CLASSES) == set(ARTICLE_TABLE1)
    for k, region in enumerate(FREYER_2020_CLASSES):
        cls = params.classes[k]
        assert cls.long == cls.short, region  # one structure along both barbule axes
        s = cls.at(t)[0]
        got = (s.interval, s.spacing, cls.cortex_at(t), 2 * s.radius, s.channel, s.count)
        *lengths_nm, layers = ARTICLE_TABLE1[region]
        want = (*(v / 1000.0 for v in lengths_nm), layers)
        assert got == pytest.approx(want, abs=1e-6), region


@pytest.mark.parametrize("region", sorted(NAMED_BANDS_NM))
def test_band_lies_in_the_colour_the_region_is_named_for(region):
    r = _reflectance(region)
    peak, width = peak_and_width(WAVELENGTHS_NM[VISIBLE], r[VISIBLE])
    lo, hi = NAMED_BANDS_NM[region]
    assert lo <= peak <= hi, (region, peak)
    assert width is not None and width < 130.0, (region, width)  # a band, not a slope
    assert 0.2 < r[VISIBLE].max() < 0.6, region  # the model's band: 0.34-0.40


def test_brown_is_a_broad_low_chroma_spectrum():
    r = _reflectance("brown")
    lab = _lab(r)
    hue = float(np.degrees(np.arctan2(lab[2], lab[1])) % 360.0)
    assert _chroma(lab) < 20.0 and 40.0 <= hue <= 100.0 and lab[0] < 45.0, (lab, hue)


@pytest.mark.xfail(
    strict=True,
    reason="the article's 'purple' region gives a green band (528 nm) with Table 1 as quoted; "
    "docs/model.md, 'Literature preset'",
)
def test_purple_region_is_purple():
    xyz = colour.reflectance_to_xyz(WAVELENGTHS_NM, _reflectance("purple"))
    assert colour.dominant_wavelength(xyz) < 0.0  # purples have only a complementary wavelength


def test_black_violet_structure_is_darker_than_the_blue_green_ring():
    heart, ring = _lab(_reflectance("black-violet")), _lab(_reflectance("blue-green"))
    assert heart[0] <= ring[0] - HEART_DARKER_BY, (heart, ring)
    hue = float(np.degrees(np.arctan2(heart[2], heart[1])) % 360.0)
    assert 280.0 <= hue <= 330.0 and _chroma(heart) > 50.0, heart  # a saturated violet


def _painted_melanin():
    maps = generate_maps("eye", 256, 1)  # the shipped recipe's painter (seed 1), smaller
    return maps["ocellar"], maps["melanin"]


def _shipped_melanin():
    if not (SHIPPED_MAPS / "melanin.png").exists():
        pytest.skip(f"no shipped eye feather maps at {SHIPPED_MAPS}")
    return (
        read_map(SHIPPED_MAPS / "ocellar.png", "ocellar"),
        read_map(SHIPPED_MAPS / "melanin.png", "melanin"),
    )


@pytest.mark.parametrize("source", ["painted", "shipped"])
def test_eye_feather_keeps_the_heart_black_violet(source):
    """Each zone's colour as the BSDF mixes it, ``w R + (1 - w) ρ_melanin`` with ``w`` the zone's
    mean melanin-map value (structural share), lobe gain 1. The maps keep the heart's share at 1:
    this gives the heart 19.0 and the ring 33.2, and the shipped scene's baseline (128x192, 512 spp)
    reads 23.3 and 34.7. Maps that lowered the heart's share to 0.65-0.66 failed it (30.6-30.8 here,
    32.0 in the baseline): the brown that replaces the structure is lighter than the violet."""
    ocellar, melanin = _painted_melanin() if source == "painted" else _shipped_melanin()
    klass = ocellar_class(ocellar)
    brown = melanin_albedo(preset(PRESET).melanin_color, WAVELENGTHS_NM)
    seen = {}
    for k, region in ((5, "black-violet"), (4, "blue-green")):
        share = float(melanin[klass == k].mean())
        structure = _reflectance(region)
        seen[region] = (share, _lab(structure)[0], _lab(share * structure + (1 - share) * brown)[0])
    (_, heart_structure, heart), (_, _, ring) = seen["black-violet"], seen["blue-green"]
    assert heart <= ring - SHIPPED_HEART_DARKER_BY, seen
    assert heart <= heart_structure + MIXING_MAY_LIGHTEN_BY, seen


#: The eye's fringe (issue 33): the loose barb tips beyond the outer ring, class 1 (brass-green)
#: where the alpha map is partial, must be bronze-green to golden-green as the maps mix it with
#: melanin brown: hue between bronze-yellow and the brass-green structure's own 127° (the brown
#: alone is 66°), and about as saturated as the vane inside it (C* 52 there). The maps that faded
#: the fringe's share to 0.2 mixed it to h 97°, C* 29 (tan).
FRINGE_HUE_DEG = (105.0, 135.0)
FRINGE_MIN_CHROMA = 40.0
#: The fringe may differ from the vane just inside it by at most this (CIE ΔE2000).
FRINGE_FROM_VANE_DE = 5.0


def _mixed_lab(share: float, structure: np.ndarray, brown: np.ndarray) -> np.ndarray:
    return _lab(share * structure + (1.0 - share) * brown)


def _eye_maps(source: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(alpha, ocellar, melanin) of the painted eye maps (seed 1, 256 px) or the shipped ones."""
    if source == "painted":
        maps = generate_maps("eye", 256, 1)  # the shipped recipe's painter (seed 1), smaller
        return maps["alpha"], maps["ocellar"], maps["melanin"]
    if not (SHIPPED_MAPS / "melanin.png").exists():
        pytest.skip(f"no shipped eye feather maps at {SHIPPED_MAPS}")
    return tuple(read_map(SHIPPED_MAPS / f"{n}.png", n) for n in ("alpha", "ocellar", "melanin"))


@pytest.mark.parametrize("source", ["painted", "shipped"])
def test_eye_feather_fringe_is_bronze_green(source):
    """The BSDF mixes ``w R + (1 - w) ρ_melanin`` (lobe gain 1), ``w`` the melanin map's structural
    share averaged over the fringe weighted by the alpha map (the barbs' coverage there): the
    fringe is class 1 above the lower vane (v > 0.45) with alpha in (0.05, 0.95), the vane class 1
    there with alpha 1."""
    alpha, ocellar, melanin = _eye_maps(source)
    klass = ocellar_class(ocellar)
    rows = alpha.shape[0]
    v = 1.0 - (np.arange(rows)[:, None] + 0.5) / rows + np.zeros_like(alpha)
    disc = (klass == 1) & (v > 0.45)
    structure = _reflectance("brass-green")
    brown = melanin_albedo(preset(PRESET).melanin_color, WAVELENGTHS_NM)
    seen = {}
    for zone, mask in (
        ("fringe", disc & (alpha > 0.05) & (alpha < 0.95)),
        ("vane", disc & (alpha >= 0.999)),
    ):
        assert mask.sum() > 500, zone
        share = float((melanin[mask] * alpha[mask]).sum() / alpha[mask].sum())
        seen[zone] = (share, _mixed_lab(share, structure, brown))
    fringe, vane = seen["fringe"][1], seen["vane"][1]
    hue = float(np.degrees(np.arctan2(fringe[2], fringe[1])) % 360.0)
    assert FRINGE_HUE_DEG[0] <= hue <= FRINGE_HUE_DEG[1], (hue, seen)
    assert _chroma(fringe) >= FRINGE_MIN_CHROMA, seen
    assert colour.delta_e2000(fringe, vane) <= FRINGE_FROM_VANE_DE, seen
