"""hdmitsuba's ``mitsuba:`` render settings: the integrator and samples per pixel a stage asks
for (render/integrator_settings.py), honoured by the renderer, the command line and the farm."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from pxr import Gf, Sdf, Usd, UsdLux, UsdRender
from render_helpers import bind, new_stage, preview, quad, render, render_product

from pavonine.apps.cli import cli
from pavonine.apps.compare.methods import stat_test
from pavonine.base.errors import InputError
from pavonine.render.diagnostics import Diagnostics, StageWarning
from pavonine.render.integrator_settings import IntegratorSpec, read_integrator, read_sample_count

TYPES = {int: Sdf.ValueTypeNames.Int, str: Sdf.ValueTypeNames.String}
TYPES.update({bool: Sdf.ValueTypeNames.Bool, float: Sdf.ValueTypeNames.Double})
QUAD = (slice(13, 19), slice(13, 19))  # the grey quad's middle, at 32×32
SKY = (slice(0, 3), slice(0, 3))  # a corner: the dome seen directly


def settings_prim(stage: Usd.Stage, **attributes) -> Usd.Prim:
    """A RenderSettings prim authoring ``attributes`` (``mitsuba__integrator__max_depth`` for
    ``mitsuba:integrator:max_depth``)."""
    prim = UsdRender.Settings.Define(stage, "/Render/Settings").GetPrim()
    for key, value in attributes.items():
        kind = TYPES[type(value)]
        if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 2**31:
            kind = Sdf.ValueTypeNames.Int64
        prim.CreateAttribute(key.replace("__", ":"), kind).Set(value)
    return prim


def dome_stage(path: Path, **attributes) -> Usd.Stage:
    """A grey UsdPreviewSurface quad under a uniform white dome, seen from 12 units away (the dome
    fills the frame around it), with the given render settings."""
    stage = new_stage(path, camera_z=12.0)
    material, _ = preview(stage, diffuseColor=(0.5, 0.5, 0.5), roughness=1.0)
    bind(quad(stage), material)
    UsdLux.DomeLight.Define(stage, "/Sky").CreateIntensityAttr(1.0)
    if attributes:
        settings_prim(stage, **attributes)
    return stage


def region(rgb: np.ndarray, where: tuple[slice, slice]) -> float:
    return float(rgb[where].mean())


def read(prim: Usd.Prim) -> tuple[IntegratorSpec, list[str]]:
    diag = Diagnostics()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        return read_integrator(prim, diag), diag.messages


# -- reading the settings -------------------------------------------------------------------------


def test_no_mitsuba_settings_give_the_defaults():
    stage = Usd.Stage.CreateInMemory()
    spec, messages = read(settings_prim(stage))
    assert spec == IntegratorSpec() and messages == []
    assert spec.describe() == {
        "type": "path",
        "max_depth": 8,
        "rr_depth": 5,
        "rr_threshold": 0.1,
        "hide_emitters": False,
    }
    assert read_sample_count(settings_prim(stage)) == (None, "")


def test_the_recorded_roulette_is_the_one_the_variant_plays():
    """Scalar variants render with Mitsuba's volpath, which has no early roulette: the image's
    metadata says so (rr_threshold 0); JIT variants keep the default."""
    spec = IntegratorSpec()
    assert spec.for_variant("llvm_ad_spectral").describe()["rr_threshold"] == 0.1
    assert spec.for_variant("scalar_spectral").describe()["rr_threshold"] == 0.0
    direct = IntegratorSpec("direct", samples=(("shading_samples", 4),))
    assert direct.for_variant("scalar_spectral") == direct


@pytest.mark.parametrize("kind", ["path", "volpath", "pavonine_path"])
def test_path_types_are_the_path_tracer_with_their_depths(kind):
    stage = Usd.Stage.CreateInMemory()
    prim = settings_prim(
        stage,
        mitsuba__integrator__type=kind,
        mitsuba__integrator__max_depth=-1,
        mitsuba__integrator__rr_depth=3,
        mitsuba__integrator__hide_emitters=True,
        mitsuba__sample_count=12,
    )
    spec, messages = read(prim)
    # An authored rr_depth is volpath's roulette exactly: no early roulette below a threshold.
    expected = IntegratorSpec(
        "path", max_depth=-1, rr_depth=3, rr_threshold=0.0, hide_emitters=True
    )
    assert spec == expected
    count, where = read_sample_count(prim)
    assert messages == [] and count == 12
    assert where.endswith(": /Render/Settings.mitsuba:sample_count")


def test_direct_keeps_its_sample_counts():
    stage = Usd.Stage.CreateInMemory()
    prim = settings_prim(
        stage,
        mitsuba__integrator__type="direct",
        mitsuba__integrator__emitter_samples=4,
        mitsuba__integrator__bsdf_samples=2,
    )
    spec, _ = read(prim)
    assert spec.describe() == {
        "type": "direct",
        "hide_emitters": False,
        "bsdf_samples": 2,
        "emitter_samples": 4,
    }


def test_unsupported_types_and_keys_are_rendered_by_the_path_tracer_and_named():
    stage = Usd.Stage.CreateInMemory()
    spec, messages = read(
        settings_prim(
            stage,
            mitsuba__integrator__type="ptracer",
            mitsuba__integrator__samples=4,
            mitsuba__integrator__max_depth=3,
        )
    )
    assert spec == IntegratorSpec(max_depth=3)  # a Monte Carlo integrator's depth still holds
    assert any(
        "type 'ptracer' is not supported; rendered with the path tracer" in m for m in messages
    )
    assert any("mitsuba:integrator:samples is not supported here; ignored" in m for m in messages)
    other = Usd.Stage.CreateInMemory()
    spec, messages = read(
        settings_prim(
            other,
            mitsuba__integrator__type="path",
            mitsuba__integrator__emitter_samples=2,
        )
    )
    assert spec == IntegratorSpec()
    assert messages == [
        "/Render/Settings: mitsuba:integrator:emitter_samples is not supported here; ignored"
    ]


@pytest.mark.parametrize(
    ("attributes", "field", "message"),
    [
        ({"max_depth": -2}, "max_depth", "must be at least -1, got -2"),
        ({"max_depth": "eight"}, "max_depth", "must be an integer, got 'eight'"),
        ({"max_depth": float("nan")}, "max_depth", "must be an integer"),
        ({"max_depth": 2.5}, "max_depth", "must be an integer, got 2.5"),
        ({"rr_depth": 0}, "rr_depth", "must be at least 1, got 0"),
        ({"max_depth": 2**31}, "max_depth", "must be at most 2,147,483,647, got 2,147,483,648"),
        ({"rr_depth": 1e300}, "rr_depth", "must be at most 2,147,483,647"),
        ({"hide_emitters": "yes"}, "hide_emitters", "must be a bool"),
        ({"type": ""}, "type", "must be a non-empty string"),
    ],
)
def test_bad_values_name_the_layer_and_the_attribute(tmp_path, attributes, field, message):
    stage = Usd.Stage.CreateNew(str(tmp_path / "settings.usda"))
    values = {"type": "path", **attributes}
    prim = settings_prim(stage, **{f"mitsuba__integrator__{k}": v for k, v in values.items()})
    with pytest.raises(InputError) as caught:
        read(prim)
    text = str(caught.value)
    assert text.startswith(f"{tmp_path / 'settings.usda'}: /Render/Settings.mitsuba:integrator:")
    assert field in caught.value.where and message in text and "\n" not in text


def test_a_setting_without_its_type_or_with_clashing_counts_is_refused():
    stage = Usd.Stage.CreateInMemory()
    with pytest.raises(InputError, match="needs mitsuba:integrator:type too"):
        read(settings_prim(stage, mitsuba__integrator__max_depth=3))
    stage = Usd.Stage.CreateInMemory()
    prim = settings_prim(
        stage,
        mitsuba__integrator__type="direct",
        mitsuba__integrator__shading_samples=2,
        mitsuba__integrator__bsdf_samples=2,
    )
    with pytest.raises(InputError, match="shading_samples: cannot be given with"):
        read(prim)
    stage = Usd.Stage.CreateInMemory()
    with pytest.raises(InputError, match="sample_count: must be at least 1"):
        read_sample_count(settings_prim(stage, mitsuba__sample_count=0))
    stage = Usd.Stage.CreateInMemory()
    prim = settings_prim(stage)
    prim.CreateAttribute("mitsuba:sample_count", Sdf.ValueTypeNames.Int).Set(8, 1.0)
    with pytest.raises(InputError, match="has no default value"):
        read_sample_count(prim)


def test_direct_needs_one_sample_of_either_technique_as_mitsuba_does():
    """Mitsuba's ``direct`` accepts 0 emitter samples with BSDF samples (and the reverse); only a
    total of 0 is refused."""
    stage = Usd.Stage.CreateInMemory()
    spec, _ = read(
        settings_prim(
            stage,
            mitsuba__integrator__type="direct",
            mitsuba__integrator__emitter_samples=0,
            mitsuba__integrator__bsdf_samples=2,
        )
    )
    assert dict(spec.samples) == {"emitter_samples": 0, "bsdf_samples": 2}
    stage = Usd.Stage.CreateInMemory()
    prim = settings_prim(
        stage, mitsuba__integrator__type="direct", mitsuba__integrator__shading_samples=0
    )
    with pytest.raises(InputError, match="shading_samples: direct needs at least one"):
        read(prim)


# -- rendering what they say ----------------------------------------------------------------------


@pytest.mark.render
def test_max_depth_counts_scattering_vertices(tmp_path):
    """Depth 1: only emitters seen directly (the dome, not the lit quad); 0: nothing at all; -1
    (no limit) and the default: the quad under the dome (a single surface: no interreflection, so
    the same image as depth 2 in the same random sequence)."""
    settings = {"mitsuba__integrator__type": "path"}
    depth = {}
    for limit in (-1, 0, 1, 2, 8):
        stage = dome_stage(tmp_path / f"d{limit}.usda", **settings)
        result = render(stage, spp=16, max_depth=limit)
        assert result.metadata["integrator"]["max_depth"] == limit
        depth[limit] = result.rgb
    assert region(depth[1], QUAD) == 0.0 and region(depth[1], SKY) == pytest.approx(1.0, abs=0.05)
    assert not depth[0].any()
    assert 0.45 < region(depth[8], QUAD) < 0.65  # grey 0.5 plus a dielectric coat, under sky 1
    assert np.array_equal(depth[2], depth[8]) and np.array_equal(depth[-1], depth[8])


@pytest.mark.render
def test_the_stage_max_depth_is_honoured_and_the_caller_overrides_it(tmp_path):
    stage = dome_stage(
        tmp_path / "d1.usda", mitsuba__integrator__type="path", mitsuba__integrator__max_depth=1
    )
    assert region(render(stage, spp=4).rgb, QUAD) == 0.0
    assert region(render(stage, spp=4, max_depth=3).rgb, QUAD) > 0.4


def with_alpha(stage: Usd.Stage) -> Usd.Stage:
    """``stage`` with a RenderProduct of the beauty and an ``alpha`` RenderVar."""
    render_product(stage, {"color": "color3f", "alpha": "float"}, path="/Render/Main")
    return stage


@pytest.mark.render
def test_hide_emitters_hides_the_sky_not_its_light(tmp_path):
    shown, hidden = (
        render(
            with_alpha(
                dome_stage(
                    tmp_path / f"hide{hide}.usda",
                    mitsuba__integrator__type="volpath",
                    mitsuba__integrator__hide_emitters=hide,
                )
            ),
            spp=16,
        ).images
        for hide in (False, True)
    )
    assert region(shown["color"], SKY) == pytest.approx(1.0, abs=0.05)
    assert region(hidden["color"], SKY) == 0.0 and region(hidden["alpha"], SKY) == 0.0
    assert region(shown["alpha"], SKY) == 1.0 and region(hidden["alpha"], QUAD) == 1.0
    assert region(hidden["color"], QUAD) == region(shown["color"], QUAD) > 0.45


@pytest.mark.render
def test_hide_emitters_lets_camera_rays_through_area_lights(tmp_path):
    """volpath's ``skip_area_emitters``: a rect light between the camera and the quad (its dark
    back to the camera) hides the quad, unless emitters are hidden; then the quad shows, lit by
    the dome and the lamp."""
    middle = {}
    for hide in (False, True):
        stage = lamp_over_quad(
            tmp_path / f"lamp{hide}.usda",
            mitsuba__integrator__type="path",
            mitsuba__integrator__hide_emitters=hide,
        )
        middle[hide] = region(render(stage, spp=16).rgb, (slice(14, 18), slice(14, 18)))
    assert middle[False] == 0.0
    assert middle[True] > 0.5


@pytest.mark.render
def test_direct_agrees_with_the_path_tracer_at_depth_2(tmp_path):
    """hdmitsuba's own render-settings test stage pattern: ``type = "direct"`` is Mitsuba's direct
    integrator, whose image is the path tracer's at depth 2 (direct light only), within noise."""

    def moments(name, **attributes):
        stage = dome_stage(tmp_path / f"{name}.usda", **attributes)
        result = render(stage, spp=32, moments=True, seed=1 if name == "direct" else 0)
        return result.rgb, result.variance, result.metadata["integrator"]

    direct = moments("direct", mitsuba__integrator__type="direct")
    path = moments("path", mitsuba__integrator__type="path", mitsuba__integrator__max_depth=2)
    assert direct[2]["type"] == "direct" and path[2]["max_depth"] == 2
    assert stat_test(direct[0], path[0], direct[1], path[1]).passed
    assert not np.array_equal(direct[0], path[0])


