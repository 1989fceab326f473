"""``pavonine demo``: the README's main job, end to end at a tiny size."""

import numpy as np
import pytest
from click.testing import CliRunner

from pavonine.pipeline.cli import cli

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
