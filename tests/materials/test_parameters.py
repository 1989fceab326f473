"""The gradation map of the literature preset: measured structure at t = ½, a size spread at the
ends (materials/parameters.py, ``freyer_class``; docs/model.md, "Gradation in freyer2020")."""

from __future__ import annotations

import numpy as np
import pytest

from pavonine.materials import colour, optics
from pavonine.materials.brdf import direction
from pavonine.materials.dispersion import Dispersion
from pavonine.materials.parameters import (
    FREYER_2020_CLASSES,
    FREYER_2020_REGIONS,
    FREYER_2020_SIZE_SPREAD,
    ParameterError,
    freyer_class,
    preset,
)
from pavonine.materials.stack import structure_reflectance

FREYER = preset("freyer2020")
LAM = np.arange(360.0, 831.0, 2.0)


@pytest.mark.parametrize("k", range(6))
def test_measured_region_sits_at_the_middle_and_the_ends_scale_it(k):
    a, b, c, dm, da, nm = FREYER_2020_REGIONS[FREYER_2020_CLASSES[k]]
    cls = FREYER.classes[k]
    for stack in cls.at(0.5):  # both axes: the region as measured (µm)
        assert (stack.interval, stack.spacing, 2 * stack.radius, stack.channel) == pytest.approx(
            (a / 1000, b / 1000, dm / 1000, da / 1000), rel=1e-6
        )
        assert stack.count == nm
    assert cls.cortex_at(0.5) == pytest.approx(c / 1000, rel=1e-6)
    for axis in (cls.long, cls.short):
        black, white = axis
        for quantity in ("interval", "radius", "spacing", "channel"):
            middle = getattr(cls.at(0.5)[0], quantity)
            assert getattr(black, quantity) == pytest.approx(middle * 0.97, rel=1e-6)
            assert getattr(white, quantity) == pytest.approx(middle * 1.03, rel=1e-6)
        assert black.count == white.count == nm  # the layer count is the region's own
    assert cls.cortex == pytest.approx((c * 0.97 / 1000, c * 1.03 / 1000), rel=1e-6)


def test_both_ends_of_every_class_fit_a_real_rectangular_lattice():
    FREYER.validate()  # the physical mode refuses overlapping rods or channels at either end
    for k, cls in enumerate(FREYER.classes):
        for end, stack in enumerate(cls.long):
            lattice = stack.lattice("rectangular", cls.cortex[end]).check()
            assert lattice.interval >= 2 * lattice.radius, (k, end)  # d >= 2a (rectangular)
            assert lattice.period >= 2 * lattice.radius, (k, end)


def test_a_uniform_scale_shifts_the_spectrum_by_the_same_factor():
    """Maxwell's equations have no length scale: with constant indices, the end scaled by s
    reflects at s·λ exactly what the measured structure reflects at λ (a closed form check of the
    rule and of the effective-medium stack, whose slices scale with the rods)."""
    rod, matrix = Dispersion.constant(1.75), Dispersion.constant(1.54)
    cls = freyer_class("blue-green")
    cos_inside = np.array([[1.0, 0.9, 0.8]])
    middle = structure_reflectance(
        cls.at(0.5)[0], "rectangular", cls.cortex_at(0.5), LAM[:, None], cos_inside, rod, matrix
    )
    for t, scale in ((0.0, 1 - FREYER_2020_SIZE_SPREAD), (1.0, 1 + FREYER_2020_SIZE_SPREAD)):
        end = structure_reflectance(
            cls.at(t)[0],
            "rectangular",
            cls.cortex_at(t),
            scale * LAM[:, None],
            cos_inside,
            rod,
            matrix,
        )
        assert np.max(np.abs(end - middle)) < 1e-5
        assert np.max(np.abs(end - middle)) < 1e-3 * np.max(middle)


@pytest.mark.parametrize("k", range(6))
def test_the_gradation_map_changes_every_class(k):
    """The regression: with equal ends the gradation map (and the train's per-instance offset)
    changed nothing. Now the band moves red from the black to the white end by about the size
    spread and the colour changes visibly (CIE ΔE2000 > 3 between the ends)."""
    model = optics.model_for(FREYER)
    h = direction(10.0, 45.0)
    peaks, labs = [], []
    for t in (0.0, 0.5, 1.0):
        spectrum = model.structural(h, h, LAM, k, t)
        peaks.append(LAM[np.argmax(spectrum)])
        labs.append(colour.xyz_to_lab(colour.reflectance_to_xyz(LAM, spectrum)))
    assert peaks[0] < peaks[1] < peaks[2], peaks
    assert peaks[2] / peaks[0] == pytest.approx(1.03 / 0.97, abs=0.015)
    assert float(colour.delta_e2000(labs[0], labs[2])) > 3.0


def test_freyer_class_refuses_unknown_regions_and_spreads():
    with pytest.raises(ParameterError, match="unknown region 'teal'"):
        freyer_class("teal")
    with pytest.raises(ParameterError, match="spread"):
        freyer_class("brown", spread=1.5)
    flat = freyer_class("brown", spread=0.0)
    assert flat.long[0] == flat.long[1] and flat.cortex[0] == flat.cortex[1]
