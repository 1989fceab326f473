"""Crisp zones (issue 24): a ring boundary in a close-up is a smooth curve, not a staircase of the
ocellar map's texels (the scene: ``tests/glint_scene.py`` at 4 pixels per texel)."""

import numpy as np
import pytest

pytest.importorskip("mitsuba")  # conftest says why when it cannot load
from glint_scene import EYE, closeup_stage

from pavonine.base.map_files import read_map, sample_nearest
from pavonine.render.api import render_stage

pytestmark = pytest.mark.render
RES = 128
TEXEL_MM = 150.0 / 512  # the shipped eye's ocellar map: 512 texels over 15 cm
PIXELS_PER_TEXEL = 4


def _boundary_columns(left: np.ndarray) -> np.ndarray:
    """Per row, the columns of the left zone (the boundary runs top to bottom), after a 5×5
    median filter (the render's noise flips single pixels)."""
    from scipy import ndimage

    clean = ndimage.median_filter(left.astype(np.uint8), size=5, mode="nearest")
    return clean.sum(axis=1).astype(np.float64)


def _deviation(columns: np.ndarray) -> float:
    """Largest distance (pixels) of the boundary from a smooth (cubic) curve fitted through it."""
    rows = np.arange(len(columns), dtype=np.float64)
    fit = np.polynomial.Polynomial.fit(rows, columns, 3)
    return float(np.max(np.abs(columns - fit(rows))))


def test_a_ring_boundary_has_no_texel_staircase(tmp_path):
    field = RES / PIXELS_PER_TEXEL * TEXEL_MM
    stage = closeup_stage(tmp_path / "boundary.usda", 0.0, field_mm=field, uv=True)
    # 128 spp: the heart's narrow 443 nm band makes its red-minus-green noisy; at 32 spp the largest
    # deviation scattered by sd 0.13 px over seeds 0-5 (0.83-1.16 px), at 128 spp 0.02 (0.86-0.90).
    result = render_stage(stage, spp=128, progress=False)
    rgb, uv = result.rgb, result.images["uv"]
    # The dark centre (class 5) renders violet, its first ring (class 4) cyan: split by the
    # red-minus-green difference, midway between the two zones' typical values.
    key = rgb[..., 0] - rgb[..., 1]
    left_value, right_value = np.median(key[:, :8]), np.median(key[:, -8:])
    assert left_value > right_value + 0.05  # two zones, violet on the left
    left = key > 0.5 * (left_value + right_value)
    rendered = _deviation(_boundary_columns(left))
    # The same pixels' classes looked up per texel (the map's staircase) for comparison.
    grey = read_map(EYE.parent / "maps" / "ocellar.png", "ocellar")
    feather_uv = np.stack([uv[..., 0], 1.0 - uv[..., 1]], axis=-1).reshape(-1, 2)
    per_texel = sample_nearest(grey, feather_uv).reshape(RES, RES) < 0.1
    staircase = _deviation(_boundary_columns(per_texel))
    assert staircase > 1.5, staircase  # the metric sees the texels
    assert rendered <= 1.0, (rendered, staircase)
