"""The physical mode against exact optics: RCWA of the rod lattice, the ``tmm`` package, closed forms."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from pavonine.materials import dispersion, optics, rcwa
from pavonine.materials.lattice import GeometryError, RodLattice
from pavonine.materials.parameters import ParameterError, preset
from pavonine.materials.stack import lattice_reflectance_emt, uniaxial_stack_reflectance

#: Issue 9's reference stacks: (interval d, radius a in nm, layers N).
STACKS = {"yellow": (190.0, 70.0, 4), "blue": (150.0, 65.0, 10), "class5": (110.0, 60.0, 16)}
LAM = np.arange(330.0, 881.0, 3.0)


def _indices(which: str):
    """(rod, medium) for stack_reflectance and (rod, matrix) arrays for the RCWA."""
    if which == "paper":
        return (2.0, 1.0), (2.0, 1.0)
    return (None, None), (dispersion.MELANIN.index(LAM), dispersion.KERATIN.real(LAM))


def _band(values: np.ndarray) -> tuple[float, float, float | None]:
    peak, width = optics.peak_and_width(LAM, values)
    return peak, float(values.max()), width


@pytest.mark.slow
@pytest.mark.parametrize("which", ["paper", "literature"])
@pytest.mark.parametrize("name", list(STACKS))
def test_physical_mode_matches_rcwa_of_the_rod_lattice(name, which):
    """Acceptance: peak wavelength within 10 nm, peak reflectance within 15 %, the blue stack's
    bandwidth within 20 % of the rigorous solution, at normal incidence."""
    d, a, n = STACKS[name]
    (n_rod, n_med), (rod_index, matrix) = _indices(which)
    physical = optics.stack_reflectance(LAM, d, a, n, n_rod=n_rod, n_medium=n_med)
    exact = rcwa.lattice_reflectance(
        RodLattice(d, a, n), LAM, n_rod=rod_index, n_matrix=matrix, harmonics=8
    )
    (p_peak, p_max, p_width), (e_peak, e_max, e_width) = _band(physical), _band(exact)
    assert abs(p_peak - e_peak) <= 10.0, (p_peak, e_peak)
    assert abs(p_max / e_max - 1.0) <= 0.15, (p_max, e_max)
    if name == "blue":
        assert abs(p_width / e_width - 1.0) <= 0.20, (p_width, e_width)
    paper = optics.stack_reflectance(LAM, d, a, n, n_rod=n_rod, n_medium=n_med, mode="paper")
    assert paper.max() < 0.6 * e_max  # the finding: the paper mode is far too dim


@pytest.mark.slow
@pytest.mark.parametrize("name", list(STACKS))
def test_angle_shift_matches_rcwa(name):
    """Acceptance: the peak's shift from 0 to 42.5° of incidence (in the medium above the stack)
    is within 20 % of the exact value for the same structure (paper indices)."""
    d, a, n = STACKS[name]
    lattice = RodLattice(d, a, n)
    shifts = {}
    for method in ("physical", "rcwa"):
        peaks = []
        for theta in (0.0, math.radians(42.5)):
            if method == "physical":
                r = optics.stack_reflectance(
                    LAM, d, a, n, n_rod=2.0, n_medium=1.0, cos_theta=math.cos(theta)
                )
            else:
                r = rcwa.lattice_reflectance(
                    lattice, LAM, n_rod=2.0, n_matrix=1.0, incidence_rad=theta, harmonics=8
                )
            peaks.append(optics.peak_and_width(LAM, r)[0])
        shifts[method] = peaks[0] - peaks[1]
    assert shifts["physical"] > 0
    assert abs(shifts["physical"] / shifts["rcwa"] - 1.0) <= 0.20, shifts


def test_peak_reflectance_rises_with_layer_count_and_saturates():
    lam = np.arange(330.0, 1101.0, 2.0)
    peaks = [
        optics.stack_reflectance(lam, 190.0, 70.0, n, n_rod=2.0, n_medium=1.0).max()
        for n in (1, 2, 4, 8, 16)
    ]
    assert all(b > a for a, b in itertools.pairwise(peaks)), peaks
    assert peaks[-1] > 0.99 and peaks[-1] - peaks[-2] < 0.01  # saturated
    # The paper mode's array factor is 1 at the peak: brightness does not grow (issue 9).
    paper = [
        optics.stack_reflectance(lam, 190.0, 70.0, n, n_rod=2.0, n_medium=1.0, mode="paper").max()
        for n in (2, 16)
    ]
    assert paper[1] <= paper[0]


def test_one_harmonic_rcwa_is_the_effective_medium_transfer_matrix():
    """With a single Fourier harmonic RCWA reduces to the zeroth-order (lamellar) effective medium
    (Li's rule for TM): the two independent codes must then agree to rounding, absorption, air
    channels, cortex and oblique incidence included."""
    lattice = RodLattice(160.0, 55.0, 5, spacing=170.0, lattice="rectangular", channel=33.0)
    lattice = RodLattice(**{**lattice.__dict__, "cortex": 100.0})
    lam = np.linspace(380.0, 780.0, 41)
    rod, matrix = dispersion.MELANIN.index(lam), dispersion.KERATIN.real(lam)
    for pol in ("TE", "TM"):
        for theta in (0.0, 0.5):
            emt = lattice_reflectance_emt(
                lattice,
                lam,
                n_rod=rod,
                n_matrix=matrix,
                n_above=1.0,
                sin_above=math.sin(theta),
                polarisation=pol,
                tm_rule="lamellar",
            )
            exact0 = rcwa.lattice_reflectance(
                lattice,
                lam,
                n_rod=rod,
                n_matrix=matrix,
                n_above=1.0,
                incidence_rad=theta,
                polarisation=pol,
                harmonics=0,
            )
            np.testing.assert_allclose(emt, exact0, rtol=1e-8, atol=1e-10)


def test_uniaxial_solver_matches_the_tmm_package():
    """The characteristic-matrix solver against Byrnes' ``tmm`` (isotropic, absorbing, oblique)."""
    tmm = pytest.importorskip("tmm")
    indices = [1.55, 1.74 + 0.09j, 1.55, 1.74 + 0.09j, 1.0]
    thicknesses = [120.0, 70.0, 90.0, 70.0, 40.0]
    slabs = [(n * n, n * n, t) for n, t in zip(indices, thicknesses, strict=True)]
    for pol, tmm_pol in (("TE", "s"), ("TM", "p")):
        for theta in (0.0, 0.4, 1.1):
            for lam in (420.0, 550.0, 700.0):
                ours = uniaxial_stack_reflectance(
                    slabs,
                    np.array([lam]),
                    n_above=1.0,
                    n_below=1.55,
                    sin_above=math.sin(theta),
                    polarisation=pol,
                )[0]
                ref = tmm.coh_tmm(
                    tmm_pol, [1.0, *indices, 1.55], [np.inf, *thicknesses, np.inf], theta, lam
                )
                assert ours == pytest.approx(ref["R"], rel=1e-9, abs=1e-12)


@pytest.mark.parametrize("pairs", [1, 4, 10])
def test_quarter_wave_stack_peak_is_the_closed_form(pairs):
    """Born & Wolf §1.6.5: N quarter-wave pairs (H L)^N between media n0 and ns reflect
    ``((1 − Y)/(1 + Y))²`` at the design wavelength, ``Y = (ns/n0) (nL/nH)^{2N}``."""
    n_h, n_l, n0, ns, lam0 = 2.0, 1.5, 1.0, 1.5, 550.0
    slabs = [(n_h**2, n_h**2, lam0 / (4 * n_h)), (n_l**2, n_l**2, lam0 / (4 * n_l))] * pairs
    got = uniaxial_stack_reflectance(slabs, np.array([lam0]), n_above=n0, n_below=ns)[0]
    y = (ns / n0) * (n_h / n_l) ** (2 * pairs)
    assert got == pytest.approx(((1 - y) / (1 + y)) ** 2, rel=1e-10)


def test_rcwa_without_rods_is_fresnel():
    """Vanishing rods under a cortex: RCWA's half-space matrices and TE/TM normalisation give the
    bare air–keratin interface (Fresnel) at oblique incidence."""
    lattice = RodLattice(150.0, 1e-4, 1, cortex=250.0)
    lam = np.array([450.0, 600.0])
    for pol in ("TE", "TM"):
        got = rcwa.lattice_reflectance(
            lattice,
            lam,
            n_rod=2.0,
            n_matrix=1.5,
            n_above=1.0,
            incidence_rad=0.6,
            polarisation=pol,
            harmonics=2,
        )
        ti, tt = 0.6, math.asin(math.sin(0.6) / 1.5)
        if pol == "TE":
            r = (math.cos(ti) - 1.5 * math.cos(tt)) / (math.cos(ti) + 1.5 * math.cos(tt))
        else:
            r = (1.5 * math.cos(ti) - math.cos(tt)) / (1.5 * math.cos(ti) + math.cos(tt))
        np.testing.assert_allclose(got, r * r, rtol=1e-4)


@pytest.mark.slow
def test_rcwa_has_converged_at_the_harmonics_used():
    """The harmonics and staircase slices of the acceptance tests are converged for what they
    measure: doubling both moves the blue stack's peak by < 2 nm, its peak reflectance by < 1 %
    and its bandwidth by < 5 % (paper indices: the highest contrast, the slowest case)."""
    lam = np.arange(420.0, 621.0, 2.5)
    lattice = RodLattice(150.0, 65.0, 10)
    bands = []
    for harmonics, slices in ((8, 16), (14, 32)):
        r = rcwa.lattice_reflectance(
            lattice, lam, n_rod=2.0, n_matrix=1.0, harmonics=harmonics, per_diameter=slices
        )
        bands.append((*optics.peak_and_width(lam, r), r.max()))
    (p1, w1, m1), (p2, w2, m2) = bands
    assert abs(p1 - p2) < 2.0 and abs(m1 / m2 - 1) < 0.01 and abs(w1 / w2 - 1) < 0.05, bands


@pytest.mark.slow
def test_rcwa_agrees_with_grcwa():
    """The project's RCWA against an independent implementation (grcwa, dev extra)."""
    pytest.importorskip("grcwa")
    cases = [
        (RodLattice(150.0, 65.0, 10), 520.0, 2.0, 1.0),
        (RodLattice(190.0, 70.0, 4), 640.0, 2.0, 1.0),
        (RodLattice(150.0, 65.0, 10), 600.0, 1.74 + 0.1j, 1.56),
    ]
    for lattice, lam, n_rod, n_matrix in cases:
        ours = rcwa.lattice_reflectance(
            lattice, np.array([lam]), n_rod=n_rod, n_matrix=n_matrix, harmonics=10
        )[0]
        theirs = rcwa.grcwa_reflectance(lattice, lam, n_rod=n_rod, n_matrix=n_matrix)
        assert ours == pytest.approx(theirs, rel=0.05, abs=0.005), (lattice, lam)


def test_dispersive_defaults_are_melanin_in_keratin():
    lam = np.array([450.0, 550.0, 650.0])
    default = optics.stack_reflectance(lam, 150.0, 65.0, 10)
    explicit = optics.stack_reflectance(
        lam,
        150.0,
        65.0,
        10,
        n_rod=dispersion.MELANIN.index(lam),
        n_medium=dispersion.KERATIN.real(lam),
    )
    np.testing.assert_allclose(default, explicit)
    assert dispersion.MELANIN.index(500.0) == pytest.approx(
        1.648 + 23700 / 500**2 + 0.56j * math.exp(-500 / 270)
    )
    assert dispersion.KERATIN.index(500.0).real == pytest.approx(1.532 + 5890 / 500**2)


def test_staggered_rods_need_sqrt3_a():
    RodLattice(110.0, 60.0, 16).check()  # class 5 black end: 110 >= 103.9
    with pytest.raises(GeometryError, match="sqrt\\(3\\)"):
        RodLattice(110.0, 65.0, 16).check()  # Table 1 class 4 short axis: 110 < 112.6
    with pytest.raises(GeometryError):
        RodLattice(150.0, 80.0, 4, lattice="rectangular", spacing=170.0).check()  # d < 2a


def test_paper_table1_warns_and_physical_mode_refuses_class4_short():
    params = preset("paper-table1").validate()
    assert [(k, axis) for k, axis, _ in params.geometry_warnings()] == [(4, "short")]
    with pytest.raises(ParameterError) as info:
        params.with_(interference="physical").validate()
    assert info.value.field.startswith("class[4].short")
    # Class 5 is no longer clamped to a contrast-free stack (fill factor 1).
    white = params.classes[5].long[1]
    assert white.radius == pytest.approx(0.11 / math.sqrt(3.0), rel=1e-6)
    assert optics.fill_factor(white.interval, white.radius) < 0.95


def test_freyer2020_preset_is_physical_and_every_class_fits():
    params = preset("freyer2020").validate()
    assert params.interference == "physical" and params.lattice == "rectangular"
    heart = params.classes[5].at(0.5)[0]  # the measured region sits at the map's middle
    assert (heart.interval, heart.spacing, heart.radius * 2, heart.channel, heart.count) == (
        pytest.approx(0.140),
        pytest.approx(0.150),
        pytest.approx(0.100),
        pytest.approx(0.033),
        10,
    )
    assert params.classes[5].cortex_at(0.5) == pytest.approx(0.100)
