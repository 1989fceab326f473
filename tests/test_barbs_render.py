"""Acceptance (issue 23): the shipped eye feather's barbs, rendered.

* A close-up 4 cm across of the loose lower vane (the feather's own barbs, straight there): the
  image's power spectrum along the rachis peaks at the recipe's barb spacing (within 15 %), and
  at least a quarter of the region inside the feather's outline shows the background between
  barbs.
* At the README's hero view (``assets/scenes/eye_feather_sun.usda``) barbs and sheet agree: the
  mean colour of each ocellus zone within CIE ΔE2000 3 (zones from the ocellar map at the
  feather coordinate the sheet shows each pixel, alpha above 0.9, one pixel in from every zone
  boundary).

    pytest tests/test_barbs_render.py -s   # prints the figures
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
ASSET = REPO / "assets" / "feathers" / "eye_feather" / "eye_feather.usd"
HERO = REPO / "assets" / "scenes" / "eye_feather_sun.usda"
RECIPE = REPO / "assets" / "recipes" / "eye_feather.toml"
#: The close-up: 4 cm across, centred 1 cm right of the rachis, 4.5 cm up the vane (v = 0.15).
VIEW_CM, CENTRE = 4.0, (1.0, 4.5)
CLOSE_RES, CLOSE_SPP = 256, 16
HERO_RES, HERO_SPP = (128, 192), 32


def _close_up(folder: Path, geometry: str) -> Path:
    """A camera 8.3 cm in front of the vane (50 mm lens, 24 mm aperture: 4 cm across), the
    hero scene's sun, no sky: the background is black."""
    distance = VIEW_CM * 50.0 / 24.0
    text = f"""#usda 1.0
(
    defaultPrim = "World"
    metersPerUnit = 0.01
    upAxis = "Y"
    renderSettingsPrimPath = "/Render/Settings"
)
def Xform "World"
{{
    def Xform "Feather" (
        prepend references = @{ASSET}@
        variants = {{ string geometry = "{geometry}" }}
    )
    {{
    }}
    def Camera "Camera"
    {{
        float focalLength = 50
        float horizontalAperture = 24
        float verticalAperture = 24
        float2 clippingRange = (0.5, 100)
        double3 xformOp:translate = ({CENTRE[0]}, {CENTRE[1]}, {distance:.4f})
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }}
    def DistantLight "Sun"
    {{
        float inputs:angle = 0.53
        float inputs:intensity = 3.14159
        bool inputs:normalize = 1
        float xformOp:rotateY = 25
        uniform token[] xformOpOrder = ["xformOp:rotateY"]
    }}
}}
def Scope "Render"
{{
    def RenderSettings "Settings"
    {{
        rel camera = </World/Camera>
        int2 resolution = ({CLOSE_RES}, {CLOSE_RES})
    }}
}}
"""
    path = folder / f"close_{geometry}.usda"
    path.write_text(text)
    return path


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
    from pavonine.render.api import render_stage
    from pavonine.render.imageio import write_png

    spacing_cm = tomllib.loads(RECIPE.read_text())["geometry"].get("barbs", {})
    spacing_cm = spacing_cm.get("spacing_cm", 0.225)
    rgb = {
        g: render_stage(_close_up(tmp_path, g), spp=CLOSE_SPP, seed=0, progress=False).rgb
        for g in ("sheet", "barbs")
    }
    write_png(tmp_path / "close_up.png", np.concatenate([rgb["sheet"], rgb["barbs"]], 1))
    np.save(tmp_path / "close_up.npy", np.stack([rgb["sheet"], rgb["barbs"]]))
    sheet, barbs = _luma(rgb["sheet"]), _luma(rgb["barbs"])
    lit = np.median(sheet[sheet > 0])
    # Inside the outline: where the sheet shows (its own opacity aside), closed a few pixels.
    from scipy import ndimage

    inside = ndimage.binary_closing(sheet > 0.05 * lit, iterations=3)
    inside = ndimage.binary_erosion(inside, iterations=2)
    # A pixel shows the background where it is under half as bright as the barbs beside it
    # (the brightest within one spacing): half-maximum, as a gap's edge pixels are shared.
    pixels_per_cm = CLOSE_RES / VIEW_CM
    near = ndimage.maximum_filter(barbs, size=round(spacing_cm * pixels_per_cm))
    background = float(np.mean(barbs[inside] < 0.5 * near[inside]))
    nearly_black = float(np.mean(barbs[inside] < 0.05 * lit))
    # Along the rachis (image columns) the barbs repeat every spacing_cm, whatever their angle.
    columns = barbs[:, inside.mean(axis=0) > 0.9]
    power = np.abs(np.fft.rfft(columns - columns.mean(axis=0), axis=0)) ** 2
    spectrum = power.mean(axis=1)
    spectrum[:3] = 0.0  # the outline's own scale
    period = CLOSE_RES / int(np.argmax(spectrum))
    expected = spacing_cm * pixels_per_cm
    print(
        f"\nclose-up: barb period {period:.2f} px (recipe spacing {expected:.2f} px), "
        f"background inside the outline {background:.1%} at half maximum, {nearly_black:.1%} "
        f"under 5 % of the lit sheet ({int(inside.sum())} px)"
    )
    assert columns.shape[1] >= 20
    assert abs(period - expected) <= 0.15 * expected
    assert background >= 0.25


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
