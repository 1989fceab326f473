"""Clumps of loose barbs (pipeline/convert/barb_clumps.py; issue 33, "barbs splitting into
clumps in places as real vanes do").

Unit figures against closed forms, and from the shipped eye feather's barbs
(``assets/feathers/eye_feather/eye_feather_geo_barbs.usdc``): the spacing of the fringe's loose
tips (the tip's fan) along the vane's edge is no comb.

    pytest tests/pipeline/test_barb_clumps.py -s   # prints the figures
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest
from barb_layer import curve_attributes

from pavonine.pipeline.convert.barb_clumps import clump, clump_guides, point_at_length
from pavonine.pipeline.convert.barb_form import FormOptions, apply_form

REPO = Path(__file__).resolve().parents[2]
LAYER = REPO / "assets" / "feathers" / "eye_feather" / "eye_feather_geo_barbs.usdc"
RECIPE = REPO / "assets" / "recipes" / "eye_feather.toml"


@pytest.mark.parametrize("size", [1.0, 4.0, 7.0])
def test_clump_runs_average_the_clump_size_and_keep_families_apart(size):
    family = np.repeat([0, 1, 2], 2000)
    position = -np.arange(6000.0)  # order within a family reversed: runs follow position
    guide = clump_guides(family, position, size, np.random.default_rng(5))
    assert np.all(family[guide] == family)
    runs = np.unique(guide)
    # 1 + Poisson(size - 1) barbs a run: the mean run is `size` (3 x 2000 barbs, within 5 %).
    assert len(family) / len(runs) == pytest.approx(size, rel=0.05)
    assert np.all(guide[runs] == runs)  # a guide is its own guide
    # A run is consecutive in position: its members lie within the run around the guide.
    assert np.abs(guide - np.arange(6000)).max() <= 2 * size + 12


def test_point_at_length_interpolates_along_each_barb():
    s = np.array([0.0, 1.0, 3.0, 0.0, 2.0])
    points = np.column_stack([s, [0, 0, 0, 1, 1], np.zeros(5)])
    counts = np.array([3, 2])
    got = point_at_length(points, s, counts, np.array([0, 0, 1, 1]), np.array([2.0, 9.0, 0.5, -1]))
    assert np.allclose(got, [[2.0, 0, 0], [3.0, 0, 0], [0.5, 1, 0], [0.0, 1, 0]])


def test_a_loose_tip_moves_the_clump_share_toward_its_guide_and_closed_parts_stay():
    # Three parallel barbs 1 cm apart, 4 vertices each; loose share 0, 0, 0.5, 1 along each.
    s = np.tile([0.0, 1.0, 2.0, 3.0], 3)
    points = np.column_stack([s, np.repeat([0.0, 1.0, 2.0], 4), np.zeros(12)])
    counts = np.array([4, 4, 4])
    share = np.tile([0.0, 0.0, 0.5, 1.0], 3)
    guide = np.array([1, 1, 1])
    free = np.array([True, True, False])
    moved = clump(points, s, counts, share, guide, 0.6, free)
    assert np.allclose(moved[:2], points[:2])  # closed: the barbules hold it
    assert np.allclose(moved[4:8], points[4:8])  # the guide stays
    assert moved[3, 1] == pytest.approx(0.6)  # 0 + 0.6 x (1 - 0) at the tip
    assert moved[2, 1] == pytest.approx(0.3)  # half of it halfway along the loose part
    assert np.allclose(moved[8:], points[8:])  # not free: stays
    assert clump(points, s, counts, share, guide, 0.0, free) is points


def test_fan_barbs_clump_deterministically_and_rachis_barbs_do_not():
    from test_barb_form import _comb

    curves, along, rachis = _comb(barbs=12)
    options = FormOptions(
        camber=0.0,
        bow=0.0,
        bow_out=0.0,
        droop_deg=0.0,
        root_jitter=0.0,
        length_jitter=0.0,
        clump=0.8,
    )
    family, position = np.zeros(12, dtype=int), np.arange(12.0)
    fan = ~rachis
    a = apply_form(curves, along, fan, 0.2, 7.5, options, 3, family, position)
    b = apply_form(curves, along, fan, 0.2, 7.5, options, 3, family, position)
    assert np.array_equal(a.points, b.points)
    assert not np.allclose(a.points, curves.points)  # the loose tails gathered
    kept = apply_form(curves, along, rachis, 0.2, 7.5, options, 3, family, position)
    assert np.allclose(kept.points, curves.points)  # rachis barbs do not clump


def _fringe_tip_gaps(path: Path, rachis_top: float) -> np.ndarray:
    """Distances (cm) between neighbouring loose tips of the tip's fan, in their order around
    the rachis tip; a barb is loose at its tip where its barbules reach nothing
    (``pavonine_barbules`` 0: coverage under 0.75)."""
    attrs = curve_attributes(path)
    points = attrs["points"].astype(float)
    counts = attrs["curveVertexCounts"].astype(int)
    uv = attrs["primvars:pavonine_featherUV"].astype(float)
    reach = attrs["primvars:pavonine_barbules"].astype(float)
    starts = np.cumsum(counts) - counts
    ends = starts + counts - 1
    chosen = (uv[starts, 1] > rachis_top - 0.005) & (reach[ends] <= 1e-6)
    tips, roots = points[ends[chosen]], points[starts[chosen]]
    centre = roots.mean(axis=0)
    order = np.argsort(np.arctan2(tips[:, 0] - centre[0], tips[:, 1] - centre[1]))
    return np.linalg.norm(np.diff(tips[order], axis=0), axis=1)


def test_the_shipped_eye_feathers_fringe_is_clumped():
    """The fringe's loose tips: gap CV 0.411 unclumped (the layer before clumps), 0.815 with
    the shipped ``clump = 0.6``, ``clump_size = 4`` (174 tips)."""
    top = tomllib.loads(RECIPE.read_text())["geometry"]["rachis_length"]
    gaps = _fringe_tip_gaps(LAYER, top)
    cv = gaps.std() / gaps.mean()
    share_close = float(np.mean(gaps < 0.5 * np.median(gaps)))
    print(
        f"\nfringe tips {len(gaps) + 1}: gap CV {cv:.3f}, {share_close:.1%} under half the median"
    )
    assert len(gaps) >= 100
    assert cv >= 0.65
