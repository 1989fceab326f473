"""Glints from the pixel's footprint (issue 34): the counts of a cell's grains per bin have
expectation one and the variance of the blocks they stand for, the footprint's lobe averages to
the smooth lobe, and the BSDF with a footprint passes χ², reciprocity and eval/pdf."""

import math

import numpy as np
import pytest

from pavonine.base.backend import select_variant
from pavonine.materials import barbule, glitter
from pavonine.materials.brdf import MaterialConstants, direction
from pavonine.materials.parameters import preset

pytest.importorskip("mitsuba")  # conftest says why when it cannot load
pytestmark = pytest.mark.llvm  # vectorised calls: Mitsuba's llvm variant
select_variant()
dr = pytest.importorskip("drjit")
mi = pytest.importorskip("mitsuba")
feather_bsdf = pytest.importorskip("pavonine.render.feather_bsdf")
PLUGIN_NAME = feather_bsdf.PLUGIN_NAME
feather_bsdf.register()
TABLE1 = preset("paper-table1").with_(glitter=1.0, glitter_seed=3)
CONSTANTS = MaterialConstants.from_parameters(TABLE1)
LAMBDA = 550.0


def _lobe(wavelength=LAMBDA):
    """``(spread σ_μ, within s_w, total σ_t = tan σ_along, speckle)`` at ``wavelength`` (slopes)."""
    along = barbule.along_sigma(CONSTANTS.block_sigma, CONSTANTS.rod_length_nm, wavelength)
    speckle, within = glitter.grain_split(CONSTANTS, 1.0, along, wavelength)
    spread = math.hypot(math.tan(CONSTANTS.block_sigma), speckle)
    return spread, float(within), math.tan(along), float(speckle)


GRAINS = glitter.grain_count(TABLE1.block_length_um, TABLE1.rod_length_um)
SPREAD, WITHIN, TOTAL, SPECKLE = _lobe()
MODEL = glitter.count_model(SPREAD, WITHIN, SPECKLE, GRAINS)
ALPHA_Y = barbule.SQRT2 * math.tan(CONSTANTS.crescent_sigma)


def test_a_bins_count_over_its_expectation_has_mean_one_and_the_poisson_variance():
    """``count_ratio`` by quadrature over its uniform (Poisson, below the switch: a 10⁶-point
    midpoint grid) and over the exact law of its Irwin–Hall deviate (normal, from the switch
    on: every hash of 2²⁰ integers): E[X] = 1 and Var[X] = 1/mean within 2 %, never negative."""
    u = (np.arange(1_000_000) + 0.5) / 1_000_000
    for mean in (2e-3, 0.05, 0.7, 2.9, 6.0, 11.9):
        x = glitter.count_ratio(mean, u, 0.0)
        assert np.all(x >= 0.0)
        assert x.mean() == pytest.approx(1.0, abs=1e-4), mean
        assert x.var() * mean == pytest.approx(1.0, rel=0.02), mean
    z = glitter.irwin_hall(glitter.lowbias32(np.arange(2**20, dtype=np.uint64)))
    assert abs(z.mean()) < 3e-3 and z.var() == pytest.approx(1.0, abs=5e-3)
    assert z.min() >= -math.sqrt(12.0)
    for mean in (12.0, 40.0, 3000.0):
        x = glitter.count_ratio(mean, 0.5, z)
        assert np.all(x >= 0.0)
        assert x.mean() == pytest.approx(1.0, abs=1e-3), mean
        assert x.var() * mean == pytest.approx(1.0, rel=0.02), mean
    assert np.all(glitter.count_ratio(1e-6, u, 0.0) == 1.0)  # far tail: the mean


def _footprint(level, along, across, slope_x, seed=7):
    block = glitter.block_state(1.0, CONSTANTS.block_sigma, 0, 0, seed, GRAINS)
    return glitter.footprint_at(
        block,
        level,
        along,
        across,
        seed,
        slope_x,
        MODEL,
        SPREAD,
        TOTAL,
        TABLE1.block_length_um,
        TABLE1.barbule_width_um,
    )


def _half_vectors(slopes_x, slope_y=0.05):
    h = np.stack(np.broadcast_arrays(-np.asarray(slopes_x), -slope_y, 1.0), -1)
    return h / np.linalg.norm(h, axis=-1, keepdims=True)


