"""Discrete barbule blocks (``glitter``): the BSDF's sampling (χ²), reciprocity, its agreement
with the NumPy model, and the average over blocks being the smooth BRDF."""

import math

import numpy as np
import pytest

from pavonine.base.backend import select_variant
from pavonine.materials import barbule, glitter, optics
from pavonine.materials.arraymath import NUMPY
from pavonine.materials.brdf import direction
from pavonine.materials.parameters import ParameterError, preset

pytest.importorskip("mitsuba")  # conftest says why when it cannot load
pytestmark = pytest.mark.llvm  # vectorised calls: Mitsuba's llvm variant
select_variant()
dr = pytest.importorskip("drjit")
mi = pytest.importorskip("mitsuba")
feather_bsdf = pytest.importorskip("pavonine.render.feather_bsdf")
PLUGIN_NAME, feather_bsdf_dict = feather_bsdf.PLUGIN_NAME, feather_bsdf.feather_bsdf_dict
feather_bsdf.register()
TABLE1 = preset("paper-table1")
FREYER = preset("freyer2020")


def _plugin_dict(params, ocellar_class=3, gradation=0.5, angle=0.2, share=0.7):
    """test_feather_bsdf's BSDF dict with uniform inputs, at this file's defaults."""
    from test_feather_bsdf import _plugin_dict as uniform_inputs

    return uniform_inputs(ocellar_class, gradation, angle, share, params=params)


def _sheet(wi, wavelengths, uv, unit_um=1.0e4):
    """Interactions on a flat sheet (z up, u along x, v along y, 1 scene unit = ``unit_um``)."""
    n = wi.shape[0]
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.wi = mi.Vector3f(*wi.T)
    si.wavelengths = mi.Spectrum(*[mi.Float(wavelengths[:, k]) for k in range(4)])
    si.uv = mi.Point2f(*uv.T)
    si.dp_du = mi.Vector3f(1.0, 0.0, 0.0)
    si.dp_dv = mi.Vector3f(0.0, 1.0, 0.0)
    si.sh_frame = mi.Frame3f(mi.Vector3f(0.0, 0.0, 1.0))
    return si


def _directions(rng, n):
    w = rng.normal(size=(n, 3))
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    w[:, 2] = np.abs(w[:, 2])
    return w


@pytest.mark.parametrize("mode", ["paper", "physical"])
@pytest.mark.parametrize(("incidence", "seed"), [(0.0, 2), (40.0, 1), (40.0, 2), (75.0, 5)])
def test_sampling_passes_chi2_with_glitter(incidence, seed, mode):
    """Mitsuba's χ² test of ``sample`` against ``pdf`` on one block (the adapter's interaction
    sits at uv 0), its tilt set by the seed: 1, 2, 5 give offsets of -0.36σ, 1.3σ, -1.2σ."""
    from mitsuba.chi2 import BSDFAdapter, ChiSquareTest, SphericalDomain

    params = (FREYER if mode == "physical" else TABLE1).with_(glitter=1.0, glitter_seed=seed)
    wi = [float(v) for v in direction(incidence, 30.0)]
    sample, pdf = BSDFAdapter(PLUGIN_NAME, _plugin_dict(params), wi=wi)
    test = ChiSquareTest(
        domain=SphericalDomain(),
        sample_func=sample,
        pdf_func=pdf,
        sample_dim=3,
        sample_count=200_000,
        ires=16,  # a block's grains are ~1° wide along the barbule: integrate the pdf finely
    )
    assert test.run(), test.messages


def _frame_sheet(wi, lam, uv):
    si = _sheet(wi, lam, uv)
    si.sh_frame = mi.Frame3f(
        mi.Vector3f(1.0, 0.0, 0.0), mi.Vector3f(0.0, 1.0, 0.0), mi.Vector3f(0.0, 0.0, 1.0)
    )
    return si


def _expected_block(params, uv, angle, unit_um=1.0e4):
    """The block the renderer should find, from the NumPy side of the same functions."""
    along, across, step = glitter.sheet_coordinates(uv[:, 0] * unit_um, uv[:, 1] * unit_um, angle)
    barbule_index, block_index = glitter.block_cell(
        along, across, params.block_length_um, params.barbule_width_um
    )
    seed = glitter.lowbias32(params.glitter_seed ^ ((step * 0x9E3779B1) & glitter.MASK32))
    grains = glitter.grain_count(params.block_length_um, params.rod_length_um)
    return glitter.block_state(
        params.glitter,
        math.radians(params.block_sigma_deg),
        barbule_index,
        block_index,
        seed,
        grains,
    )