@pytest.mark.render
def test_sample_count_sets_the_samples_unless_the_caller_does(tmp_path):
    stage = dome_stage(tmp_path / "sc.usda", mitsuba__sample_count=3)
    assert render(stage, spp=None).metadata["spp"] == 3
    assert render(stage, spp=5).metadata["spp"] == 5
    assert render(dome_stage(tmp_path / "plain.usda"), spp=None).metadata["spp"] == 64


@pytest.mark.render
def test_product_level_mitsuba_settings_are_named_as_ignored(tmp_path):
    stage = dome_stage(tmp_path / "product.usda", mitsuba__integrator__type="path")
    product = UsdRender.Product.Define(stage, "/Render/Main")
    product.GetPrim().CreateAttribute("mitsuba:integrator:max_depth", Sdf.ValueTypeNames.Int).Set(1)
    settings = UsdRender.Settings(stage.GetPrimAtPath("/Render/Settings"))
    settings.GetProductsRel().AddTarget(product.GetPath())
    result = render(stage, spp=2)
    assert result.metadata["integrator"]["max_depth"] == 8
    assert any(
        w.startswith("/Render/Main: mitsuba:integrator:max_depth (hdmitsuba's setting) is ignored")
        and "RenderSettings prim only" in w
        for w in result.warnings
    )


