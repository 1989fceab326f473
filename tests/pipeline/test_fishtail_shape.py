"""The fishtail feather reads as a feather (issue 33, item 4): a narrow shaft of loose barbs that
lengthen into two lobes trailing past the notch at the rachis tip (a swallow-tail), its barbs
leaving the rachis, not a solid chevron. Figures measured on the 1024-pixel maps the recipe is
made from and on the shipped barbs layer (before this shape: shaft half width 0.052, lobe barbs
76° from the rachis, 33 % of the vane loose, 453 barbs of which 240 rooted at the tip, its fan)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from pxr import Usd, UsdGeom
from scipy import ndimage

from pavonine.pipeline.convert.barb_curves import coverage_map, seeds
from pavonine.pipeline.convert.barb_form import LOOSE_COVERAGE
from pavonine.pipeline.convert.barbs import barb_direction_field
from pavonine.pipeline.convert.rachis import RachisSpec
from pavonine.pipeline.convert.recipe import BarbOptions
from pavonine.pipeline.convert.surface import FeatherFrame
from pavonine.pipeline.maps.paint import (
    FISHTAIL_RACHIS_TIP,
    FISHTAIL_SPACING,
    generate_maps,
)

ROOT = Path(__file__).resolve().parents[2]
BARBS = ROOT / "assets/feathers/fishtail_feather/fishtail_feather_geo_barbs.usdc"
LENGTH_CM = 30.0  # assets/recipes/fishtail_feather.toml


@pytest.fixture(scope="module")
def maps() -> dict[str, np.ndarray]:
    return generate_maps("fishtail", 1024, 1)  # the recipe's maps (docs/pipeline.md)


def _coords(shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    h, w = shape
    x = ((np.arange(w) + 0.5) / w - 0.5) * (w / h)
    y = 1.0 - (np.arange(h) + 0.5) / h
    return np.meshgrid(x, y)


def _inside(maps: dict[str, np.ndarray]) -> np.ndarray:
    """The vane as the converter sees it: alpha box-filtered over one barb spacing above the
    level at which a barb ends (barb_curves.END_COVERAGE)."""
    alpha = maps["alpha"]
    return coverage_map(alpha, FISHTAIL_SPACING * alpha.shape[0]) > 0.02


def test_silhouette_is_a_swallow_tail(maps):
    inside = _inside(maps)
    x, y = _coords(inside.shape)
    top = np.where(inside, y, -1.0).max(axis=0)  # highest vane point per column
    notch = top[np.abs(x[0]) < 0.01].max()
    lobes = top.max()
    # The notch sits at the rachis tip; the lobes trail 0.158 of the length (4.7 cm) past it.
    assert notch == pytest.approx(FISHTAIL_RACHIS_TIP, abs=0.015)
    assert lobes - notch > 0.12
    assert lobes < 0.99  # the lobes' tips lie inside the map, not cut by its edge

    def half_width(height: float) -> float:
        row = int((1.0 - height) * inside.shape[0])
        return float(np.abs(x[row][inside[row]]).max())

    # A long narrow shaft (0.032: ~1 cm across at 30 cm), the lobes 5× as wide (0.172).
    assert half_width(0.3) < 0.04
    assert half_width(0.9) > 4.0 * half_width(0.3)


def test_most_of_the_vane_hangs_loose(maps):
    """Loose barbs (coverage at most LOOSE_COVERAGE: filaments, no hooked barbules) on most of
    the vane: the whole shaft and the outer part of every lobe barb (measured 0.716)."""
    alpha = maps["alpha"]
    coverage = coverage_map(alpha, FISHTAIL_SPACING * alpha.shape[0])
    inside = coverage > 0.02
    loose = (coverage <= LOOSE_COVERAGE) & inside
    assert loose.sum() / inside.sum() > 0.55
    # ... but the lobes keep a closed core beside the rachis, the metallic green.
    x, y = _coords(alpha.shape)
    core = inside & (y > 0.7) & (y < FISHTAIL_RACHIS_TIP) & (np.abs(x) < 0.03)
    assert np.median(coverage[core]) > 0.9


def test_barbs_leave_the_rachis_apex_ward(maps):
    """The barb direction the converter measures from the streaks: 40° from the rachis on the
    shaft (measured 41.8°), and in the lobes above the notch still pointing apex-ward (41.6°),
    not running across them (the chevron's barbs: 76°)."""
    field = barb_direction_field(maps["displacement"])
    inside = ndimage.zoom(_inside(maps).astype(float), field.shape[0] / 1024, order=0) > 0.5
    x, y = _coords(field.shape[:2])
    angle = np.degrees(np.arctan2(np.abs(field[..., 0]), np.abs(field[..., 1])))
    shaft = inside & (y > 0.1) & (y < 0.4) & (np.abs(x) > 0.01)
    lobes = inside & (y > 0.85) & (np.abs(x) > 0.05)
    assert np.median(angle[shaft]) == pytest.approx(40.0, abs=5.0)
    assert 25.0 < np.median(angle[lobes]) < 50.0


def test_no_fan_without_an_eye():
    """``tip_barbs = 0``: every barb leaves the side of the rachis, none radiates from its tip."""
    frame = FeatherFrame(length=30.0, aspect=0.42, bend=0.0, cup=0.0)
    rachis = RachisSpec(calamus_cm=5.0, top=0.8, radius_cm=0.13, tip_radius_cm=0.025)
    start, _, rachis_barb = seeds(frame, rachis, BarbOptions(tip_barbs=0))
    assert rachis_barb.all() and len(start) == 2 * round(0.8 * 30.0 / 0.225)
    _, _, with_fan = seeds(frame, rachis, BarbOptions(tip_barbs=240))
    assert (~with_fan).sum() == 239


def test_shipped_barbs_leave_the_rachis_and_hang_loose():
    """The shipped barbs layer: every barb rooted on the rachis below its tip, 214 of them (two
    per 0.225 cm of the 24 cm shaft; none fanned from the tip), and most of their length
    loose (no barbules reaching past the ribbon: 76 % of the vertices; the chevron's 36 %)."""
    stage = Usd.Stage.Open(str(BARBS))
    curves = next(UsdGeom.BasisCurves(p) for p in stage.Traverse() if p.IsA(UsdGeom.BasisCurves))
    points = np.asarray(curves.GetPointsAttr().Get())
    counts = np.asarray(curves.GetCurveVertexCountsAttr().Get())
    roots = points[np.concatenate([[0], np.cumsum(counts)[:-1]])]
    assert len(counts) == 2 * round(FISHTAIL_RACHIS_TIP * LENGTH_CM / 0.225)
    assert np.abs(roots[:, 0]).max() < 0.3  # on the shaft (radius 0.13 cm)
    assert roots[:, 1].max() < FISHTAIL_RACHIS_TIP * LENGTH_CM
    barbules = np.asarray(UsdGeom.PrimvarsAPI(curves).GetPrimvar("pavonine_barbules").Get())
    assert (barbules <= 1e-6).mean() > 0.6