@pytest.mark.parametrize("params", [TABLE1, FREYER], ids=["paper", "physical"])
def test_plugin_eval_with_glitter_equals_analysis_model(params):
    """The renderer's blocks are the NumPy model's: same cell, same hash, same shifted lobe
    (4 000 random points of a 1 mm patch, about 2 000 blocks)."""
    params = params.with_(glitter=1.0, glitter_seed=11)
    rng = np.random.default_rng(3)
    n = 4000
    wi, wo = _directions(rng, n), _directions(rng, n)
    lam = rng.uniform(380.0, 780.0, size=(n, 4))
    uv = rng.uniform(0.0, 0.01, size=(n, 2))  # 1 mm at 1 cm per unit
    angle = 0.2
    bsdf = mi.load_dict(_plugin_dict(params, 3, 0.5, angle, 0.8))
    value = np.array(bsdf.eval(mi.BSDFContext(), _frame_sheet(wi, lam, uv), mi.Vector3f(*wo.T)))
    block = _expected_block(params, uv, angle * math.pi)
    assert np.std(block.tilt) > 0.1  # the blocks really differ (σ_block = 8°: tan = 0.14)
    assert len(block.grains) == 5  # 25 µm blocks of 5 µm rods
    c, s = math.cos(angle * math.pi), math.sin(angle * math.pi)
    rot = np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]])
    model = optics.model_for(params)
    expected = np.stack(
        [
            model.brdf(wi @ rot.T, wo @ rot.T, lam[:, k], 3, 0.5, 0.8, block=block) * wo[:, 2]
            for k in range(4)
        ]
    )
    close = np.all(np.isclose(value, expected, rtol=3e-3, atol=3e-5), axis=0)
    # float32 (renderer) and float64 (NumPy) may put a point a hair from a block edge in
    # different blocks: a handful of lanes at most.
    assert close.mean() > 0.995, np.flatnonzero(~close)[:10]


def test_plugin_with_glitter_is_reciprocal_and_its_weights_are_eval_over_pdf():
    params = TABLE1.with_(glitter=1.0, glitter_seed=4)
    rng = np.random.default_rng(8)
    n = 3000
    wi, wo = _directions(rng, n), _directions(rng, n)
    lam = np.tile([450.0, 520.0, 600.0, 680.0], (n, 1))
    uv = rng.uniform(0.0, 0.02, size=(n, 2))
    bsdf = mi.load_dict(_plugin_dict(params))
    ctx = mi.BSDFContext()
    f_io = np.array(bsdf.eval(ctx, _sheet(wi, lam, uv), mi.Vector3f(*wo.T))) / wo[:, 2]
    f_oi = np.array(bsdf.eval(ctx, _sheet(wo, lam, uv), mi.Vector3f(*wi.T))) / wi[:, 2]
    np.testing.assert_allclose(f_io, f_oi, rtol=1e-3, atol=1e-6)
    assert np.ptp(f_io[0]) > 0

    si = _sheet(wi, lam, uv)
    bs, weight = bsdf.sample(ctx, si, mi.Float(rng.random(n)), mi.Point2f(*rng.random((2, n))))
    value, pdf = bsdf.eval_pdf(ctx, si, bs.wo)
    ok = np.array(bs.pdf) > 1e-3
    assert ok.mean() > 0.8
    np.testing.assert_allclose(np.array(bs.pdf)[ok], np.array(pdf)[ok], rtol=1e-3)
    expected = np.array(value)[:, ok] / np.array(pdf)[ok]
    np.testing.assert_allclose(np.array(weight)[:, ok], expected, rtol=2e-3, atol=1e-5)


