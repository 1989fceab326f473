"""The Mitsuba plugin against the analysis model, its sampling (χ²), energy and reciprocity."""

import math

import numpy as np
import pytest

pytest.importorskip("mitsuba")  # conftest says why when it cannot load
pytestmark = pytest.mark.llvm  # vectorised calls: Mitsuba's llvm variant
from pavonine.base.backend import select_variant
from pavonine.materials import optics
from pavonine.materials.brdf import direction
from pavonine.materials.parameters import preset
from pavonine.render.feather_bsdf import PLUGIN_NAME, PRIMVAR_SLOTS, feather_bsdf_dict, register

select_variant()
import drjit as dr
import mitsuba as mi

register()
TABLE1 = preset("paper-table1")
FREYER = preset("freyer2020")  # the physical mode, as shipped
#: A physical-mode material whose gradation ends differ (tables with gradation samples).
GRADED = FREYER.with_(
    classes=(
        *FREYER.classes[:5],
        type(FREYER.classes[5])(
            long=(FREYER.classes[5].long[0], FREYER.classes[4].long[0]),
            short=(FREYER.classes[5].short[0], FREYER.classes[3].short[0]),
            cortex=(0.10, 0.07),
        ),
    )
)


def _plugin_dict(
    ocellar_class: int, gradation: float, angle: float = 0.0, share: float = 1.0, params=TABLE1
):
    d = feather_bsdf_dict(params)
    grey = 1.0 - ocellar_class / (len(params.classes) - 1)
    for name, value in (
        ("ocellar", grey),
        ("gradation", gradation),
        ("angle", angle),
        ("melanin", share),
    ):
        d[name] = {"type": "uniform", "value": value}
    return d


def _interaction(wi: np.ndarray, wavelengths: np.ndarray):
    n = wi.shape[0]
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.wi = mi.Vector3f(*wi.T)
    si.wavelengths = mi.Spectrum(*[mi.Float(wavelengths[:, k]) for k in range(4)])
    return si


def _random_directions(rng, n, lower_fraction=0.2):
    w = rng.normal(size=(n, 3))
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    w[:, 2] = np.abs(w[:, 2])
    flip = rng.random(n) < lower_fraction
    w[flip, 2] *= -1
    return w


@pytest.mark.parametrize(
    ("ocellar_class", "gradation", "angle", "share", "params"),
    [
        (0, 0.0, 0.0, 1.0, TABLE1),
        (2, 0.5, 0.25, 1.0, TABLE1),
        (3, 1.0, 0.6, 0.7, TABLE1),
        (5, 0.3, 0.9, 0.4, TABLE1),
        (0, 0.0, 0.1, 1.0, FREYER),
        (3, 0.5, 0.4, 0.8, FREYER),
        (4, 0.2, 0.7, 1.0, FREYER),
        (5, 0.37, 0.9, 0.6, GRADED),
    ],
    ids=["paper-0", "paper-2", "paper-3", "paper-5", "phys-0", "phys-3", "phys-4", "phys-graded"],
)
def test_plugin_eval_equals_analysis_model(ocellar_class, gradation, angle, share, params):
    """The renderer's JIT-compiled eval equals the NumPy model at thousands of configurations
    (4 000 each, paper and physical mode: 32 000 in all), reading the same tables."""
    rng = np.random.default_rng(ocellar_class)
    n = 4000
    wi = _random_directions(rng, n, 0.0)
    wo = _random_directions(rng, n, 0.0)
    below = rng.random(n) < 0.2
    wi[below, 2] *= -1
    wo[below, 2] *= -1
    lam = rng.uniform(360.0, 830.0, size=(n, 4))
    bsdf = mi.load_dict(_plugin_dict(ocellar_class, gradation, angle, share, params))
    value = np.array(bsdf.eval(mi.BSDFContext(), _interaction(wi, lam), mi.Vector3f(*wo.T)))

    # The angle map turns the barbule's long axis by angle·180° from the surface tangent.
    c, s = math.cos(angle * math.pi), math.sin(angle * math.pi)
    rot = np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]])
    model = optics.model_for(params)
    expected = np.stack(
        [
            model.brdf(wi @ rot.T, wo @ rot.T, lam[:, k], ocellar_class, gradation, share)
            * np.abs(wo[:, 2])
            for k in range(4)
        ]
    )
    np.testing.assert_allclose(value, expected, rtol=2e-3, atol=2e-5)


