"""The shipped train read back as a display (``pipeline/assemble/display.py``): the eyes' count,
lattice and span against the cited figures, each eye on the vanes below it, every feather bent."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from pavonine.apps.cli import cli
from pavonine.pipeline.assemble import display as D

REPO = Path(__file__).parents[2]
RECIPE = REPO / "assets" / "recipes" / "peacock_train.toml"
SHIPPED = REPO / "assets" / "assemblies" / "peacock_train" / "peacock_train.usda"


@pytest.fixture(scope="module")
def feathers() -> D.Feathers:
    return D.read_feathers(SHIPPED)


def test_the_eyes_are_as_many_as_a_full_train_in_concentric_rows(feathers):
    rows = D.eye_rows(feathers)
    # 165-170 eyes in a full adult train (Dakin & Montgomerie 2011, Anim. Behav. 82: 21-28)
    assert 165 <= sum(len(r.members) for r in rows) <= 170
    assert len(rows) == 6 and all(len(r.members) == 28 for r in rows)
    radii = [r.radius_cm for r in rows]
    assert radii == sorted(radii, reverse=True)
    for row in rows:  # a semicircle and a little: the fan reaches the ground on both sides
        assert 180 <= row.span_deg <= 190, row.span_deg


def test_the_eyes_lie_on_a_hexagonal_lattice(feathers):
    """Adjacent rows √3/2 of the along-row step apart and staggered (Singh et al. 2024)."""
    for radial, stagger in D.lattice(D.eye_rows(feathers)):
        assert radial == pytest.approx(math.sqrt(3) / 2, rel=0.08)
        assert 0.35 <= stagger <= 0.5  # half a step, less the rotation jitter's fold


def test_each_eye_lies_on_the_vanes_of_the_row_behind(feathers):
    rows = D.eye_rows(feathers)
    shares = D.eyes_on_vanes(feathers, rows)
    assert len(shares) == len(rows) - 1 and min(shares) >= 0.9, shares
    for row in rows:  # neighbours in a row overlap, as scales do, yet each eye shows
        assert 0.3 <= D.side_overlap(feathers, row) <= 0.6


def test_every_feather_is_curved_and_the_rows_bend_scales_it(feathers, tmp_path):
    bent = D.sagittas(feathers)
    assert np.all(bent > 0.1), bent.min()
    flat_text = RECIPE.read_text().replace("bend = 3.0", "bend = 1.0")
    flat_text = flat_text.replace('"../feathers/', f'"{REPO / "assets" / "feathers"}/')
    recipe = tmp_path / "flat.toml"
    recipe.write_text(flat_text)
    result = CliRunner().invoke(cli, ["assemble", "train", str(recipe), "-o", str(tmp_path)])
    assert result.exit_code == 0, result.output
    flat = D.sagittas(D.read_feathers(tmp_path / "peacock_train" / "peacock_train.usda"))
    eyes = np.array(feathers.names) == "eye"
    ratio = bent[eyes] / flat[eyes]  # the depth scale is the bend: about 3x, the chord tilting
    assert np.all((ratio > 2.5) & (ratio < 3.1)), (ratio.min(), ratio.max())


def test_a_flat_sheet_has_no_sagitta():
    line = np.array([[0.0, y, 0.0] for y in np.linspace(0, 30, 31)])
    feathers = D.Feathers(["f"], np.eye(4)[None], {"f": line}, {})
    assert D.sagittas(feathers)[0] == pytest.approx(0.0, abs=1e-12)
    arc = np.array([[0.0, y, -2.0 * (y / 30) ** 2] for y in np.linspace(0, 30, 301)])
    feathers = D.Feathers(["f"], np.eye(4)[None], {"f": arc}, {})
    # a parabola z = -b v² over its chord: sagitta b/4 · cos(atan(b/L)), b = 2 cm, L = 30 cm
    assert D.sagittas(feathers)[0] == pytest.approx(0.5 * math.cos(math.atan(2 / 30)), rel=1e-3)