def test_glitter_zero_is_the_smooth_plugin():
    """``glitter`` 0 takes the smooth path: eval, pdf and samples equal the plain material's
    whatever the seed and the uv."""
    rng = np.random.default_rng(2)
    n = 2000
    wi, wo = _directions(rng, n), _directions(rng, n)
    lam = rng.uniform(380.0, 780.0, size=(n, 4))
    uv = rng.uniform(0.0, 0.05, size=(n, 2))
    ctx = mi.BSDFContext()
    plain = mi.load_dict(_plugin_dict(TABLE1))
    seeded = mi.load_dict(_plugin_dict(TABLE1.with_(glitter_seed=99, block_length_um=21.0)))
    s1, s2 = mi.Float(rng.random(n)), mi.Point2f(*rng.random((2, n)))
    for bsdf_a, bsdf_b in ((plain, seeded),):
        si = _sheet(wi, lam, uv)
        a = [np.array(v) for v in bsdf_a.eval_pdf(ctx, si, mi.Vector3f(*wo.T))]
        b = [np.array(v) for v in bsdf_b.eval_pdf(ctx, si, mi.Vector3f(*wo.T))]
        for x, y in zip(a, b, strict=True):
            assert np.array_equal(x, y)
        (bs_a, w_a), (bs_b, w_b) = bsdf_a.sample(ctx, si, s1, s2), bsdf_b.sample(ctx, si, s1, s2)
        assert np.array_equal(np.array(bs_a.wo), np.array(bs_b.wo))
        assert np.array_equal(np.array(w_a), np.array(w_b))