@pytest.mark.parametrize("as_texture", [False, True], ids=["constant", "texture"])
def test_primvar_twins_take_the_primvars_units_and_win_over_the_maps(as_texture):
    """``<map>_primvar`` slots (barbs' vertex primvars) in class index, t, w and degrees give
    the BSDF of the maps' grey levels, over maps that say otherwise; the angle is 180° periodic."""
    rng = np.random.default_rng(7)
    n = 500
    wi, wo = _random_directions(rng, n, 0.0), _random_directions(rng, n, 0.0)
    lam = rng.uniform(360.0, 830.0, size=(n, 4))

    def evaluate(d):
        bsdf = mi.load_dict(d)
        return np.array(bsdf.eval(mi.BSDFContext(), _interaction(wi, lam), mi.Vector3f(*wo.T)))

    expected = evaluate(_plugin_dict(3, 0.6, 0.25, 0.7))
    twins = _plugin_dict(0, 0.1, 0.8, 1.0)  # maps that disagree
    for name, value in (
        ("ocellar", 3),
        ("gradation", 0.6),
        ("angle", 45.0 - 180.0),
        ("melanin", 0.7),
    ):
        slot = PRIMVAR_SLOTS[name]
        twins[slot] = {"type": "uniform", "value": value} if as_texture else float(value)
    np.testing.assert_allclose(evaluate(twins), expected, rtol=1e-5, atol=1e-7)


@pytest.mark.parametrize("params", [TABLE1, GRADED], ids=["paper", "physical"])
def test_plugin_eval_is_reciprocal(params):
    rng = np.random.default_rng(7)
    n = 2000
    wi, wo = _random_directions(rng, n), _random_directions(rng, n)
    wo[:, 2] = np.abs(wo[:, 2]) * np.sign(wi[:, 2])
    lam = np.tile([450.0, 520.0, 600.0, 680.0], (n, 1))
    bsdf = mi.load_dict(_plugin_dict(3, 0.4, 0.3, 0.8, params))
    ctx = mi.BSDFContext()
    f_io = np.array(bsdf.eval(ctx, _interaction(wi, lam), mi.Vector3f(*wo.T))) / np.abs(wo[:, 2])
    f_oi = np.array(bsdf.eval(ctx, _interaction(wo, lam), mi.Vector3f(*wi.T))) / np.abs(wi[:, 2])
    np.testing.assert_allclose(f_io, f_oi, rtol=1e-3, atol=1e-6)


@pytest.mark.parametrize("mode", ["paper", "physical"])
@pytest.mark.parametrize("ocellar_class", range(6))
@pytest.mark.parametrize("incidence", [0.0, 40.0, 75.0])
def test_sampling_passes_chi2(ocellar_class, incidence, mode):
    from mitsuba.chi2 import BSDFAdapter, ChiSquareTest, SphericalDomain

    params = FREYER if mode == "physical" else TABLE1
    wi = [float(v) for v in direction(incidence, 30.0)]
    sample, pdf = BSDFAdapter(
        PLUGIN_NAME, _plugin_dict(ocellar_class, 0.5, 0.2, 0.7, params), wi=wi
    )
    test = ChiSquareTest(
        domain=SphericalDomain(),
        sample_func=sample,
        pdf_func=pdf,
        sample_dim=3,
        sample_count=200_000,
    )
    assert test.run(), test.messages


@pytest.mark.parametrize("params", [TABLE1, FREYER, GRADED], ids=["paper", "physical", "graded"])
@pytest.mark.parametrize("ocellar_class", range(6))
def test_white_furnace_albedo_at_most_one(ocellar_class, params):
    rng = np.random.default_rng(11)
    bsdf = mi.load_dict(_plugin_dict(ocellar_class, 1.0, 0.0, 1.0, params))
    n = 100_000
    for incidence in (0.0, 45.0, 80.0, 89.0):
        wi = np.tile(direction(incidence, 60.0), (n, 1))
        lam = rng.uniform(360.0, 830.0, size=(n, 4))
        _, weight = bsdf.sample(
            mi.BSDFContext(),
            _interaction(wi, lam),
            mi.Float(rng.random(n)),
            mi.Point2f(rng.random(n), rng.random(n)),
        )
        albedo = np.array(weight).mean(axis=1)
        assert np.all(np.isfinite(albedo)) and np.all(albedo <= 1.0 + 0.01)


