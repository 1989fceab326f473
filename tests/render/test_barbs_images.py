"""Acceptance (issue 23): the shipped eye feather's barbs, rendered.

* A close-up 4 cm across of the loose lower vane (the feather's own barbs, straight there): the
  image's power spectrum along the rachis peaks at the recipe's barb spacing (within 15 %), and
  on at least a quarter of the area inside the feather's outline the background shows between
  barbs (the film alpha's share of samples that hit nothing: no brightness threshold); the loose
  barbs, free filaments, cover ``FILAMENT_SHARE`` of what the sheet's alpha covers (within 5
  points).
* A close-up 4 cm across of the eye: the boundary of its heart and first ring, on the barbs, is
  a smooth curve, not a staircase of the ocellar map's texels (tests/render/test_ocellus_crisp_zones.py's
  measure).
* At the README's hero view (``assets/scenes/eye_feather_sun.usda``) barbs and sheet agree: the
  mean colour of each ocellus zone within CIE ΔE2000 3 (zones from the ocellar map at the
  feather coordinate the sheet shows each pixel, alpha above 0.9, one pixel in from every zone
  boundary).

    pytest tests/render/test_barbs_images.py -s   # prints the figures
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest
from barb_measures import with_alpha
from barbule_views import close_up

REPO = Path(__file__).resolve().parents[2]
ASSET = REPO / "assets" / "feathers" / "eye_feather" / "eye_feather.usd"
HERO = REPO / "assets" / "scenes" / "eye_feather_sun.usda"
RECIPE = REPO / "assets" / "recipes" / "eye_feather.toml"
#: The close-up: 4 cm across, centred 1 cm right of the rachis, 4.5 cm up the vane (v = 0.15).
VIEW_CM, CENTRE = 4.0, (1.0, 4.5)
CLOSE_RES, CLOSE_SPP = 256, 16
HERO_RES, HERO_SPP = (128, 192), 32


def _close_up(folder: Path, geometry: str) -> Path:
    """A camera 8.3 cm in front of the vane (50 mm lens, 24 mm aperture: 4 cm across), the
    hero scene's sun, no sky: the background is black; the product gives colour and alpha."""
    target = np.array([CENTRE[0], CENTRE[1], 0.0])
    return with_alpha(close_up(folder, "close", target, VIEW_CM, CLOSE_RES, geometry, ASSET))


def _hero(folder: Path, geometry: str) -> Path:
    text = HERO.read_text().replace("@../feathers/eye_feather/eye_feather.usd@", f"@{ASSET}@")
    selection = f'@{ASSET}@\n        variants = {{ string geometry = "{geometry}" }}'
    path = folder / f"hero_{geometry}.usda"
    path.write_text(text.replace(f"@{ASSET}@", selection, 1))
    return path


def _luma(rgb: np.ndarray) -> np.ndarray:
    return rgb @ np.array([0.2126, 0.7152, 0.0722])


