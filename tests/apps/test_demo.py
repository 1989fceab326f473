"""``pavonine demo``: the README's main job, end to end at a tiny size."""

import numpy as np
import pytest
from click.testing import CliRunner

from pavonine.apps.cli import cli

pytestmark = [pytest.mark.render, pytest.mark.convert]


def test_demo_paints_converts_and_renders(tmp_path):
    out = tmp_path / "demo"
    result = CliRunner().invoke(
        cli, ["demo", "-o", str(out), "--size", "256", "--spp", "4", "--resolution", "48x72"]
    )
    assert result.exit_code == 0, result.output
    for name in (
        "alpha",
        "ocellar",
        "gradation",
        "angle",
        "displacement",
        "melanin",
        "contact_sheet",
    ):
        assert (out / "maps" / "eye" / f"{name}.png").is_file()
    assert (out / "assets" / "eye_feather" / "eye_feather.usd").is_file()
    import OpenImageIO as oiio

    image = oiio.ImageBuf(str(out / "eye_feather_sun.png"))
    assert (image.spec().width, image.spec().height) == (48, 72)
    pixels = image.get_pixels(oiio.FLOAT)
    # The feather is in the frame: the image is not one flat colour.
    assert np.ptp(pixels[..., :3]) > 0.2
    from pxr import Usd

    stage = Usd.Stage.Open(str(out / "eye_feather_sun.usda"))
    assert stage.GetPrimAtPath("/World/Feather").GetChildren(), "the scene must resolve the asset"


def test_demo_rejects_a_bad_resolution(tmp_path):
    result = CliRunner().invoke(cli, ["demo", "-o", str(tmp_path / "d"), "--resolution", "wide"])
    assert result.exit_code == 2 and "--resolution" in result.output


def test_demo_renders_small_on_the_scalar_fallback_and_says_so(tmp_path, monkeypatch):
    """Without libLLVM the default demo would take hours: it renders 96x144 at 8 spp instead."""
    from pavonine.base import backend
    from pavonine.render import api

    seen = {}

    def fake_render(stage, *, spp, resolution, seed, progress):
        seen.update(spp=spp, resolution=resolution)
        raise SystemExit(0)  # stop here: the size was decided

    monkeypatch.setattr(
        backend,
        "select_variant",
        lambda *a: backend.Backend("scalar_spectral", None, None, "no usable libLLVM"),
    )
    monkeypatch.setattr(api, "render_stage", fake_render)
    result = CliRunner().invoke(cli, ["demo", "-o", str(tmp_path / "d"), "--size", "64"])
    assert result.exit_code == 0, result.output
    assert seen == {"spp": 8, "resolution": (96, 144)}
    assert "warning: no libLLVM" in result.stderr
    seen.clear()
    CliRunner().invoke(cli, ["demo", "-o", str(tmp_path / "e"), "--size", "64", "--spp", "2"])
    assert seen == {"spp": 2, "resolution": (512, 768)}  # asked for: kept
