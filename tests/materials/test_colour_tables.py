"""The colour tables analysis uses without Mitsuba are Mitsuba's own (observer, illuminant, matrix)."""

import numpy as np
import pytest

from pavonine.materials import colour

mi = pytest.importorskip("mitsuba")


@pytest.fixture(scope="module")
def scalar():
    from pavonine.base.backend import select_variant

    previous = select_variant().variant
    mi.set_variant("scalar_spectral")
    yield
    mi.set_variant(previous)


def test_cmfs_and_d65_match_mitsuba_on_and_between_the_grid(scalar):
    rng = np.random.default_rng(3)
    wavelengths = np.concatenate([np.arange(360.0, 831.0, 1.0), rng.uniform(355.0, 835.0, 300)])
    expected_cmf = np.array([np.array(mi.cie1931_xyz(float(w))) for w in wavelengths])
    expected_d65 = np.array([float(mi.cie_d65(float(w))) for w in wavelengths])
    on_grid = slice(0, 471)  # the table holds Mitsuba's values exactly; between them Mitsuba
    assert np.array_equal(colour.cmfs(wavelengths[on_grid]), expected_cmf[on_grid])
    assert np.array_equal(colour.d65(wavelengths[on_grid]), expected_d65[on_grid])
    # interpolates linearly in float32, NumPy in float64: equal to float32 precision
    assert colour.cmfs(wavelengths) == pytest.approx(expected_cmf, rel=1e-5, abs=1e-7)
    assert colour.d65(wavelengths) == pytest.approx(expected_d65, rel=1e-5, abs=1e-7)


def test_xyz_to_srgb_matrix_is_mitsubas(scalar):
    columns = [np.array(mi.xyz_to_srgb(mi.Color3f(*e))) for e in np.eye(3)]
    assert np.array_equal(colour.XYZ_TO_SRGB, np.array(columns, dtype=np.float64).T)


def test_white_reflector_is_white():
    w = np.arange(360.0, 831.0, 1.0)
    assert colour.reflectance_to_xyz(w, np.ones_like(w))[1] == pytest.approx(1.0, abs=1e-12)
    assert colour.reflectance_to_linear_srgb(w, np.ones_like(w)) == pytest.approx(1.0, abs=2e-4)