@pytest.mark.render
def test_a_close_up_shows_the_barbs_spacing_and_the_background_between_them(tmp_path):
    from pavonine.pipeline.convert.barb_curves import FILAMENT_SHARE
    from pavonine.render.api import render_stage
    from pavonine.render.imageio import write_png

    spacing_cm = tomllib.loads(RECIPE.read_text())["geometry"].get("barbs", {})
    spacing_cm = spacing_cm.get("spacing_cm", 0.225)
    images = {
        g: render_stage(_close_up(tmp_path, g), spp=CLOSE_SPP, seed=0, progress=False).images
        for g in ("sheet", "barbs")
    }
    rgb = {g: images[g]["color"] for g in images}
    alpha = {g: images[g]["alpha"][..., 0] for g in images}
    write_png(tmp_path / "close_up.png", np.concatenate([rgb["sheet"], rgb["barbs"]], 1))
    np.save(tmp_path / "close_up.npy", np.stack([rgb["sheet"], rgb["barbs"]]))
    barbs = _luma(rgb["barbs"])
    pixels_per_cm = CLOSE_RES / VIEW_CM
    # Inside the outline: where the sheet shows (its alpha map's silhouette), its own holes
    # closed, two pixels in from the edge.
    from scipy import ndimage

    inside = ndimage.binary_closing(alpha["sheet"] > 0.0, iterations=3)
    inside = ndimage.binary_erosion(inside, iterations=2)
    # The background's share of that area: the film alpha is each pixel's share of samples
    # that hit the feather, so 1 - alpha is the share of its area where the (black) background
    # shows: no brightness threshold. Beside it, the share of pixels (nearly) no barb touches.
    background = 1.0 - float(np.mean(alpha["barbs"][inside]))
    sheet_background = 1.0 - float(np.mean(alpha["sheet"][inside]))
    empty = float(np.mean(alpha["barbs"][inside] < 0.05))
    # Along the rachis (image columns) the barbs repeat every spacing_cm, whatever their angle.
    columns = barbs[:, inside.mean(axis=0) > 0.9]
    power = np.abs(np.fft.rfft(columns - columns.mean(axis=0), axis=0)) ** 2
    spectrum = power.mean(axis=1)
    spectrum[:3] = 0.0  # the outline's own scale
    period = CLOSE_RES / int(np.argmax(spectrum))
    expected = spacing_cm * pixels_per_cm
    print(
        f"\nclose-up: barb period {period:.2f} px (recipe spacing {expected:.2f} px); inside "
        f"the outline ({int(inside.sum())} px) the background shows on {background:.1%} of the "
        f"area between the barbs ({sheet_background:.1%} through the sheet's alpha), "
        f"{empty:.1%} of the pixels have under 5 % barb in them"
    )
    assert columns.shape[1] >= 20
    assert abs(period - expected) <= 0.15 * expected
    assert background >= 0.25
    # The loose barbs are filaments (pipeline/convert/barb_curves.py): their ribbons cover
    # FILAMENT_SHARE of the alpha map's share, the sheet's opacity (issue 33).
    cover, sheet_cover = 1.0 - background, 1.0 - sheet_background
    assert abs(cover - FILAMENT_SHARE * sheet_cover) <= 0.05, (cover, sheet_cover)


@pytest.mark.render
def test_barbs_and_sheet_agree_per_ocellus_zone_at_the_hero_view(tmp_path):
    from ocellus_zones import zone_delta_e, zone_masks

    from pavonine.render.api import render_stage
    from pavonine.render.imageio import write_png

    width, height = HERO_RES
    sheet_scene = _hero(tmp_path, "sheet")
    masks = zone_masks(sheet_scene, ASSET.parent / "maps", width, height)
    rgb = {
        g: render_stage(
            _hero(tmp_path, g), spp=HERO_SPP, resolution=HERO_RES, seed=0, progress=False
        ).rgb
        for g in ("sheet", "barbs")
    }
    write_png(tmp_path / "hero_sheet_vs_barbs.png", np.concatenate([rgb["sheet"], rgb["barbs"]], 1))
    delta_e = zone_delta_e(rgb["sheet"], rgb["barbs"], masks)
    results = {k: (int(masks[k].sum()), delta_e[k]) for k in masks}
    print("\nzone  pixels  ΔE2000 (sheet vs barbs, hero view)")
    for k, (n, de) in results.items():
        print(f"{k:>4}  {n:>6}  {de:6.2f}")
    assert set(results) >= {1, 2, 3, 4, 5}  # the vane, every ring and the heart
    assert all(de <= 3.0 for _, de in results.values()), results


#: The eye close-up 4 cm across (tests/glint_scene.py's camera 3 cm from the boundary of the
#: heart and its first ring), at 3.75 pixels per ocellar-map texel; the boundary is measured in
#: the CROP pixels around it (1 cm square), as tests/render/test_ocellus_crisp_zones.py measures it.
STAIR_FIELD_MM, STAIR_RES, STAIR_SPP, CROP = 40.0, 512, 32, 128