@pytest.mark.render
def test_cli_max_depth_and_sample_count_reach_the_farm_tasks(tmp_path):
    """``--max-depth`` through the farm path (two sample shards, rendered in this process) and
    ``mitsuba:sample_count`` as the samples when ``--spp`` is not given."""
    import OpenImageIO as oiio

    stage = dome_stage(tmp_path / "cli.usda", mitsuba__sample_count=4)
    stage.Save()
    out = tmp_path / "out.exr"
    args = ["render", str(tmp_path / "cli.usda"), "-o", str(out), "--resolution", "32x32"]
    run = CliRunner().invoke(
        cli, [*args, "--max-depth", "1", "--split", "2", "--workers", "0", "--json", "-"]
    )
    assert run.exit_code == 0, run.output
    record = json.loads(run.output[run.output.index("{") :])
    assert record["spp"] == 4
    pixels = oiio.ImageBuf(str(out)).get_pixels(oiio.FLOAT)
    assert region(pixels, QUAD) == 0.0 and region(pixels, SKY) > 0.9
    integrator = json.loads(
        oiio.ImageInput.open(str(out)).spec().getattribute("pavonine:integrator")
    )
    assert integrator["max_depth"] == 1
    bad = CliRunner().invoke(cli, [*args, "--max-depth", "-2"])
    assert bad.exit_code == 2 and "--max-depth" in bad.output


