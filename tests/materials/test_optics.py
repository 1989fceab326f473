"""Eq. 1–7 and Table 1 against the paper's numbers, closed forms and independent methods."""

import math

import numpy as np
import pytest

from pavonine.materials import barbule, layers, optics, rod
from pavonine.materials.parameters import ParameterError, preset, uniform_parameters


# Eq. 1 ------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("d", "a", "expected"), [(190, 70, 300.0), (150, 65, 252.1)])
def test_optical_distance_matches_paper(d, a, expected):
    assert round(optics.optical_distance(d, a), 1) == expected


def test_optical_distance_limits():
    # No rods → plain medium; a fully filled layer (f = 1) → melanin only.
    assert optics.optical_distance(100.0, 0.0, 2.0, 1.0) == pytest.approx(100.0)
    assert optics.optical_distance(math.pi / 2 * 50.0, 50.0, 2.0, 1.0) == pytest.approx(
        math.pi * 50.0
    )


# Eq. 2 ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("x", [0.05, 0.4, 0.9, 1.7, 4.0, 12.0])
@pytest.mark.parametrize("m", [1.33, 1.6, 2.0])
def test_cylinder_lossless_scattering_equals_extinction(x, m):
    a, b = optics.cylinder_coefficients(x, m, rod.n_max_for(x))
    for coefficients in (a, b):
        q_sca, q_ext = rod.efficiencies(x, coefficients)
        assert q_sca == pytest.approx(q_ext, rel=1e-9, abs=1e-14)


def test_absorbing_cylinder_extinguishes_more_than_it_scatters():
    # Literature melanin at 500 nm: n ≈ 1.743 + 0.088 i (MODEL-NOTES, "Literature figures").
    a, b = optics.cylinder_coefficients(0.8, 1.743 + 0.088j, 12)
    for coefficients in (a, b):
        q_sca, q_ext = rod.efficiencies(0.8, coefficients)
        assert q_ext > q_sca > 0


@pytest.mark.parametrize("x", [0.1, 0.9, 3.0])
def test_cylinder_te0_equals_tm1(x):
    a, b = optics.cylinder_coefficients(x, 2.0, 10)
    assert a[0] == pytest.approx(b[1], rel=1e-12)


def test_cylinder_small_size_limit():
    # Bohren & Huffman §8.4 / van de Hulst §15: b0 ≈ −iπx²(m²−1)/4, a1 ≈ −iπx²(m²−1)/(4(m²+1)).
    x, m = 1e-3, 2.0
    a, b = optics.cylinder_coefficients(x, m, 3)
    assert b[0] == pytest.approx(-1j * math.pi * x**2 * (m * m - 1) / 4, rel=1e-4)
    assert a[1] == pytest.approx(-1j * math.pi * x**2 * (m * m - 1) / (4 * (m * m + 1)), rel=1e-4)
    q_tm, _ = rod.efficiencies(x, b)
    assert q_tm == pytest.approx(math.pi**2 * x**3 * (m * m - 1) ** 2 / 8, rel=1e-4)


def test_cylinder_series_is_converged_at_truncation():
    x = 2.5
    a, b = optics.cylinder_coefficients(x, 2.0, rod.n_max_for(x) + 10)
    for coefficients in (a, b):
        assert np.abs(coefficients[rod.n_max_for(x) + 1 :]).max() < 1e-6


def test_cylinder_rejects_bad_size():
    with pytest.raises(ValueError, match="size parameter"):
        optics.cylinder_coefficients(-1.0, 2.0, 4)


# Eq. 3 / Fig. 7 ---------------------------------------------------------------------------------
def _fig7_half_width(n_rods: int) -> float:
    """Half-width (sin θ_out) of Fig. 7's central peak: a = 70 nm, L = 140 nm, λ = 600 nm."""
    sin_out = np.linspace(0.0, 0.999, 40001)
    single = rod.unpolarised_intensity(2 * math.pi * 70 / 600, 2.0, math.pi - np.arcsin(sin_out))
    curve = optics.rod_row_intensity(single, n_rods, 140.0, 0.0, sin_out, 600.0)
    curve = curve / curve[0]
    return float(sin_out[np.argmax(curve < 0.5)])


