"""Without Mitsuba, sRGB colours are upsampled by the same Jakob & Hanika fit Mitsuba tabulates."""

import numpy as np
import pytest

from pavonine.materials.brdf import srgb_model_eval
from pavonine.materials.upsampling import fit_sigmoid_polynomial

mi = pytest.importorskip("mitsuba")

COLOURS = [(0.22, 0.12, 0.06), (0.5, 0.5, 0.5), (0.9, 0.1, 0.1), (0.02, 0.02, 0.02)]
COLOURS += [tuple(c) for c in np.random.default_rng(1).uniform(0.05, 0.9, (8, 3))]


@pytest.mark.parametrize("rgb", COLOURS, ids=lambda c: "_".join(f"{v:.2f}" for v in c))
def test_fit_gives_mitsubas_spectrum(rgb):
    from pavonine.base.backend import select_variant

    select_variant()
    wavelengths = np.arange(360.0, 831.0, 1.0)
    ours = srgb_model_eval(fit_sigmoid_polynomial(rgb), wavelengths)
    theirs = srgb_model_eval(np.array(mi.srgb_model_fetch(mi.ScalarColor3f(*rgb))), wavelengths)
    # Mitsuba interpolates a 64³ table of the same fits; measured worst case 1.0e-3
    assert np.max(np.abs(ours - theirs)) < 2e-3


def test_fit_reproduces_the_colour():
    from pavonine.materials import colour

    wavelengths = np.arange(360.0, 831.0, 1.0)
    rgb = np.array([0.22, 0.12, 0.06])
    spectrum = srgb_model_eval(fit_sigmoid_polynomial(tuple(rgb)), wavelengths)
    assert colour.delta_e76(colour.reflectance_to_linear_srgb(wavelengths, spectrum), rgb) < 1e-4
