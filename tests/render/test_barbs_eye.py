"""Acceptance (issue 33): the eye's barbs show as fine radial lines over its colour, and the loose
lower vane is thin filaments with the background between them (tests/barb_measures.py defines
both measures; benchmarks/bench_barbs_eye.py measures them at full size, docs/pipeline.md).

* **Eye, 3 cm close-up**: tests/glint_scene.py's camera 3 cm above the heart's edge, at the full
  measure's pixel size (117 µm, 256 px over 3 cm) but its middle 1.5 cm only (128 px), 16 spp,
  seeds 0 and 1: the local contrast both seeds share is at least 1.5× the sheet's, glitter 0 and
  1. Beside it the radial lines' contrast (the luminance in polar coordinates about the rachis
  tip, averaged along the radius, high-passed along the angle) at least twice the sheet's.
* **Hero view, lower vane**: a 128×128 window of the README's hero view
  (assets/scenes/eye_feather_sun.usda, 512×768) on the lower vane, the same rays and pixel size
  (the camera's apertures narrowed to the window), no sky (film alpha 0 where rays miss):
  at least a quarter of the lower vane's outline shows the background in whole pixels.

    pytest tests/render/test_barbs_eye.py -s   # prints the figures
"""

from __future__ import annotations

import numpy as np
import pytest

#: The eye close-up: 1.5 cm of the 3 cm view at its 256-px pixel size, 16 spp.
EYE_FIELD_MM, EYE_RES, EYE_SPP, WINDOW = 15.0, 128, 16, 16
#: The hero window (x0, y0, width, height in the 512x768 hero pixels): the lower vane.
HERO_WINDOW, HERO_SPP = (192, 560, 128, 128), 8


@pytest.mark.render
@pytest.mark.parametrize("glitter", [0.0, 1.0])
def test_the_eyes_barbs_show_as_fine_radial_lines_3cm_across(tmp_path, glitter):
    from barb_measures import local_contrast, radial_line_contrast, render_color_alpha
    from glint_scene import TARGET, closeup_stage

    images = {}
    for geometry in ("sheet", "barbs"):
        path = closeup_stage(
            tmp_path / f"eye_{geometry}.usda",
            glitter,
            field_mm=EYE_FIELD_MM,
            resolution=EYE_RES,
            geometry=geometry,
        )
        images[geometry] = [render_color_alpha(path, EYE_SPP, seed) for seed in (0, 1)]
    on_feather = images["sheet"][0][1] > 0.99
    seeds = {g: (images[g][0][0], images[g][1][0]) for g in images}
    contrast = {g: local_contrast(seeds[g], on_feather, WINDOW) for g in seeds}
    lines = {
        g: radial_line_contrast(seeds[g], on_feather, TARGET[:2], EYE_FIELD_MM / 10.0)
        for g in seeds
    }
    print(
        f"\neye 3 cm (middle {EYE_FIELD_MM / 10:g} cm, {EYE_RES} px, {EYE_SPP} spp), glitter "
        f"{glitter:g}: local contrast sheet {contrast['sheet'][0]:.3f}, barbs "
        f"{contrast['barbs'][0]:.3f} ({contrast['sheet'][1]} windows); radial lines sheet "
        f"{lines['sheet']:.4f}, barbs {lines['barbs']:.4f}"
    )
    assert contrast["sheet"][1] >= 30  # the windows cover the eye
    assert contrast["barbs"][0] >= 1.5 * contrast["sheet"][0]
    assert lines["barbs"] >= 2.0 * lines["sheet"]


@pytest.mark.render
def test_the_lower_vane_shows_the_background_between_filaments_at_the_hero_view(tmp_path):
    from barb_measures import (
        hero_stage,
        lower_vane_outline,
        render_color_alpha,
        whole_pixel_share,
    )

    width, height = HERO_WINDOW[2:]
    outline = lower_vane_outline(
        hero_stage(tmp_path, "sheet", HERO_WINDOW, sky=False), width, height
    )
    _, alpha = render_color_alpha(hero_stage(tmp_path, "barbs", HERO_WINDOW, sky=False), HERO_SPP)
    share = whole_pixel_share(alpha, outline)
    print(
        f"\nhero window {HERO_WINDOW}: the lower vane's outline ({int(outline.sum())} px) shows "
        f"the background in whole pixels on {share:.1%}; mean film alpha "
        f"{float(np.mean(alpha[outline])):.3f}"
    )
    assert outline.mean() >= 0.3  # the window lies on the lower vane
    assert share >= 0.25