def test_rod_rows_narrow_as_one_over_n():
    widths = {n: _fig7_half_width(n) for n in (5, 10, 20, 40)}
    products = np.array([n * w for n, w in widths.items()])
    assert products.std() / products.mean() < 0.05
    assert widths[40] < widths[20] < widths[10] < widths[5]


def test_single_rod_row_is_the_cylinder_pattern():
    theta = np.linspace(0, 1.2, 7)
    single = rod.unpolarised_intensity(0.73, 2.0, math.pi - theta)
    assert np.allclose(
        optics.rod_row_intensity(single, 1, 140.0, 0.0, np.sin(theta), 600.0), single
    )


# Eq. 4 ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("mode", ["paper", "intensity"])
@pytest.mark.parametrize("n", [2, 4, 10, 16])
def test_stack_peaks_where_phase_is_multiple_of_two_pi(mode, n):
    for k in range(4):
        assert layers.array_factor(2 * math.pi * k, n, mode) == pytest.approx(1.0, abs=1e-9)
    delta = np.linspace(0.3, 2 * math.pi - 0.3, 999)
    assert np.all(layers.array_factor(delta, n, mode) < 1.0)


def test_paper_and_intensity_modes_share_peaks_and_differ_in_width():
    delta = np.linspace(-1, 1, 2001)
    paper = layers.array_factor(delta, 8, "paper")
    intensity = layers.array_factor(delta, 8, "intensity")
    assert delta[np.argmax(paper)] == delta[np.argmax(intensity)] == pytest.approx(0.0, abs=1e-3)
    assert np.count_nonzero(paper > 0.5) > np.count_nonzero(intensity > 0.5)
    np.testing.assert_allclose(intensity, paper**2, atol=1e-12)


def test_array_factor_matches_explicit_sum():
    delta = np.linspace(0.01, 6.0, 50)
    for n in (1, 3, 7):
        explicit = np.abs(np.exp(1j * np.outer(delta, np.arange(n))).sum(axis=1)) / n
        np.testing.assert_allclose(layers.array_factor(delta, n), explicit, atol=1e-6)


def test_non_integer_layer_count_interpolates_and_stays_bounded():
    delta = np.linspace(0.0, 20.0, 4001)
    af = layers.array_factor(delta, 4.5)
    assert np.all((af >= 0) & (af <= 1.0 + 1e-12))
    np.testing.assert_allclose(
        af, 0.5 * (layers.array_factor(delta, 4) + layers.array_factor(delta, 5)), atol=1e-12
    )


# Eq. 5 ------------------------------------------------------------------------------------------
def test_rod_gradient_weight_defined_everywhere():
    grid = np.linspace(-math.pi / 2, math.pi / 2, 41)
    phi, t_in, t_out = np.meshgrid(grid, grid, grid, indexing="ij")
    w = optics.rod_gradient_weight(phi, t_in, t_out)
    assert np.all(np.isfinite(w)) and np.all(w >= 0) and np.all(w <= 1)
    assert optics.rod_gradient_weight(0.0, 0.3, 0.0) == 0.0
    # Closed form at one point: φ = 0, tan θ_in / tan θ_out = −1 → √((1+1)/2) = 1.
    assert optics.rod_gradient_weight(0.0, -0.4, 0.4) == pytest.approx(1.0)


# Eq. 6 / Fig. 10 --------------------------------------------------------------------------------
@pytest.mark.parametrize("incidence_deg", [0, 20, 45, 70, 89])
def test_crescent_density_integrates_to_one(incidence_deg):
    theta = np.linspace(-math.pi / 2, math.pi / 2, 20001)
    density = optics.crescent_density(theta, math.radians(incidence_deg))
    assert np.trapezoid(density, theta) == pytest.approx(1.0, abs=1e-4)
    assert np.all(density >= 0)


