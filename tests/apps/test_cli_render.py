"""``pavonine render``: outputs, defaults for bare assets, bad stages, determinism, moments."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from pavonine.apps.cli import cli
from pavonine.base.errors import InputError
from pavonine.render.api import render_stage
from pavonine.render.diagnostics import StageWarning
from pavonine.render.imageio import read_exr

pytestmark = pytest.mark.mitsuba  # the CLI checks that Mitsuba loads first

DATA = Path(__file__).parents[1] / "data" / "render"
SCENE = Path(__file__).parents[2] / "assets" / "scenes" / "eye_feather_sun.usda"


def run(*args):
    return CliRunner().invoke(cli, ["render", *map(str, args)])


def quiet_render(path, **kwargs):
    kwargs.setdefault("progress", False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        return render_stage(path, **kwargs)


@pytest.mark.render
def test_bare_asset_gets_framing_camera_sun_and_sky(tmp_path):
    out = tmp_path / "bare.exr"
    result = run(
        DATA / "bare_quad.usda", "-o", out, "--png", "--spp", 8, "--resolution", "32x32", "-q"
    )
    assert result.exit_code == 0, result.output
    pixels, attrs = read_exr(out)
    assert pixels.shape == (32, 32, 3)
    assert attrs["oiio:ColorSpace"] == "lin_rec709_scene"
    assert attrs["pavonine:spp"] == 8 and attrs["pavonine:camera"] == "(framing camera)"
    centre = pixels[12:20, 12:20].mean()
    corner = pixels[:3, :3].mean()
    assert centre > 0.1 and centre > 2 * corner  # the quad fills the middle and is sunlit
    grey = np.asarray(pixels[12:20, 12:20]).reshape(-1, 3).mean(axis=0)
    assert grey.min() > 0.5 * grey.max()  # default sun and sky are close to white
    assert (tmp_path / "bare.png").stat().st_size > 0


@pytest.mark.render
def test_bad_data_renders_what_it_can_with_warnings_naming_prims(tmp_path):
    out = tmp_path / "bad.exr"
    result = run(DATA / "bad_data.usda", "-o", out, "--spp", 4, "--resolution", "16x16", "-q")
    assert result.exit_code == 0, result.output
    err = result.output
    assert "warning: /NaNPoints: 1 of 5 points are NaN" in err
    assert "warning: /Empty: empty mesh" in err
    assert "warning: /Looks/Textured/Albedo: texture 'textures/missing_albedo.png' not found" in err
    assert "warning: /Box: NurbsPatch prims are not supported" in err
    assert "warning: /IntNormals: normals has type int, expected normal3f[]; ignored" in err
    assert "Traceback" not in err
    pixels, _ = read_exr(out)
    assert np.isfinite(pixels).all()
    centre = pixels[6:10, 6:10].reshape(-1, 3).mean(axis=0)
    assert centre[1] > 1.5 * centre[0]  # the texture's green fallback colour is used


@pytest.mark.render
def test_map_of_another_aspect_warns_naming_the_file_and_attribute(tmp_path):
    """``convert`` refuses maps whose width:height differ; a render of such an asset stretches
    the odd map over the feather and says so, naming the attribute and the file."""
    import shutil

    from pavonine.base.map_files import write_map

    asset = tmp_path / "blue_feather"
    shutil.copytree(Path(__file__).parents[2] / "assets" / "feathers" / "blue_feather", asset)
    odd = asset / "maps" / "gradation.png"
    write_map(odd, np.full((64, 64), 0.5))
    out = tmp_path / "r.exr"
    result = run(asset / "blue_feather.usd", "-o", out, "--spp", 2, "--resolution", "32x24", "-q")
    assert result.exit_code == 0, result.output
    warned = [line for line in result.stderr.splitlines() if "pavonine:gradationMap" in line]
    assert len(warned) == 1 and str(odd) in warned[0], result.stderr
    assert "is 64x64, not the width:height of the alpha map's 737x1024" in warned[0]


def test_broken_layer_is_a_one_line_error_and_writes_nothing(tmp_path):
    out = tmp_path / "broken.exr"
    result = run(DATA / "broken_layer.usda", "-o", out, "--spp", 1, "-q")
    assert result.exit_code == 2
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and "broken_layer.usda" in lines[0]
    assert "broken_layer.usda:6:1: parse error" in lines[0] and "pxrInternal" not in lines[0]
    assert not out.exists() and not list(tmp_path.iterdir())


def test_missing_stage_and_bad_options_are_one_line_errors(tmp_path):
    result = run(tmp_path / "nope.usda", "-q")
    assert result.exit_code == 2 and "error: " in result.output and "no such file" in result.output
    result = run(DATA / "bare_quad.usda", "--resolution", "12by4")
    assert result.exit_code == 2 and "WIDTHxHEIGHT" in result.output


@pytest.mark.render
def test_unknown_camera_names_the_cameras(tmp_path):
    result = run(
        SCENE,
        "-o",
        tmp_path / "x.exr",
        "--camera",
        "/Nope",
        "--spp",
        1,
        "--resolution",
        "8x8",
        "-q",
    )
    assert result.exit_code == 2
    assert (
        "error: --camera: no visible camera at /Nope" in result.output
        and "/World/Camera" in result.output
    )
    assert not (tmp_path / "x.exr").exists()


@pytest.mark.render
def test_same_seed_same_image_other_seed_other_noise():
    a = quiet_render(DATA / "bare_quad.usda", spp=8, resolution=(24, 24), seed=3)
    b = quiet_render(DATA / "bare_quad.usda", spp=8, resolution=(24, 24), seed=3)
    c = quiet_render(DATA / "bare_quad.usda", spp=8, resolution=(24, 24), seed=4)
    np.testing.assert_array_equal(a.rgb, b.rgb)
    assert np.abs(a.rgb - c.rgb).max() > 1e-3
    assert a.metadata["seed"] == 3 and a.metadata["variant"] == "llvm_ad_spectral"


@pytest.mark.render
def test_moments_give_a_variance_that_falls_as_one_over_spp():
    low = quiet_render(DATA / "bare_quad.usda", spp=16, resolution=(16, 16), moments=True)
    high = quiet_render(DATA / "bare_quad.usda", spp=64, resolution=(16, 16), moments=True)
    assert low.variance.shape == (16, 16, 3) and np.all(low.variance >= 0)
    lit = low.rgb.mean(axis=2) > 0.1
    ratio = low.variance[lit].mean() / high.variance[lit].mean()
    assert ratio == pytest.approx(4.0, rel=0.35)
    # the variance predicts the actual error between two independent renders
    other = quiet_render(DATA / "bare_quad.usda", spp=16, resolution=(16, 16), seed=9)
    observed = ((low.rgb - other.rgb) ** 2)[lit].mean() / 2.0
    assert observed == pytest.approx(low.variance[lit].mean(), rel=0.35)


@pytest.mark.render
def test_shipped_scene_renders_the_feather_in_colour(tmp_path):
    result = quiet_render(SCENE, spp=16, resolution=(32, 48))
    assert result.metadata["camera"] == "/World/Camera"
    centre = result.rgb[16:32, 10:22].reshape(-1, 3).mean(axis=0)
    assert centre.max() > 0.1 and centre.max() > 2.0 * centre.min()  # saturated, not grey


# -- options are checked before the render; outputs appear together or not at all ---------------


def fail_if_rendered(monkeypatch):
    import pavonine.render.api as api

    def render_stage(*args, **kwargs):
        raise AssertionError("render_stage must not run for bad options")

    monkeypatch.setattr(api, "render_stage", render_stage)


def one_error_line(result) -> str:
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert result.exit_code == 2 and len(lines) == 1, result.output
    assert lines[0].startswith("error: ") and "Traceback" not in result.output
    return lines[0]


def test_unknown_view_is_a_one_line_error_before_rendering(tmp_path, monkeypatch):
    fail_if_rendered(monkeypatch)
    out = tmp_path / "v.exr"
    result = run(DATA / "bare_quad.usda", "-o", out, "--png", "--view", "Bogus View", "-q")
    line = one_error_line(result)
    assert "--view" in line and "'Bogus View'" in line and "'Un-tone-mapped'" in line
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("where", ["file", "proc"])
def test_unwritable_output_is_a_one_line_error_before_rendering(tmp_path, monkeypatch, where):
    fail_if_rendered(monkeypatch)
    (tmp_path / "plain").write_text("not a folder")
    out = tmp_path / "plain" / "x.exr" if where == "file" else Path("/proc/pavonine_x.exr")
    line = one_error_line(run(DATA / "bare_quad.usda", "-o", out, "-q"))
    assert str(out) in line


def test_png_out_must_be_a_png(tmp_path, monkeypatch):
    fail_if_rendered(monkeypatch)
    result = run(DATA / "bare_quad.usda", "-o", tmp_path / "w.exr", "--png-out", tmp_path / "w.jpg")
    assert "must name a .png file" in one_error_line(result)
    assert not list(tmp_path.iterdir())


@pytest.mark.render
def test_png_flag_before_the_stage_is_a_flag(tmp_path):
    out = tmp_path / "flag.exr"
    args = ("--png", DATA / "bare_quad.usda", "-o", out, "--spp", 1, "--resolution", "8x8", "-q")
    result = run(*args)
    assert result.exit_code == 0, result.output
    assert out.is_file() and (tmp_path / "flag.png").is_file()
    png = tmp_path / "named" / "look.png"
    result = run(*args, "--png-out", png, "--view", "ACES 2.0 - SDR 100 nits (Rec.709)")
    assert result.exit_code == 0, result.output
    assert png.is_file()


def test_exr_and_png_are_written_together_or_not_at_all(tmp_path, monkeypatch):
    from pavonine.render import imageio

    rgb = np.full((4, 4, 3), 0.5, np.float32)
    imageio.write_render(tmp_path / "ok.exr", rgb, {"spp": 1}, png_path=tmp_path / "ok.png")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ok.exr", "ok.png"]

    def broken_png(path, rgb, display=None, **attributes):
        raise OSError(28, "No space left on device", str(path))

    monkeypatch.setattr(imageio, "write_png", broken_png)
    with pytest.raises((OSError, InputError)):
        imageio.write_render(tmp_path / "x.exr", rgb, png_path=tmp_path / "x.png")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ok.exr", "ok.png"]  # no x.*, no temps


def test_resolution_parser_shared_by_every_command():
    from pavonine.render.settings import parse_resolution

    assert parse_resolution("64x48") == (64, 48)
    assert parse_resolution(" 32X16 ") == (32, 16)
    assert parse_resolution("96") == (96, 96)
    for bad in ("12by4", "0x5", "1x2x3", "", "-4x4"):
        with pytest.raises(InputError, match="--resolution"):
            parse_resolution(bad)
