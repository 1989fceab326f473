"""Property tests of the full BRDF: reciprocal, non-negative, finite, energy-bounded."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pavonine.materials import optics
from pavonine.materials.brdf import direction
from pavonine.materials.parameters import preset

TABLE1 = preset("paper-table1")
FREYER = preset("freyer2020")
MODEL = optics.model_for(TABLE1)
INTENSITY_MODEL = optics.model_for(TABLE1.with_(interference="intensity"))
PHYSICAL_MODEL = optics.model_for(FREYER)
#: Every interference mode's material (the physical one as shipped: literature preset).
MODES = {"paper": TABLE1, "intensity": TABLE1.with_(interference="intensity"), "physical": FREYER}

polar = st.one_of(st.floats(0.0, 89.999), st.sampled_from([0.0, 1e-6, 45.0, 89.9, 89.999, 90.0]))
azimuth = st.floats(0.0, 360.0)
configs = st.tuples(
    polar,
    azimuth,
    polar,
    azimuth,
    st.floats(300.0, 900.0),
    st.integers(0, 5),
    st.floats(0.0, 1.0),
    st.floats(0.0, 1.0),
    st.booleans(),
)


@settings(max_examples=400, deadline=None)
@given(configs)
def test_brdf_is_reciprocal_nonnegative_and_finite(config):
    ti, pi, to, po, lam, cls, grad, share, below = config
    wi, wo = direction(ti, pi), direction(to, po)
    if below:  # lit from under the vane: two-sided
        wi, wo = wi * [1, 1, -1], wo * [1, 1, -1]
    for model in (MODEL, INTENSITY_MODEL, PHYSICAL_MODEL):
        f = model.brdf(wi, wo, lam, cls, grad, share)
        g = model.brdf(wo, wi, lam, cls, grad, share)
        assert np.isfinite(f) and f >= 0.0
        assert f == pytest.approx(g, rel=1e-9, abs=1e-12)


def test_brdf_is_zero_across_the_vane():
    f = MODEL.brdf(direction(30.0, 0.0), direction(40.0, 180.0) * [1, 1, -1], 550.0, 2, 0.5, 0.6)
    assert f == 0.0


def test_brdf_vectorised_matches_scalar():
    rng = np.random.default_rng(1)
    wi = direction(rng.uniform(0, 89, 64), rng.uniform(0, 360, 64))
    wo = direction(rng.uniform(0, 89, 64), rng.uniform(0, 360, 64))
    lam = rng.uniform(380, 780, 64)
    batch = MODEL.brdf(wi, wo, lam, 3, 0.25)
    single = [MODEL.brdf(wi[i], wo[i], lam[i], 3, 0.25) for i in range(64)]
    np.testing.assert_allclose(batch, single, rtol=1e-12)


@pytest.mark.parametrize("ocellar_class", range(6))
@pytest.mark.parametrize("incidence", [0.0, 30.0, 60.0, 85.0])
def test_directional_albedo_at_most_one(ocellar_class, incidence):
    wavelengths = np.arange(380.0, 781.0, 10.0)
    for gradation in (0.0, 1.0):
        for params in MODES.values():
            albedo = optics.directional_albedo(
                params,
                incidence,
                ocellar_class=ocellar_class,
                gradation=gradation,
                wavelengths_nm=wavelengths,
                n_slopes=64,
            )
            assert np.all(albedo <= 1.0) and np.all(albedo >= 0.0)


def test_albedo_quadrature_agrees_with_brute_force():
    """Slope-space quadrature vs plain (θ, φ) quadrature of the same BRDF, at one wavelength."""
    params = preset("blue")
    quick = optics.directional_albedo(params, 40.0, wavelengths_nm=np.array([500.0]))[0]
    theta = np.linspace(0, math.pi / 2, 721)[1:]
    phi = np.linspace(0, 2 * math.pi, 1441)[:-1]
    tt, pp = np.meshgrid(theta, phi, indexing="ij")
    wo = np.stack([np.sin(tt) * np.cos(pp), np.sin(tt) * np.sin(pp), np.cos(tt)], -1)
    f = optics.model_for(params).brdf(direction(40.0, 90.0), wo, 500.0)
    brute = np.sum(f * np.cos(tt) * np.sin(tt)) * (theta[1] - theta[0]) * (phi[1] - phi[0])
    assert quick == pytest.approx(brute, rel=0.02)


def test_melanin_share_mixes_towards_brown():
    wi, wo = direction(20.0, 90.0), direction(60.0, 0.0)
    lam = np.arange(400.0, 701.0, 50.0)
    brown = MODEL.brdf(wi, wo, lam, 0, 0.0, 0.0)
    np.testing.assert_allclose(
        brown * math.pi, optics.model_for(TABLE1).brdf(wi, wo, lam, 3, 1.0, 0.0) * math.pi
    )
    assert brown[-1] > brown[0]  # melanin brown reflects more red than blue