def test_the_footprint_averages_to_the_smooth_lobe():
    """The posterior weights sum to one (all counts at their mean give the smooth lobe exactly),
    and over 200 000 cells the footprint's lobe at level 2.5 (levels 2 and 3 by block) is the smooth
    Beckmann lobe within its Monte Carlo error, from the peak to 3 σ out, at 450 and 650 nm."""
    rng = np.random.default_rng(5)
    n = 200_000
    along, across = rng.uniform(-1e6, 1e6, size=(2, n))
    for wavelength in (450.0, 650.0):
        _, within, total, speckle = _lobe(wavelength)
        alpha_x = barbule.SQRT2 * total
        for slope in (0.0, 0.1, 0.3, -0.45):
            hx, hy, hz = _half_vectors(np.full(n, slope)).T
            fp = _footprint(2.5, along, across, -hx / hz)
            smooth = barbule.beckmann_ndf(hx, hy, hz, alpha_x, ALPHA_Y)
            d = glitter.footprint_ndf(hx, hy, hz, alpha_x, ALPHA_Y, within, speckle, CONSTANTS, fp)
            assert float(fp.block_weight.max()) == 0.0
            with pytest.MonkeyPatch.context() as patch:  # every count at its mean
                patch.setattr(glitter, "count_ratio", lambda mean, u, z, ops: 1.0)
                flat = _footprint(2.5, along[:100], across[:100], -hx[:100] / hz[:100])
            assert np.allclose(flat.cells[0].gain, 1.0, rtol=1e-12, atol=0.0)
            error = d.std() / math.sqrt(n)
            assert abs(d.mean() - smooth[0]) < 4.0 * error + 1e-9 * smooth[0], (slope, wavelength)
            assert d.std() > 0.05 * smooth[0]  # the cells do differ


