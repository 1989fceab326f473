"""CIEDE2000 (``pavonine.materials.colour.delta_e2000``) against the published test data of Sharma,
Wu & Dalal (2005), "The CIEDE2000 color-difference formula: implementation notes, supplementary
test data, and mathematical observations", Color Res. Appl. 30(1), Table 1."""

from __future__ import annotations

import numpy as np
import pytest

from pavonine.materials import colour

# (L1, a1, b1), (L2, a2, b2), ΔE00: pairs 1-4 (hue near 270°), 7-9 (hue angle wrap), 17-19,
# 24, 32 (dark colours) of Table 1.
SHARMA = [
    ((50.0000, 2.6772, -79.7751), (50.0000, 0.0000, -82.7485), 2.0425),
    ((50.0000, 3.1571, -77.2803), (50.0000, 0.0000, -82.7485), 2.8615),
    ((50.0000, 2.8361, -74.0200), (50.0000, 0.0000, -82.7485), 3.4412),
    ((50.0000, -1.3802, -84.2814), (50.0000, 0.0000, -82.7485), 1.0000),
    ((50.0000, 0.0000, 0.0000), (50.0000, -1.0000, 2.0000), 2.3669),
    ((50.0000, 2.4900, -0.0010), (50.0000, -2.4900, 0.0009), 7.1792),
    ((50.0000, 2.4900, -0.0010), (50.0000, -2.4900, 0.0010), 7.1792),
    ((50.0000, 2.4900, -0.0010), (50.0000, -2.4900, 0.0011), 7.2195),
    ((50.0000, 2.5000, 0.0000), (73.0000, 25.0000, -18.0000), 27.1492),
    ((50.0000, 2.5000, 0.0000), (50.0000, 3.2592, 0.3350), 1.0000),
    ((60.2574, -34.0099, 36.2677), (60.4626, -34.1751, 39.4387), 1.2644),
    ((2.0776, 0.0795, -1.1350), (0.9033, -0.0636, -0.5514), 0.9082),
]


def test_delta_e2000_matches_sharma_wu_dalal_table1():
    a = np.array([p[0] for p in SHARMA])
    b = np.array([p[1] for p in SHARMA])
    expected = np.array([p[2] for p in SHARMA])
    assert colour.delta_e2000(a, b) == pytest.approx(expected, abs=1e-4)
    assert colour.delta_e2000(b, a) == pytest.approx(expected, abs=1e-4)  # symmetric


def test_identical_colours_differ_by_nothing_and_white_is_l100():
    lab = colour.linear_srgb_to_lab(np.array([[1.0, 1.0, 1.0], [0.2, 0.4, 0.1]]))
    assert lab[0] == pytest.approx([100.0, 0.0, 0.0], abs=1e-6)
    assert colour.delta_e2000(lab, lab) == pytest.approx([0.0, 0.0])