@pytest.mark.render
def test_ring_boundaries_on_the_barbs_show_no_texel_staircase(tmp_path):
    from glint_scene import EYE, closeup_stage
    from ocellus_zones import feather_hits
    from scipy import ndimage
    from test_ocellus_crisp_zones import _boundary_columns, _deviation

    from pavonine.base.map_files import read_map, sample_nearest
    from pavonine.render.api import render_stage
    from pavonine.render.imageio import write_png

    def stage(geometry: str) -> Path:
        path = closeup_stage(
            tmp_path / f"stair_{geometry}.usda",
            0.0,
            field_mm=STAIR_FIELD_MM,
            resolution=STAIR_RES,
            geometry=geometry,
        )
        # The class field at the barbs' scale, without the barbules (issue 33), which break a
        # ring's edge at their own 20 µm scale as on a real feather (tests/render/test_barbules.py).
        return _without_barbules(path)

    rgb = render_stage(stage("barbs"), spp=STAIR_SPP, seed=0, progress=False).rgb
    lo = (STAIR_RES - CROP) // 2
    crop = rgb[lo : lo + CROP, lo : lo + CROP]
    write_png(tmp_path / "stair_barbs.png", rgb)
    # Violet heart (class 5) left, cyan ring (class 4) right, split by red minus green midway;
    # the dark seams between barbs take the zone of the nearest lit pixel.
    key = crop[..., 0] - crop[..., 1]
    luma = _luma(crop)
    lit = luma > 0.25 * np.median(luma)
    nearest = ndimage.distance_transform_edt(~lit, return_distances=False, return_indices=True)
    key = key[nearest[0], nearest[1]]
    left_value, right_value = np.median(key[:, :8]), np.median(key[:, -8:])
    assert left_value > right_value + 0.05  # two zones, violet on the left
    rendered = _deviation(_boundary_columns(key > 0.5 * (left_value + right_value)))
    # The same pixels' classes per texel (the map's staircase), through the sheet's coordinates.
    uv, on_vane = feather_hits(stage("sheet"), STAIR_RES, STAIR_RES)
    grey = read_map(EYE.parent / "maps" / "ocellar.png", "ocellar")
    uv = uv[lo : lo + CROP, lo : lo + CROP].reshape(-1, 2)
    per_texel = sample_nearest(grey, uv).reshape(CROP, CROP) < 0.1
    staircase = _deviation(_boundary_columns(per_texel))
    print(
        f"\nclose-up 4 cm, heart/ring boundary: {rendered:.2f} px from a smooth curve on the "
        f"barbs; the map's texels {staircase:.2f} px; lit {lit.mean():.1%} of the crop"
    )
    assert on_vane[lo : lo + CROP, lo : lo + CROP].all()
    assert staircase > 1.5, staircase  # the metric sees the texels
    # The largest deviation of one noisy boundary: at 32 spp it scatters by 0.11-0.14 px (sd of
    # seeds 0-5: 0.85-1.17 px with the eye maps that lowered the heart's share, 0.79-1.19 px
    # with today's); at 128 spp it is 1.07-1.15 px and 1.00-1.04 px (seeds 0-2). So 1.0 px sat at
    # the metric's mean; 1.2 px passes every seed measured and stays 0.87 px below the texels.
    assert rendered <= 1.2, (rendered, staircase)


def _without_barbules(path: Path) -> Path:
    """``path`` with every barb's ``primvars:pavonine_barbules`` blocked (plain ribbons)."""
    from pxr import Usd, UsdGeom

    from pavonine.schemas.primvars import BARBULES_PRIMVAR

    stage = Usd.Stage.Open(str(path))
    for prim in stage.Traverse():
        primvar = UsdGeom.PrimvarsAPI(prim).GetPrimvar(BARBULES_PRIMVAR)
        if prim.IsA(UsdGeom.BasisCurves) and primvar.HasAuthoredValue():
            stage.OverridePrim(prim.GetPath()).GetAttribute(primvar.GetName()).Block()
    stage.Save()
    return path