def _explicit_cells(level, slope, cells, seed=11):
    """Each cell's lobe summed block by block: the mean of its 4^level blocks' ``block_ndf``."""
    side = 2**level
    hx, hy, hz = _half_vectors(slope)
    total = 0.0
    for i in range(side):
        for j in range(side):
            block = glitter.block_state(
                1.0,
                CONSTANTS.block_sigma,
                (cells // 4096) * side + i,
                (cells % 4096) * side + j,
                seed,
                GRAINS,
            )
            d = glitter.block_ndf(hx, hy, hz, barbule.SQRT2 * WITHIN, ALPHA_Y, block, SPECKLE)
            total = total + d
    return total / side**2


@pytest.mark.parametrize("level", [2, 3])
def test_the_counts_vary_as_much_as_the_blocks_they_stand_for(level):
    """An independent method: the lobe of a cell of 4^level blocks summed block by block (each
    block's tilt and grains, :func:`glitter.block_state`) against the cell's counts, over 4 000
    cells each, at the lobe's peak and 1 and 2 σ out. Same mean, and the spread from cell to cell
    (what makes the sparkle) within 15 % (0.95–1.09 measured; 0.72–0.83 before a block's grains
    were counted as clustered about its tilt, :func:`glitter.count_model`): the counts are the
    few-block statistics, not noise of another size."""
    cells = np.arange(4000, dtype=np.uint64)
    for slope in (0.0, TOTAL, 2.0 * TOTAL):
        explicit = _explicit_cells(level, slope, cells)
        hx, hy, hz = _half_vectors(np.full(cells.size, slope)).T
        side = 2.0**level
        along = (cells % 4096 + 0.5).astype(float) * side * TABLE1.block_length_um
        across = (cells // 4096 + 0.5).astype(float) * side * TABLE1.barbule_width_um
        fp = _footprint(float(level), along, across, -hx / hz)
        counted = glitter.footprint_ndf(
            hx, hy, hz, barbule.SQRT2 * TOTAL, ALPHA_Y, WITHIN, SPECKLE, CONSTANTS, fp
        )
        smooth = barbule.beckmann_ndf(hx[0], hy[0], hz[0], barbule.SQRT2 * TOTAL, ALPHA_Y)
        assert explicit.mean() == pytest.approx(smooth, rel=0.06)
        assert counted.mean() == pytest.approx(smooth, rel=0.06)
        ratio = counted.std() / explicit.std()
        assert 0.85 < ratio < 1.15, (level, slope, ratio, counted.std(), explicit.std())


def test_the_level_follows_the_footprint_and_its_blocks_blend_the_two_levels():
    """``footprint_level`` is ½ log₂ of the blocks in the footprint; a block takes level k + 1
    with probability ℓ − k (over 200 000 blocks within 0.005), keeps its choice while ℓ moves
    by less than that, and is its own lobe for an unknown (zero) footprint."""
    area = TABLE1.block_length_um * TABLE1.barbule_width_um
    levels = glitter.footprint_level(np.array([0.0, area, 4 * area, 64 * area, 32 * area]), 25, 20)
    assert levels[0] < -10
    np.testing.assert_allclose(levels[1:], [0.0, 1.0, 3.0, 2.5], atol=1e-12)
    rng = np.random.default_rng(1)
    along, across = rng.uniform(-1e6, 1e6, size=(2, 200_000))

    def choice(level):
        return glitter.level_choice(level, along, across, 25.0, 20.0, 7)

    for level in (-40.0, 0.0, 0.3, 1.0, 2.75, 11.5):
        chosen, is_block = choice(level)
        k = math.floor(max(level, 0.0))
        assert set(np.unique(chosen)) <= {k, k + 1}
        assert np.mean(chosen == k + 1) == pytest.approx(max(level, 0.0) - k, abs=5e-3)
        np.testing.assert_array_equal(is_block, chosen == 0)
    a, b = choice(2.75)[0], choice(2.76)[0]
    assert 0.0 < np.mean(a != b) < 0.015  # 1 % of the blocks change level (a 0.7 % dolly)


# -- the BSDF with a footprint ----------------------------------------------------------------


def _plugin_dict(share=0.7, angle=0.2):
    from test_feather_bsdf import _plugin_dict as uniform_inputs

    return uniform_inputs(3, 0.5, angle, share, params=TABLE1)


def _duv_for(level):
    """uv partials (1 cm per scene unit, a square pixel) of a footprint at ``level``."""
    area = 4.0**level * TABLE1.block_length_um * TABLE1.barbule_width_um
    return math.sqrt(area) / feather_bsdf.WORLD_UNIT_UM


def _sheet(wi, wavelengths, uv, duv):
    n = wi.shape[0]
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.wi = mi.Vector3f(*wi.T)
    si.wavelengths = mi.Spectrum(*[mi.Float(wavelengths[:, k]) for k in range(4)])
    si.uv = mi.Point2f(*uv.T)
    si.dp_du = mi.Vector3f(1.0, 0.0, 0.0)
    si.dp_dv = mi.Vector3f(0.0, 1.0, 0.0)
    si.duv_dx = mi.Vector2f(duv, 0.0)
    si.duv_dy = mi.Vector2f(0.0, duv)
    si.sh_frame = mi.Frame3f(mi.Vector3f(0.0, 0.0, 1.0))
    return si


@pytest.mark.parametrize("level", [0.5, 2.5])
@pytest.mark.parametrize("incidence", [10.0, 55.0])
def test_sampling_with_a_footprint_passes_chi2(level, incidence):
    """Mitsuba's χ² test of ``sample`` against ``pdf`` with a pixel footprint: at level 0.5 the
    block's lobes and the smooth lobe half and half, at 2.5 the smooth lobe only."""
    from mitsuba.chi2 import ChiSquareTest, SphericalDomain

    wi = [float(v) for v in direction(incidence, 30.0)]
    bsdf = mi.load_dict(_plugin_dict())
    ctx = mi.BSDFContext()
    duv = _duv_for(level)

    def interaction(n):
        lam = np.full((n, 4), LAMBDA)
        return _sheet(np.tile(wi, (n, 1)), lam, np.full((n, 2), 0.5), duv)

    def sample(s):
        n = dr.width(s)
        bs, weight = bsdf.sample(ctx, interaction(n), s[0], mi.Vector2f(s[1], s[2]))
        w = dr.full(mi.Float, 1.0, n)
        w[dr.all(weight == 0)] = 0
        return bs.wo, w

    def pdf(wo):
        return bsdf.pdf(ctx, interaction(dr.width(wo)), wo)

    test = ChiSquareTest(
        domain=SphericalDomain(),
        sample_func=sample,
        pdf_func=pdf,
        sample_dim=3,
        sample_count=200_000,
        ires=16,
    )
    assert test.run(), test.messages


def _directions(rng, n):
    w = rng.normal(size=(n, 3))
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    w[:, 2] = np.abs(w[:, 2])
    return w


@pytest.mark.parametrize("level", [0.5, 2.5, 6.0])
def test_a_footprint_is_reciprocal_and_weights_are_eval_over_pdf(level):
    rng = np.random.default_rng(8)
    n = 3000
    wi, wo = _directions(rng, n), _directions(rng, n)
    lam = np.tile([450.0, 520.0, 600.0, 680.0], (n, 1))
    uv = rng.uniform(0.0, 0.02, size=(n, 2))
    duv = _duv_for(level)
    bsdf = mi.load_dict(_plugin_dict())
    ctx = mi.BSDFContext()
    f_io = np.array(bsdf.eval(ctx, _sheet(wi, lam, uv, duv), mi.Vector3f(*wo.T))) / wo[:, 2]
    f_oi = np.array(bsdf.eval(ctx, _sheet(wo, lam, uv, duv), mi.Vector3f(*wi.T))) / wi[:, 2]
    np.testing.assert_allclose(f_io, f_oi, rtol=1e-3, atol=1e-6)
    assert np.ptp(f_io[0]) > 0

    si = _sheet(wi, lam, uv, duv)
    bs, weight = bsdf.sample(ctx, si, mi.Float(rng.random(n)), mi.Point2f(*rng.random((2, n))))
    value, pdf = bsdf.eval_pdf(ctx, si, bs.wo)
    ok = np.array(bs.pdf) > 1e-3
    assert ok.mean() > 0.8
    np.testing.assert_allclose(np.array(bs.pdf)[ok], np.array(pdf)[ok], rtol=1e-3)
    expected = np.array(value)[:, ok] / np.array(pdf)[ok]
    np.testing.assert_allclose(np.array(weight)[:, ok], expected, rtol=2e-3, atol=1e-5)


def test_the_footprint_is_the_pixels_whatever_the_sample_count():
    """``pixel_differential`` undoes the 1/√spp Mitsuba applies to the camera ray's
    differentials: the footprint (and so the glints) is the same for 1, 16 or 64 spp and for
    any split of the samples; a ray without differentials gives none."""
    from pavonine.render.integrator import pixel_differential

    ray = mi.RayDifferential3f(mi.Ray3f(mi.Point3f(0.0, 0.0, 5.0), mi.Vector3f(0.0, 0.0, -1.0)))
    ray.o_x, ray.o_y = mi.Point3f(0.0, 0.0, 5.0), mi.Point3f(0.0, 0.0, 5.0)
    ray.d_x = dr.normalize(mi.Vector3f(0.01, 0.0, -1.0))
    ray.d_y = dr.normalize(mi.Vector3f(0.0, 0.013, -1.0))
    ray.has_differentials = True
    for spp in (1, 16, 64):
        scaled = mi.RayDifferential3f(mi.Ray3f(ray))
        scaled.o_x, scaled.o_y, scaled.d_x, scaled.d_y = ray.o_x, ray.o_y, ray.d_x, ray.d_y
        scaled.has_differentials = True
        scaled.scale_differential(1.0 / math.sqrt(spp))
        sampler = mi.load_dict({"type": "independent", "sample_count": spp})
        pixel = pixel_differential(scaled, sampler)
        for name in ("d_x", "d_y", "o_x", "o_y"):
            np.testing.assert_allclose(
                np.array(getattr(pixel, name)), np.array(getattr(ray, name)), atol=1e-6
            )
    plain = mi.RayDifferential3f(mi.Ray3f(mi.Point3f(0.0), mi.Vector3f(0.0, 0.0, 1.0)))
    assert pixel_differential(plain, sampler) is None
    assert pixel_differential(mi.Ray3f(plain), sampler) is None


def test_the_path_loops_uv_partials_are_mitsubas():
    """``uv_partials`` (written out for the symbolic path loop) gives what Mitsuba's own
    ``compute_uv_partials`` gives outside it, on a tilted, scaled rectangle."""
    from pavonine.render.integrator import uv_partials

    scene = mi.load_dict(
        {
            "type": "scene",
            "r": {
                "type": "rectangle",
                "to_world": mi.ScalarTransform4f().rotate([1, 0.3, 0], 35).scale([2.0, 0.7, 1.0]),
            },
        }
    )
    rng = np.random.default_rng(2)
    n = 100
    o = mi.Point3f(*rng.uniform(-0.3, 0.3, size=(2, n)), np.full(n, 5.0))
    ray = mi.RayDifferential3f(mi.Ray3f(o, mi.Vector3f(0.0, 0.0, -1.0)))
    ray.o_x, ray.o_y = o + mi.Vector3f(0.01, 0.0, 0.0), o
    ray.d_x, ray.d_y = mi.Vector3f(0.0, 0.0, -1.0), dr.normalize(mi.Vector3f(0.0, 0.004, -1.0))
    ray.has_differentials = True
    si = scene.ray_intersect(mi.Ray3f(ray))
    assert dr.all(si.is_valid())
    ours = [np.array(v) for v in uv_partials(si, ray)]
    si.compute_uv_partials(ray)
    for a, b in zip(ours, (np.array(si.duv_dx), np.array(si.duv_dy)), strict=True):
        assert np.abs(b).max() > 1e-3
        np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-7)


def test_the_renderers_footprint_is_the_analysis_models():
    """The plugin with a footprint (level 0.5: half the blocks their own lobe, half in cells of
    2 × 2) gives what the NumPy model gives for the same
    cells and counts (:func:`glitter.footprint_at` on the NumPy side of the same functions): one
    implementation, float32 against float64 (a point a hair from a cell or bin edge may differ)."""
    from pavonine.materials import optics

    rng = np.random.default_rng(3)
    n = 4000
    wi, wo = _directions(rng, n), _directions(rng, n)
    lam = rng.uniform(380.0, 780.0, size=(n, 4))
    uv = rng.uniform(0.0, 0.05, size=(n, 2))
    angle = 0.2
    duv = _duv_for(0.5)
    bsdf = mi.load_dict(_plugin_dict(share=0.8, angle=angle))
    si = _sheet(wi, lam, uv, duv)
    si.sh_frame = mi.Frame3f(
        mi.Vector3f(1.0, 0.0, 0.0), mi.Vector3f(0.0, 1.0, 0.0), mi.Vector3f(0.0, 0.0, 1.0)
    )
    value = np.array(bsdf.eval(mi.BSDFContext(), si, mi.Vector3f(*wo.T)))

    unit = feather_bsdf.WORLD_UNIT_UM
    along, across, step = glitter.sheet_coordinates(
        uv[:, 0] * unit, uv[:, 1] * unit, angle * math.pi
    )
    barbule_index, block_index = glitter.block_cell(
        along, across, TABLE1.block_length_um, TABLE1.barbule_width_um
    )
    seed = glitter.lowbias32(TABLE1.glitter_seed ^ ((step * 0x9E3779B1) & glitter.MASK32))
    block = glitter.block_state(
        1.0, CONSTANTS.block_sigma, barbule_index, block_index, seed, GRAINS
    )
    c, s = math.cos(angle * math.pi), math.sin(angle * math.pi)
    rot = np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]])
    wi_b, wo_b = wi @ rot.T, wo @ rot.T
    h = wi_b + wo_b
    level = glitter.footprint_level(
        np.full(n, (duv * unit) ** 2), TABLE1.block_length_um, TABLE1.barbule_width_um
    )
    fp = glitter.footprint_at(
        block,
        level,
        along,
        across,
        seed,
        -h[:, 0] / np.maximum(h[:, 2], 1e-6),
        MODEL,
        SPREAD,
        math.hypot(SPREAD, WITHIN),
        TABLE1.block_length_um,
        TABLE1.barbule_width_um,
    )
    model = optics.model_for(TABLE1)
    expected = np.stack(
        [model.brdf(wi_b, wo_b, lam[:, k], 3, 0.5, 0.8, block=fp) * wo[:, 2] for k in range(4)]
    )
    assert np.ptp(fp.cells[0].gain) > 1.0 and 0.2 < fp.block_weight.mean() < 0.8
    close = np.all(np.isclose(value, expected, rtol=3e-3, atol=3e-5), axis=0)
    assert close.mean() > 0.99, np.flatnonzero(~close)[:10]