def test_sample_weight_matches_eval_over_pdf():
    rng = np.random.default_rng(5)
    n = 5000
    bsdf = mi.load_dict(_plugin_dict(1, 0.5, 0.1, 0.6))
    wi = _random_directions(rng, n, 0.3)
    lam = rng.uniform(380.0, 780.0, size=(n, 4))
    si = _interaction(wi, lam)
    ctx = mi.BSDFContext()
    bs, weight = bsdf.sample(
        ctx, si, mi.Float(rng.random(n)), mi.Point2f(rng.random(n), rng.random(n))
    )
    value, pdf = bsdf.eval_pdf(ctx, si, bs.wo)
    ok = np.array(bs.pdf) > 1e-3
    np.testing.assert_allclose(np.array(bs.pdf)[ok], np.array(pdf)[ok], rtol=1e-3)
    expected = np.array(value)[:, ok] / np.array(pdf)[ok]
    np.testing.assert_allclose(np.array(weight)[:, ok], expected, rtol=2e-3, atol=1e-5)


def test_angle_map_is_relative_to_the_barb_tangent():
    """With ``barb_tangents`` the barbule axis is the mesh's barb direction turned by the angle map."""
    from pavonine.render.mesh import uv_tangents

    def render_quad(barb, angle):
        props = mi.Properties()
        d = _plugin_dict(3, 0.5, angle, 1.0)
        d["barb_tangents"] = barb is not None
        props["bsdf"] = mi.load_dict(d)
        mesh = mi.Mesh("quad", 4, 2, props=props, has_vertex_texcoords=True)
        params = mi.traverse(mesh)
        positions = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32)
        faces = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
        uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
        params["vertex_positions"] = mi.Float(positions.ravel())
        params["faces"] = mi.UInt32(faces.ravel())
        params["vertex_texcoords"] = mi.Float(uv.ravel())
        params.update()
        if barb is not None:
            tangents = uv_tangents(positions, faces, uv) if barb == "uv" else np.tile(barb, (4, 1))
            mesh.add_attribute(
                "vertex_barb_tangent", 3, mi.Float(tangents.astype(np.float32).ravel())
            )
        scene = mi.load_dict({"type": "scene", "quad": mesh})
        si = scene.ray_intersect(mi.Ray3f(mi.Point3f(0.1, 0.2, 1.0), mi.Vector3f(0, 0, -1)))
        si.wi = mi.Vector3f(*[float(c) for c in direction(40.0, 10.0)])
        si.wavelengths = mi.Spectrum(450.0, 520.0, 600.0, 680.0)
        wo = mi.Vector3f(*[float(c) for c in direction(25.0, 160.0)])
        return np.array(si.bsdf().eval(mi.BSDFContext(), si, wo)).ravel()

    along_u = render_quad(None, 0.5)
    # dp/du from the UVs is the surface tangent: same as no attribute.
    np.testing.assert_allclose(render_quad("uv", 0.5), along_u, rtol=1e-5)
    # A barb along +y with the barbule at 0° is the same axis as barb along +x turned by 90°.
    np.testing.assert_allclose(render_quad([0.0, 1.0, 0.0], 0.0), along_u, rtol=1e-4)
    assert not np.allclose(render_quad([0.0, 1.0, 0.0], 0.5), along_u, rtol=1e-2)


SCALAR_CHECK = """
import numpy as np
from pavonine.base.backend import select_variant
select_variant("scalar_spectral")
import drjit as dr
import mitsuba as mi
from pavonine.materials import optics
from pavonine.materials.parameters import preset
from pavonine.render.feather_bsdf import feather_bsdf_dict, register
register()
d = feather_bsdf_dict(preset("paper-table1"))
d["ocellar"] = {"type": "uniform", "value": 0.4}
bsdf = mi.load_dict(d)
wi = np.array([0.3, 0.1, 0.9]) / np.linalg.norm([0.3, 0.1, 0.9])
wo = np.array([-0.3, 0.0, 0.95]) / np.linalg.norm([-0.3, 0.0, 0.95])
si = dr.zeros(mi.SurfaceInteraction3f)
si.wi = mi.Vector3f(*wi)
si.wavelengths = mi.Spectrum(450, 500, 550, 600)
value = np.array(bsdf.eval(mi.BSDFContext(), si, mi.Vector3f(*wo)))
model = optics.model_for(preset("paper-table1")).brdf(wi, wo, [450, 500, 550, 600], 3, 0.0) * wo[2]
np.testing.assert_allclose(value, model, rtol=2e-3)
bs, weight = bsdf.sample(mi.BSDFContext(), si, 0.3, mi.Point2f(0.4, 0.6))
assert bs.pdf > 0 and np.all(np.isfinite(np.array(weight)))
print("ok")
"""


