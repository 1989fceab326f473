"""Acceptance (issue 9): the shipped eye feather renders its ocellus rings in the right order."""

from __future__ import annotations

import colorsys
import warnings
from pathlib import Path

import numpy as np
import pytest

from pavonine.render.api import render_stage
from pavonine.render.diagnostics import StageWarning

pytestmark = pytest.mark.render

SCENE = Path(__file__).parents[2] / "assets" / "scenes" / "eye_feather_sun.usda"
#: The heart of the eye in the shipped asset (cm): feather v = 0.74 of 30 cm, bent back 2 cm·v².
EYE_CENTRE = (0.0, 0.74 * 30.0, -2.0 * 0.74**2)
#: Zones from the centre out (docs/pipeline.md, "The ocellus"), as the hue ranges (degrees, HSV
#: of the display colour) they must fall in: violet to purple; cyan to blue; orange-brown (bronze
#: is a dark orange); yellow-gold; yellow-green (brass) to green.
ZONES = (
    ("dark blue-violet heart", (250.0, 345.0)),
    ("turquoise / blue-green ring", (165.0, 250.0)),
    ("bronze / brown ring", (10.0, 40.0)),
    ("green-gold ring", (40.0, 65.0)),
    ("brass-green vane", (65.0, 165.0)),
)


def _zone(rgb) -> int | None:
    h, s, v = colorsys.rgb_to_hsv(*(float(c) for c in rgb))
    if v < 0.04 or s < 0.12:
        return None  # too dark or too grey to have a hue
    hue = 360.0 * h
    for i, (_, (lo, hi)) in enumerate(ZONES):
        if lo <= hue < hi:
            return i
    return None


def _project(result, point) -> tuple[float, float]:
    from pxr import Gf, Usd, UsdGeom

    stage = Usd.Stage.Open(str(SCENE))
    camera = UsdGeom.Camera(stage.GetPrimAtPath("/World/Camera")).GetCamera()
    frustum = camera.frustum
    ndc = frustum.ComputeViewMatrix() * frustum.ComputeProjectionMatrix()
    p = ndc.Transform(Gf.Vec3d(*point))
    height, width = result.rgb.shape[:2]
    return (p[0] + 1.0) * 0.5 * width, (1.0 - p[1]) * 0.5 * height


@pytest.fixture(scope="module")
def render():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        return render_stage(SCENE, spp=16, resolution=(128, 192), progress=False)


def test_ocellus_rings_are_in_order_along_rays_from_the_centre(render):
    from pavonine.materials.colour import display_encode

    display = np.clip(display_encode(np.clip(render.rgb, 0.0, None)), 0.0, 1.0)
    cx, cy = _project(render, EYE_CENTRE)
    height, width = display.shape[:2]
    ok = 0
    sequences = {}
    for angle in (-135, -90, -45, 0, 45, 90, 135):  # not straight down: the rachis runs there
        t = np.radians(angle)
        zones = []
        for r in np.arange(0.0, 0.4 * width, 1.0):
            x, y = cx + r * np.sin(t), cy - r * np.cos(t)
            if not (0 <= x < width and 0 <= y < height):
                break
            zones.append(_zone(display[int(y), int(x)]))
        # first sample of each zone that starts a run of at least two (single texels of the
        # heart's melanin brown or of the barb streaks are not a ring)
        firsts = [
            next((i for i in range(len(zones) - 1) if zones[i] == zones[i + 1] == z), None)
            for z in range(len(ZONES))
        ]
        sequences[angle] = firsts
        if None not in firsts and firsts == sorted(firsts):
            ok += 1
    # Every ray but two: above the eye the gold ring and the vane are only a few texels wide.
    assert ok >= 5, (ok, sequences)