@pytest.mark.render
def test_mitsuba_sensor_settings_are_read_and_unknown_ones_named(tmp_path):
    """hdmitsuba's ``irradiancemeter.usda`` pattern: a camera asking to be an irradiance meter, a
    mesh naming it as its sensor, a pixel filter: read (render/sensors.py, whose own tests measure
    the meter), so not named; a filter Mitsuba does not have is named; another ``mitsuba:``
    attribute on a camera is named as unread."""
    stage = dome_stage(tmp_path / "sensor.usda")
    camera = stage.GetPrimAtPath("/Cam")
    for name, value in (
        ("mitsuba:sensor:type", "irradiancemeter"),
        ("mitsuba:sensor:film:pixel_filter:type", "gaussian"),
    ):
        camera.CreateAttribute(name, Sdf.ValueTypeNames.String).Set(value)
    stage.GetPrimAtPath("/Quad").CreateAttribute("mitsuba:sensor", Sdf.ValueTypeNames.String).Set(
        "/Cam"
    )
    found = render(stage, spp=1, resolution=(8, 8)).warnings
    assert not any("mitsuba:sensor" in w for w in found), found
    camera.GetAttribute("mitsuba:sensor:film:pixel_filter:type").Set("blackmanharris")
    camera.CreateAttribute("mitsuba:sensor:film:type", Sdf.ValueTypeNames.String).Set("specfilm")
    found = render(stage, spp=1, resolution=(8, 8)).warnings
    assert any(
        w.startswith("/Cam: mitsuba:sensor:film:pixel_filter:type = 'blackmanharris'")
        for w in found
    )
    assert "/Cam: mitsuba:sensor:film:type (hdmitsuba's setting) is ignored: not supported" in found