def test_plugin_works_in_the_scalar_fallback_variant():
    """Without libLLVM Pavonine falls back to scalar_spectral: the plugin must work there too."""
    import subprocess
    import sys

    result = subprocess.run(
        [sys.executable, "-c", SCALAR_CHECK], capture_output=True, text=True, timeout=300
    )
    assert result.returncode == 0 and result.stdout.strip().endswith("ok"), result.stderr[-2000:]


def test_instance_table_length_does_not_enter_the_kernel():
    """A per-instance table is as long as the largest instance registry id, which moves from one
    scene build to the next; the traced BSDF must not change with it (a changed kernel is a full
    LLVM compile of the whole path tracer, paid again on every render of an instanced train)."""
    bsdf = mi.load_dict(_plugin_dict(2, 0.5))

    def traced_hash(entries: int) -> str:
        bsdf.set_instance_table("gradation_offset", mi.Float(np.full(entries, 0.1)), 0.0)
        i = dr.arange(mi.Float, 16)  # inputs traced, not copied from NumPy (alignment is hashed)
        si = dr.zeros(mi.SurfaceInteraction3f, 16)
        si.wi = dr.normalize(mi.Vector3f(dr.cos(i), 0.3, 1.0))
        si.wavelengths = mi.Spectrum(*(400.0 + 20.0 * i + 70.0 * k for k in range(4)))
        si.instance = dr.reinterpret_array(mi.ShapePtr, dr.opaque(mi.UInt32, 0, 16))
        wo = dr.normalize(mi.Vector3f(dr.sin(i), dr.cos(0.7 * i), 1.0 + 0.1 * i))
        dr.set_flag(dr.JitFlag.KernelHistory, True)
        try:
            dr.eval(bsdf.eval(mi.BSDFContext(), si, wo))
            history = dr.kernel_history()
        finally:
            dr.set_flag(dr.JitFlag.KernelHistory, False)
        return max(history, key=lambda k: k.get("operation_count") or 0)["hash"]

    assert traced_hash(10) == traced_hash(300)


def test_a_colour_map_is_read_as_its_rec709_luma_as_convert_reads_it(tmp_path):
    """The renderer reads a map through Mitsuba's raw bitmap and ``eval_1``, which gives an RGB
    image's luminance (Rec. 709 weights), not its first channel; ``convert`` and ``bake`` reduce
    RGB maps to the same luma (base/map_files.py), so a hand-made colour map means the same
    to all three."""
    import OpenImageIO as oiio

    from pavonine.base.map_files import grey_values
    from pavonine.render.feather_encoding import _bitmap

    rgb = np.zeros((4, 4, 3), np.float32)
    rgb[..., 0], rgb[..., 1], rgb[..., 2] = 0.9, 0.2, 0.5
    path = tmp_path / "colour.exr"
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), oiio.ImageSpec(4, 4, 3, "float"))
    out.write_image(rgb)
    out.close()
    texture = mi.load_dict(_bitmap(str(path)))
    si = dr.zeros(mi.SurfaceInteraction3f)
    si.uv = mi.Point2f(0.5, 0.5)
    value = float(texture.eval_1(si)[0])
    luma = float(grey_values(rgb.ravel(), oiio.ImageSpec(4, 4, 3, "float"))[0, 0])
    assert value == pytest.approx(luma, abs=2e-4)
    assert abs(value - 0.9) > 0.3  # not the first channel


def test_table_gathers_stay_inside_the_table_for_nan_and_out_of_range_indices():
    """Regression (issue 23): a NaN table index converted to 0x80000000 and the gather read 8 GiB
    past the table (SIGSEGV in the JIT kernel); now NaN and negatives read entry 0 and indices
    past the end the last entry, in range ones their own."""
    from pavonine.materials.arraymath import DrJitOps

    ops = DrJitOps()
    table = ops.buffer([10.0, 11.0, 12.0])
    index = mi.Float([float("nan"), -3.0, 1.0, 2.0, 7.0, 2.0**31])
    values = ops.gather(table, index)
    dr.eval(values)
    assert np.asarray(values).tolist() == [10.0, 10.0, 11.0, 12.0, 12.0, 12.0]