def test_crescent_density_leans_towards_the_light():
    theta = np.linspace(-math.pi / 2, math.pi / 2, 2001)
    mean = [
        np.trapezoid(theta * optics.crescent_density(theta, math.radians(i)), theta)
        for i in (0, 30, 60)
    ]
    assert mean[0] == pytest.approx(0.0, abs=1e-6) and 0 < mean[1] < mean[2]


@pytest.mark.llvm
def test_crescent_density_is_beckmann_visible_normals_in_plane():
    """Eq. 6 vs an independent method: visible-normal sampling of the renderer's distribution."""
    from pavonine.base.backend import select_variant

    select_variant()
    import mitsuba as mi

    sigma = math.radians(15.0)
    incidence = math.radians(40.0)
    distr = mi.MicrofacetDistribution(
        mi.MicrofacetType.Beckmann, 1e-4, float(barbule.beckmann_alpha(sigma)), True
    )
    n = 200_000
    rng = np.random.default_rng(3)
    wi = mi.Vector3f(0.0, math.sin(incidence), math.cos(incidence))
    m, _ = distr.sample(wi, mi.Point2f(rng.random(n), rng.random(n)))
    tilt = np.arctan2(np.array(m.y), np.array(m.z))
    hist, edges = np.histogram(tilt, bins=40, range=(-1.0, 1.0), density=True)
    centres = 0.5 * (edges[1:] + edges[:-1])
    # Beckmann is Gaussian in slope (tan θ), Eq. 6 in angle: compare in angle via the Jacobian.
    expected = optics.crescent_density(centres, incidence, sigma)
    assert np.abs(hist - expected).max() < 0.08 * expected.max()


# Eq. 7 ------------------------------------------------------------------------------------------
def test_orientation_blend_fixes_the_misprint():
    assert optics.orientation_blend(0.3, 0.3, 0.7) == pytest.approx(0.3)  # printed form gives 0
    assert optics.orientation_blend(0.8, 0.1, 1.0) == pytest.approx(0.8)  # ψ = 0 → long axis
    assert optics.orientation_blend(0.8, 0.1, 0.0) == pytest.approx(0.1)  # ψ = 90° → short axis


# Table 1 and bad input -------------------------------------------------------------------------
def test_table1_gradation_interpolation():
    table = preset("paper-table1")
    long_black, short_black = table.stacks(2, 0.0)
    long_white, short_white = table.stacks(2, 1.0)
    long_mid, _ = table.stacks(2, 0.5)
    assert (long_black.interval, long_black.count) == pytest.approx((0.19, 4))
    assert (long_white.interval, long_white.count) == pytest.approx((0.17, 8))
    assert short_white.radius == pytest.approx(0.060) and short_black.radius == pytest.approx(0.065)
    assert long_mid.interval == pytest.approx(0.18) and long_mid.count == pytest.approx(6)


def test_every_table1_cell_is_physical():
    table = preset("paper-table1").validate()
    for cls in range(6):
        for t in (0.0, 0.3, 1.0):
            for stack in table.stacks(cls, t):
                assert math.pi * stack.radius <= 2 * stack.interval * (1 + 1e-6)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"interval_um": 0.15, "radius_um": -0.06, "count": 4}, "radius"),
        ({"interval_um": 0.0, "radius_um": 0.06, "count": 4}, "interval"),
        ({"interval_um": 0.15, "radius_um": 0.06, "count": 0}, "count"),
        ({"interval_um": 0.10, "radius_um": 0.07, "count": 4}, "radius"),  # π·a > 2·d
        ({"interval_um": float("nan"), "radius_um": 0.06, "count": 4}, "interval"),
    ],
)
def test_unphysical_parameters_name_the_field(kwargs, field):
    with pytest.raises(ParameterError) as info:
        uniform_parameters(**kwargs).validate()
    assert field in info.value.field


def test_unknown_class_and_preset_are_errors():
    with pytest.raises(ParameterError, match="unknown class 7"):
        preset("paper-table1").stacks(7, 0.0)
    with pytest.raises(ParameterError, match="unknown preset"):
        preset("green")