@pytest.mark.render
def test_the_variant_in_use_passes_another_is_named(tmp_path):
    stage = dome_stage(tmp_path / "variant.usda", mitsuba__variant="scalar_rgb")
    result = render(stage, spp=1, resolution=(8, 8))
    used = result.metadata["variant"]
    assert (
        f"/Render/Settings: mitsuba:variant 'scalar_rgb' (hdmitsuba's setting) is not used: "
        f"Pavonine renders spectrally, here with {used} (choose with --variant)"
    ) in result.warnings
    stage.GetPrimAtPath("/Render/Settings").GetAttribute("mitsuba:variant").Set(used)
    assert not any("variant" in w for w in render(stage, spp=1, resolution=(8, 8)).warnings)


def lamp_over_quad(path: Path, **attributes) -> Usd.Stage:
    """:func:`dome_stage` with a rect light 2 units above the quad, shining down on it (its
    unlit back to the camera)."""
    stage = dome_stage(path, **attributes)
    lamp = UsdLux.RectLight.Define(stage, "/Lamp")
    lamp.CreateWidthAttr(0.6)
    lamp.CreateHeightAttr(0.6)
    lamp.CreateIntensityAttr(5.0)
    lamp.AddTranslateOp().Set(Gf.Vec3d(0, 0, 2))
    return stage


@pytest.mark.render
def test_hide_emitters_and_no_depth_limit_agree_with_volpath(tmp_path, monkeypatch):
    """The same settings rendered by Mitsuba's ``volpath`` (independent seeds): the same image
    within noise, the sky hidden and the lamp passed by camera rays in both."""
    from pavonine.render import integrator

    stage = lamp_over_quad(
        tmp_path / "hide.usda",
        mitsuba__integrator__type="volpath",
        mitsuba__integrator__hide_emitters=True,
        mitsuba__integrator__max_depth=-1,
    )
    ours = render(stage, spp=32, moments=True, seed=1)
    monkeypatch.setattr(
        integrator,
        "path_tracer",
        lambda depth, rr_threshold=0.0, **params: {"type": "volpath", "max_depth": depth, **params},
    )
    theirs = render(stage, spp=32, moments=True, seed=0)
    assert ours.metadata["integrator"]["max_depth"] == -1
    assert stat_test(ours.rgb, theirs.rgb, ours.variance, theirs.variance).passed
    assert region(ours.rgb, SKY) == region(theirs.rgb, SKY) == 0.0
    middle = (slice(14, 18), slice(14, 18))
    assert region(ours.rgb, middle) > 0.5 and region(theirs.rgb, middle) > 0.5


@pytest.mark.render
def test_max_depth_given_for_direct_light_is_named(tmp_path):
    stage = dome_stage(tmp_path / "direct.usda", mitsuba__integrator__type="direct")
    result = render(stage, spp=2, resolution=(8, 8), max_depth=3)
    assert result.metadata["integrator"] == {"type": "direct", "hide_emitters": False}
    assert (
        "/Render/Settings: max_depth has no effect: the stage asks for direct light"
        in result.warnings
    )