def test_the_average_over_blocks_is_the_smooth_brdf():
    """A Gaussian of block tilts and of speckle-grain places convolved with a grain's lobe is the
    smooth lobe: the BRDF averaged over the offset ``z √(tilt² + speckle²(λ))`` (a fine
    quadrature in the deviate) equals glitter 0's for g = 1 and g = 0.5, at every wavelength;
    a block's grain shares sum to 1 and average 1/M; the hashed deviates are standard normal."""
    rng = np.random.default_rng(1)
    n = 500
    wi, wo = _directions(rng, n), _directions(rng, n)
    lam = rng.uniform(380.0, 780.0, size=n)
    smooth = optics.model_for(TABLE1).structural(wi, wo, lam, 2, 0.5)
    nodes = np.linspace(-9.0, 9.0, 3601)
    weights = np.exp(-0.5 * nodes**2)
    weights = weights / weights.sum()
    block_sigma = math.radians(TABLE1.block_sigma_deg)
    along = barbule.along_sigma(block_sigma, TABLE1.rod_length_um * 1e3, lam)
    envelope = barbule.diffraction_sigma(TABLE1.rod_length_um * 1e3, lam)
    grain = barbule.diffraction_sigma(TABLE1.block_length_um * 1e3, lam)
    zero = (np.zeros(n),)
    for g in (1.0, 0.5):
        model = optics.model_for(TABLE1.with_(glitter=g))
        speckle, within = glitter.speckle_split(g, block_sigma, along, envelope, grain)
        if g == 1.0:  # a grain is a few times narrower than the old block lobe (rod ends)
            assert np.all(within < 0.3 * np.tan(envelope)), np.max(within / np.tan(envelope))
        spread = np.hypot(math.sqrt(g) * math.tan(block_sigma), speckle)
        mean = sum(
            w * model.structural(wi, wo, lam, 2, 0.5, block=glitter.Block(spread * z, zero, (1.0,)))
            for z, w in zip(nodes, weights, strict=True)
        )
        np.testing.assert_allclose(mean, smooth, rtol=1e-5, atol=1e-9)
    blocks = np.arange(100_000, dtype=np.uint64)
    state = glitter.block_state(1.0, block_sigma, blocks // 317, blocks % 317, 12345, 5)
    np.testing.assert_allclose(sum(state.weights), 1.0, rtol=1e-12)
    assert all(abs(w.mean() - 0.2) < 0.005 for w in state.weights)
    from scipy import stats

    for z in (glitter.block_normal(blocks // 317, blocks % 317, 12345), *state.grains):
        assert abs(z.mean()) < 0.015 and abs(z.std() - 1.0) < 0.01
        assert stats.kstest(z, "norm").pvalue > 0.01
    assert abs(np.corrcoef(state.grains[0], state.grains[1])[0, 1]) < 0.01


def test_shifted_beckmann_is_normalised_and_centred_on_the_block():
    """``∫ D h_z dω = 1`` for a shifted lobe, and its peak normal is ``∝ (−μ, 0, 1)``."""
    theta = np.linspace(0.0, math.pi / 2, 1500)
    phi = np.linspace(0.0, 2 * math.pi, 1500)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    hx, hy, hz = np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)
    d = barbule.shifted_beckmann_ndf(hx, hy, hz, 0.08, 0.35, 0.2, NUMPY)
    integral = np.trapezoid(np.trapezoid(d * hz * np.sin(t), phi, axis=1), theta)
    assert integral == pytest.approx(1.0, abs=2e-3)
    peak = np.unravel_index(np.argmax(d * hz**4), d.shape)
    assert -hx[peak] / hz[peak] == pytest.approx(0.2, abs=2e-3)


def test_block_ndf_is_the_weighted_sum_of_its_grains_shifted_beckmann_lobes():
    """``block_ndf`` computes the factors its grains share once; it must stay ``Σ_k w_k D_k``
    with ``D_k`` the shifted Beckmann lobe of :func:`barbule.shifted_beckmann_ndf` at
    ``tilt + z_k · speckle`` (one definition of the lobe, a fast form of it)."""
    rng = np.random.default_rng(5)
    h = rng.normal(size=(2000, 3))
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    hx, hy, hz = h.T  # half of them below the vane: both forms are 0 there
    block = glitter.block_state(1.0, math.radians(8.0), 3, 7, 11, 5, NUMPY)
    speckle, alpha_x, alpha_y = 0.03, 0.012, 0.35
    fast = glitter.block_ndf(hx, hy, hz, alpha_x, alpha_y, block, speckle, NUMPY)
    reference = sum(
        w * barbule.shifted_beckmann_ndf(hx, hy, hz, alpha_x, alpha_y, block.tilt + z * speckle)
        for z, w in zip(block.grains, block.weights, strict=True)
    )
    assert np.any(reference > 1.0) and np.any(hz <= 0.0)
    np.testing.assert_allclose(fast, reference, rtol=1e-12, atol=1e-300)


def test_glitter_parameters_are_checked():
    for changes, field in (
        ({"glitter": 1.5}, "glitter"),
        ({"glitter": float("nan")}, "glitter"),
        ({"glitter_seed": -1}, "glitter_seed"),
        ({"block_length_um": 0.0}, "block_length_um"),
        ({"barbule_width_um": -3.0}, "barbule_width_um"),
    ):
        with pytest.raises(ParameterError) as info:
            TABLE1.with_(**changes).validate()
        assert info.value.field == field


def test_instances_with_their_own_seed_glint_differently():
    """``pavonine:glitterSeed`` per instance (a table by registry id, as the delegate binds it)
    changes the blocks' tilts; the neutral 0 is the material's own seed."""
    params = TABLE1.with_(glitter=1.0, glitter_seed=21)
    rng = np.random.default_rng(4)
    n = 1000
    wi, wo = _directions(rng, n), _directions(rng, n)
    lam = np.tile([450.0, 520.0, 600.0, 680.0], (n, 1))
    uv = rng.uniform(0.0, 0.02, size=(n, 2))
    bsdf = mi.load_dict(_plugin_dict(params))
    ctx = mi.BSDFContext()

    def eval_as(instance: int):
        si = _sheet(wi, lam, uv)
        si.instance = dr.reinterpret_array(mi.ShapePtr, mi.UInt32(np.full(n, instance)))
        return np.array(bsdf.eval(ctx, si, mi.Vector3f(*wo.T)))

    plain = eval_as(0)
    bsdf.set_instance_table("glitter_seed", mi.Float([0.0, 0.0, 7.0, 8.0]), 0.0)
    assert np.array_equal(eval_as(1), plain)
    seven, eight = eval_as(2), eval_as(3)
    assert not np.allclose(seven, plain, rtol=0.05) and not np.allclose(seven, eight, rtol=0.05)


def test_glitter_round_trips_through_usd_and_leaves_bakes_fresh():
    """The four attributes are written and read back; a layer without them reads glitter 0; the
    bake digest ignores them (a bake is the smooth average, the same for any glitter)."""
    from pxr import Usd, UsdShade

    from pavonine.schemas import authoring

    params = TABLE1.with_(glitter=0.75, glitter_seed=9, block_length_um=22.0, barbule_width_um=18.0)
    stage = Usd.Stage.CreateInMemory()
    material = UsdShade.Material.Define(stage, "/M")
    authoring.author_parameters(material.GetPrim(), params)
    back = authoring.read_feather_parameters(material)
    assert (back.glitter, back.glitter_seed, back.block_length_um, back.barbule_width_um) == (
        0.75,
        9,
        22.0,
        18.0,
    )
    for name, _ in authoring.GLITTER_ATTRS.values():
        material.GetPrim().RemoveProperty(name)
    assert authoring.read_feather_parameters(material).glitter == 0.0
    assert authoring.parameters_digest(params) == authoring.parameters_digest(TABLE1)
    assert authoring.parameters_digest(TABLE1.with_(block_sigma_deg=9.0)) != (
        authoring.parameters_digest(TABLE1)
    )
