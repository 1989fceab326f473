"""Display transforms: the pinned config, $OCIO and --ocio-config/--display/--view/--exposure."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from pavonine.apps.cli import cli
from pavonine.materials import display
from pavonine.materials.display import PINNED_CONFIG, REFERENCE_DISPLAY, DisplayTransform

ocio = pytest.importorskip("PyOpenColorIO")

DATA = Path(__file__).resolve().parents[1] / "data" / "render"

#: A config of our own: linear Rec.709 under one of the CG configs' aliases, and one display
#: whose only view is a square root (gamma 2), nothing like sRGB.
GAMMA2_CONFIG = """\
ocio_profile_version: 2
roles:
  default: linear
  scene_linear: linear
  data: linear
file_rules:
  - !<Rule> {name: Default, colorspace: linear}
displays:
  Test Display:
    - !<View> {name: Gamma 2, colorspace: gamma2}
active_displays: []
active_views: []
colorspaces:
  - !<ColorSpace>
    name: linear
    aliases: [lin_rec709_srgb]
    isdata: false
  - !<ColorSpace>
    name: gamma2
    isdata: false
    from_scene_reference: !<ExponentTransform> {value: 2.0, direction: inverse}
"""


@pytest.fixture
def gamma2(tmp_path) -> Path:
    path = tmp_path / "gamma2.ocio"
    path.write_text(GAMMA2_CONFIG)
    return path


def test_pinned_config_is_a_versioned_builtin_that_resolves():
    match = re.fullmatch(
        r"ocio://(cg-config-v\d+\.\d+\.\d+_aces-v[\d.]+_ocio-v(\d+)\.(\d+))", PINNED_CONFIG
    )
    assert match, f"{PINNED_CONFIG} must name a versioned built-in config, not an alias"
    names = [entry[0] for entry in ocio.BuiltinConfigRegistry().getBuiltinConfigs()]
    assert match.group(1) in names
    config = ocio.Config.CreateFromFile(PINNED_CONFIG)
    assert "Un-tone-mapped" in config.getViews("sRGB - Display")
    assert config.getColorSpace(display.SCENE_LINEAR) is not None


def test_closed_form_srgb_agrees_with_ocio():
    """What a PNG is without OpenColorIO (base install): IEC 61966-2-1 against OCIO's view."""
    x = np.concatenate([np.linspace(0, 1.2, 200_001), np.random.default_rng(0).random(100_000)])
    rgb = np.repeat(x.astype(np.float32)[:, None], 3, axis=1)
    ours, theirs = display.srgb_encode(rgb), REFERENCE_DISPLAY.encode(rgb)
    assert np.max(np.abs(ours - theirs)) < 2e-5
    differ = np.mean(np.round(ours * 255) != np.round(theirs * 255))
    assert differ < 1e-3  # measured 0.04 %: one code value, at rounding boundaries
    encoded = np.linspace(0, 1, 256, dtype=np.float32)[:, None].repeat(3, 1)
    assert display.srgb_decode(encoded) == pytest.approx(
        REFERENCE_DISPLAY.decode(encoded), abs=5e-5
    )


def test_unknown_names_are_errors_naming_the_option(gamma2):
    with pytest.raises(display.DisplayError, match="--view: unknown OCIO view 'Nope'"):
        display.resolve(view="Nope")
    with pytest.raises(display.DisplayError, match="--display: unknown display"):
        display.resolve(str(gamma2), display="sRGB - Display")
    with pytest.raises(display.DisplayError, match="--ocio-config: cannot load"):
        display.resolve("/nonexistent/config.ocio")
    assert display.resolve(str(gamma2)) == DisplayTransform(str(gamma2), "Test Display", "Gamma 2")


def render_png(tmp_path: Path, name: str, *args: str, env: dict | None = None):
    out = tmp_path / f"{name}.exr"
    result = CliRunner().invoke(
        cli,
        [
            "render", str(DATA / "bare_quad.usda"), "-o", str(out), "--png", "--spp", "4",
            "--resolution", "16x16", "--seed", "3", "--json", "-", *args,
        ],
        env=env,
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    from pavonine.apps.compare.methods import _read_pixels

    linear, _ = _read_pixels(out)
    png, attributes = _read_pixels(out.with_suffix(".png"))
    return json.loads(result.stdout), linear, png, attributes


@pytest.mark.render
def test_ocio_env_changes_the_png_and_compare_reads_it_back(tmp_path, gamma2):
    _, linear, pinned_png, _ = render_png(tmp_path, "pinned", env={"OCIO": ""})
    report, linear_b, png, attributes = render_png(tmp_path, "gamma2", env={"OCIO": str(gamma2)})
    assert np.array_equal(linear, linear_b)  # same render, only the display transform differs
    expected = np.round(np.sqrt(np.clip(linear, 0, 1)) * 255) / 255
    assert np.abs(png - expected).max() <= 1 / 255 + 1e-6
    assert (
        np.abs(png - pinned_png).max() > 5 / 255
    )  # the pinned view and gamma 2 really differ (rounding is 1/255)
    assert attributes["pavonine:ocio_config"] == str(gamma2)
    assert (attributes["pavonine:display"], attributes["pavonine:view"]) == (
        "Test Display",
        "Gamma 2",
    )
    assert report["display"]["config"] == str(gamma2)

    from pavonine.apps.compare.methods import read_image

    decoded = read_image(tmp_path / "gamma2.png")  # with the transform the PNG records
    bright = (linear[..., :3] > 0.05) & (linear[..., :3] < 0.95)  # not clipped by the PNG
    assert decoded.rgb[bright] == pytest.approx(linear[..., :3][bright], rel=0.03)


@pytest.mark.render
def test_exposure_and_view_options(tmp_path):
    _, linear, png, attributes = render_png(tmp_path, "ev", "--exposure", "1", env={"OCIO": ""})
    assert attributes["pavonine:exposure"] == "1"
    expected = np.round(display.srgb_encode(2 * linear[..., :3]) * 255) / 255
    assert np.abs(png[..., :3] - expected).max() <= 1 / 255 + 1e-6
    result = CliRunner().invoke(
        cli,
        ["render", str(DATA / "bare_quad.usda"), "--view", "Nope", "-o", str(tmp_path / "x.exr")],
    )
    assert result.exit_code == 2 and result.stderr.startswith("error: --view: unknown OCIO view")
