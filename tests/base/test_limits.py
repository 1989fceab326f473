"""Issue 14, hostile input: each case the issue lists, as a named test, and the input limits
(``pavonine.base.limits``, docs/reliability.md "Input limits").

Every case ends in one line ``error: <file or field>: <message>`` and exit 2 (checked by
:func:`hostile.assert_clean`), within a time limit, writing nothing.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from hostile import (
    MAP_NAMES,
    assert_clean,
    assert_nothing_left,
    odd_files,
    real_png,
    run_cli,
    small_feather_recipe,
    time_limit,
    to_toml,
)

from pavonine.base import limits
from pavonine.base.errors import InputError

SHIPPED_SCENE = Path(__file__).resolve().parents[2] / "assets" / "scenes" / "blue_feather_sun.usda"


def refused(args: list, needle: str, seconds: float = 60.0) -> str:
    """Run ``pavonine ARGS``: exit 2, one clean error line containing ``needle``; the line."""
    outcome = run_cli(args, seconds)
    assert_clean(outcome, args, codes=(2,))
    line = next(line for line in outcome.stderr.splitlines() if line.startswith("error: "))
    assert needle in line, line
    return line


@pytest.fixture(scope="module")
def huge_pngs(tmp_path_factory) -> dict[str, Path]:
    """Real, complete PNGs of 30000x30000 (about 4 MB) and 20000x20000 pixels."""
    folder = tmp_path_factory.mktemp("huge")
    return {
        "30000": real_png(folder / "huge30000.png", 30000, 30000),
        "20000": real_png(folder / "huge20000.png", 20000, 20000),
    }


def write_maps(folder: Path, width: int, height: int) -> Path:
    from pavonine.base.map_files import write_map

    for name in MAP_NAMES:
        write_map(folder / f"{name}.png", np.full((height, width), 1.0 if name == "alpha" else 0.5))
    return folder


def recipe_file(tmp_path: Path, maps: Path | None = None, **changes) -> Path:
    maps = maps or write_maps(tmp_path / "maps", 16, 32)
    table = small_feather_recipe(maps)
    table.update(changes)
    path = tmp_path / "recipe.toml"
    path.write_text(to_toml(table))
    return path


def convert_refused(tmp_path: Path, recipe: Path | str, needle: str, seconds: float = 60.0) -> str:
    out = tmp_path / "out"
    line = refused(["convert", str(recipe), "-o", str(out)], needle, seconds)
    assert_nothing_left(out)
    return line


# --------------------------------------------------------------------------------- recipes
def test_recipe_of_random_bytes(tmp_path):
    recipe = tmp_path / "noise.toml"
    recipe.write_bytes(np.random.default_rng(14).integers(0, 256, 3000, dtype=np.uint8).tobytes())
    convert_refused(tmp_path, recipe, f"{recipe}: not UTF-8 text")


def test_recipe_of_utf16_text(tmp_path):
    recipe = tmp_path / "utf16.toml"
    recipe.write_bytes('name = "eye_feather"\n'.encode("utf-16"))
    convert_refused(tmp_path, recipe, "not UTF-8 text")


def test_toml_array_nested_100000_deep(tmp_path):
    recipe = tmp_path / "deep.toml"
    recipe.write_text("a = " + "[" * 100_000 + "]" * 100_000 + "\n")
    convert_refused(tmp_path, recipe, "nested too deeply")


def test_recipe_symlink_loop(tmp_path):
    (tmp_path / "b.toml").symlink_to(tmp_path / "a.toml")
    (tmp_path / "a.toml").symlink_to(tmp_path / "b.toml")
    convert_refused(tmp_path, tmp_path / "a.toml", "symbolic link loop")


def test_recipe_is_dev_zero(tmp_path):
    convert_refused(tmp_path, "/dev/zero", "/dev/zero: is a device, expected a regular file", 20)


def test_recipe_is_a_fifo(tmp_path):
    os.mkfifo(tmp_path / "fifo.toml")  # no writer: opening it for reading would block forever
    convert_refused(tmp_path, tmp_path / "fifo.toml", "is a FIFO (named pipe)", 20)


def test_recipe_larger_than_the_recipe_limit(tmp_path):
    recipe = tmp_path / "big.toml"
    recipe.write_text("# padding\n" * (limits.MAX_RECIPE_BYTES // 10 + 1))
    convert_refused(tmp_path, recipe, "at most")


def test_name_with_trailing_newline_fails_the_name_check(tmp_path):
    line = convert_refused(tmp_path, recipe_file(tmp_path, name="eye\n"), ": name: must be a USD")
    assert "'eye\\n'" in line


def test_train_component_name_with_trailing_newline(tmp_path):
    from pavonine.pipeline.assemble.recipe import parse_train_recipe

    component = tmp_path / "eye.usda"
    component.write_text("#usda 1.0\n")
    recipe = tmp_path / "train.toml"
    recipe.write_text(
        to_toml(
            {
                "name": "train",
                "components": {"eye\n": str(component)},
                "rows": [{"component": "eye\n", "count": 1, "radius_cm": 5}],
            }
        )
    )
    with pytest.raises(InputError, match="must be a USD identifier"):
        parse_train_recipe(recipe)


def test_layer_count_2_pow_31_refused(tmp_path):
    recipe = recipe_file(
        tmp_path, material={"preset": "paper-table1", "class": {"0": {"long": {"count": 2**31}}}}
    )
    convert_refused(tmp_path, recipe, "material.class.0.long.count: must be at most 1000 layers")
    refused(
        ["spectra", "--interval", "200", "--radius", "60", "--layers", str(2**31)],
        "--layers: must be at most 1000",
    )


def test_layer_count_2_pow_31_minus_1_in_usd_is_a_validate_error(tmp_path):
    from pxr import Usd

    from pavonine.materials.parameters import preset
    from pavonine.schemas.authoring import create_feather_material

    stage = Usd.Stage.CreateNew(str(tmp_path / "asset.usda"))
    material = create_feather_material(stage, "/Feather", preset("paper-table1"), {})
    stage.SetDefaultPrim(material.GetPrim())
    attr = material.GetPrim().GetAttribute("pavonine:long:layerCount")
    counts = list(attr.Get())
    counts[0] = (2**31 - 1, 4)
    attr.Set(counts)
    stage.GetRootLayer().Save()
    outcome = run_cli(["validate", str(tmp_path / "asset.usda")])
    assert outcome.code == 1 and "at most 1000 layers" in outcome.stdout, outcome.stdout


def test_crescent_sigma_nan_named_with_the_file_and_the_key(tmp_path):
    material = {"preset": "paper-table1", "crescent_sigma_deg": float("nan")}
    recipe = recipe_file(tmp_path, material=material)
    convert_refused(tmp_path, recipe, f"{recipe}: material.crescent_sigma_deg: must be finite")


@pytest.mark.filterwarnings("error::RuntimeWarning")  # numpy's "overflow encountered in cast"
@pytest.mark.parametrize("value", [1e308, 1e39, -1e39])
@pytest.mark.parametrize(
    "key, material",
    [
        ("material.crescent_sigma_deg", lambda v: {"crescent_sigma_deg": v}),
        ("material.rod_length_um", lambda v: {"rod_length_um": v}),
        ("material.melanin_color", lambda v: {"melanin_color": [0.1, v, 0.1]}),
        (
            "material.class.0.long.interval",
            lambda v: {"class": {"0": {"long": {"interval": [v, 0.2]}}}},
        ),
    ],
)
def test_numbers_beyond_float32_are_one_line_errors_without_numpy_warnings(
    tmp_path, key, material, value
):
    """Values finite as doubles but beyond float32 (what USD stores; a cast made them inf with
    numpy's "overflow encountered in cast" warning) get the same one-line error as any other
    out-of-range value, naming the recipe and the key, and no warning."""
    recipe = recipe_file(tmp_path, material={"preset": "paper-table1", **material(value)})
    line = convert_refused(tmp_path, recipe, f"{recipe}: {key}")
    assert "must" in line and "inf" not in line, line


@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_parameters_beyond_float32_are_refused_by_validate_without_numpy_warnings():
    from pavonine.materials.parameters import ParameterError, f32, preset

    assert f32(1e39) == np.inf and f32(-1e308) == -np.inf and f32(10**400) == np.inf
    assert f32(3.4028235e38) == float(np.finfo(np.float32).max)  # rounds down, not to inf
    with pytest.raises(ParameterError, match="crescent_sigma_deg: must be finite"):
        preset("paper-table1").with_(crescent_sigma_deg=1e308).validate()


@pytest.mark.mitsuba
def test_crescent_sigma_nan_in_usd_render_names_the_layer_and_attribute(tmp_path):
    from pxr import Usd

    from pavonine.materials.parameters import ParameterError, preset
    from pavonine.schemas.authoring import (
        create_feather_material,
        parameter_input_error,
        read_feather_parameters,
    )

    stage = Usd.Stage.CreateNew(str(tmp_path / "asset.usda"))
    material = create_feather_material(stage, "/Feather", preset("paper-table1"), {})
    material.GetPrim().GetAttribute("pavonine:crescentSigma").Set(float("nan"))
    stage.GetRootLayer().Save()
    with pytest.raises(ParameterError) as caught:
        read_feather_parameters(material).validate()
    error = parameter_input_error(material.GetPrim(), caught.value)
    assert error.where == f"{tmp_path / 'asset.usda'}: /Feather.pavonine:crescentSigma"


@pytest.mark.mitsuba
@pytest.mark.parametrize(
    "attribute, value, type_name, reason",
    [
        ("pavonine:long:rodRadius", [(0.05, 0.05)], "Float2Array", "has 1 class;"),
        ("pavonine:crescentSigma", "wide", "String", "is authored as string"),
    ],
)
def test_bad_arrays_and_types_in_a_sublayer_name_that_layer_and_the_attribute(
    tmp_path, attribute, value, type_name, reason
):
    """Errors the reader raises itself (it names the USD attribute) reach the user with the layer
    that authors the value, not the stage's root layer, and the attribute named once."""
    from pxr import Sdf, Usd

    from pavonine.materials.parameters import ParameterError, preset
    from pavonine.schemas.authoring import (
        create_feather_material,
        parameter_input_error,
        read_feather_parameters,
    )

    stage = Usd.Stage.CreateNew(str(tmp_path / "asset.usda"))
    create_feather_material(stage, "/Feather", preset("paper-table1"), {})
    stage.GetRootLayer().Save()
    override = Sdf.Layer.CreateNew(str(tmp_path / "override.usda"))
    prim = Sdf.CreatePrimInLayer(override, "/Feather")
    prim.specifier = Sdf.SpecifierOver
    Sdf.AttributeSpec(prim, attribute, getattr(Sdf.ValueTypeNames, type_name)).default = value
    override.Save()
    scene = Sdf.Layer.CreateNew(str(tmp_path / "scene.usda"))
    scene.subLayerPaths[:] = [override.identifier, str(tmp_path / "asset.usda")]
    scene.Save()
    composed = Usd.Stage.Open(scene.identifier)
    material = composed.GetPrimAtPath("/Feather")
    with pytest.raises(ParameterError) as caught:
        read_feather_parameters(material).validate()
    error = parameter_input_error(material, caught.value)
    assert error.where == f"{tmp_path / 'override.usda'}: /Feather.{attribute}"
    assert error.message.startswith(reason), error.message


# ------------------------------------------------------------------------------------ maps
def test_map_symlink_loop_fifo_and_dev_zero(tmp_path):
    odd = odd_files(tmp_path / "odd")
    for kind, needle in (
        ("loop", "symbolic link loop"),
        ("fifo", "is a FIFO"),
        ("dev_zero", "is a device"),
    ):
        maps = write_maps(tmp_path / f"maps_{kind}", 16, 32)
        (maps / "ocellar.png").unlink()
        (maps / "ocellar.png").symlink_to(odd[kind])
        line = convert_refused(tmp_path, recipe_file(tmp_path, maps), needle, 20)
        assert "maps.ocellar" in line


def test_six_4000x1_maps_refused_before_the_atlas(tmp_path):
    """The maps' height is the feather's length: 4000x1 asks for a vane 4000 times wider than
    long, which xatlas charted without end."""
    maps = write_maps(tmp_path / "maps", 4000, 1)
    convert_refused(tmp_path, recipe_file(tmp_path, maps), "4000x1 pixels", 30)


def test_maps_wider_than_8_to_1_refused(tmp_path):
    maps = write_maps(tmp_path / "maps", 400, 40)
    convert_refused(tmp_path, recipe_file(tmp_path, maps), "width:height must lie in", 30)


def test_six_30000x30000_maps_refused_before_decoding(tmp_path, huge_pngs):
    """A 4 MB PNG of 900 M pixels: refused from its header (it ended in MemoryError after 7 GB)."""
    maps = tmp_path / "maps"
    maps.mkdir()
    for name in MAP_NAMES:
        (maps / f"{name}.png").symlink_to(huge_pngs["30000"])
    line = convert_refused(tmp_path, recipe_file(tmp_path, maps), "pixel budget", 30)
    assert "30000x30000: 900,000,000 pixels" in line and "maps.alpha" in line


def test_pixel_budget_override_by_environment(tmp_path, monkeypatch):
    maps = write_maps(tmp_path / "maps", 16, 32)
    monkeypatch.setenv(limits.MAX_PIXELS_ENV, "100")
    convert_refused(tmp_path, recipe_file(tmp_path, maps), "exceed the pixel budget of 100 ")
    monkeypatch.setenv(limits.MAX_PIXELS_ENV, "lots")
    with pytest.raises(InputError, match="PAVONINE_MAX_PIXELS"):
        limits.max_pixels()


def test_pixel_budget_override_by_flag(tmp_path, huge_pngs):
    refused(["compare", "--max-pixels", "10", str(huge_pngs["20000"]), str(huge_pngs["20000"])],
            "pixel budget of 10 ")  # fmt: skip


@pytest.mark.parametrize("decorator", ["max_pixels_option", "limit_options"])
@pytest.mark.parametrize("fails", [False, True], ids=["succeeds", "fails"])
def test_pixel_budget_lasts_as_long_as_the_command(monkeypatch, decorator, fails):
    """Both ways a command takes ``--max-pixels`` apply it through one helper
    (``apply_pixel_budget``): in force while the command runs, the budget before restored after
    it, also when it fails (commands run in-process by tests and tools must not inherit it)."""
    import click
    from click.testing import CliRunner

    from pavonine.apps.cli.limits import limit_options
    from pavonine.apps.cli.values import max_pixels_option

    monkeypatch.delenv(limits.MAX_PIXELS_ENV, raising=False)
    seen = []

    def body(**kwargs) -> None:
        seen.append(limits.max_pixels())
        if fails:
            raise InputError("x.png", "bad input")

    wrap = {"max_pixels_option": max_pixels_option, "limit_options": limit_options}[decorator]
    command = click.command()(wrap(body))
    for flag, expected in (("77", 77), ("0", 2**62)):
        if flag == "0" and decorator == "max_pixels_option":
            continue  # 0 (no budget) is only for the render ceilings' flag
        result = CliRunner().invoke(command, ["--max-pixels", flag])
        assert seen[-1] == expected, result.output
        assert (result.exit_code != 0) == fails, result.output
        assert limits.max_pixels() == limits.DEFAULT_MAX_PIXELS
    with limits.pixel_budget(1234):  # nested in a caller's budget: that one comes back
        CliRunner().invoke(command, ["--max-pixels", "55"])
        assert seen[-1] == 55 and limits.max_pixels() == 1234
    assert limits.max_pixels() == limits.DEFAULT_MAX_PIXELS


def test_pixel_budget_is_reset_after_a_real_command_refused_by_it(tmp_path, monkeypatch):
    from click.testing import CliRunner

    from pavonine.apps.cli import cli

    monkeypatch.delenv(limits.MAX_PIXELS_ENV, raising=False)
    png = real_png(tmp_path / "small.png", 16, 16)
    for args in (["compare", "--max-pixels", "10", str(png), str(png)],
                 ["render", "--max-pixels", "10", str(tmp_path / "missing.usda")]):  # fmt: skip
        result = CliRunner().invoke(cli, args)
        assert result.exit_code == 2, result.output
        assert limits.max_pixels() == limits.DEFAULT_MAX_PIXELS


def test_pixel_budget_survives_a_usage_error_and_the_garbage_collector(monkeypatch):
    """``validate --max-pixels 5`` without a path is a usage error found after the option was
    parsed: its budget must not outlive that command, and nothing it left behind may later put an
    old budget back in the middle of another command (the garbage collector once did: a budget
    set as a parameter callback, restored by an abandoned generator's ``finally`` at collection,
    made ``validate --max-pixels 100`` miss its maps now and then in the full suite)."""
    import gc

    from click.testing import CliRunner

    from pavonine.apps.cli import cli

    monkeypatch.delenv(limits.MAX_PIXELS_ENV, raising=False)
    result = CliRunner().invoke(cli, ["validate", "--max-pixels", "5"])
    assert result.exit_code == 2, result.output
    assert limits.max_pixels() == limits.DEFAULT_MAX_PIXELS
    with limits.pixel_budget(100):
        gc.collect()
        assert limits.max_pixels() == 100
    assert limits.max_pixels() == limits.DEFAULT_MAX_PIXELS


def test_map_header_declaring_far_more_pixels_than_it_holds(tmp_path):
    from pavonine.base.map_files import read_map

    odd = odd_files(tmp_path)
    with time_limit(20), pytest.raises(InputError, match="pixel budget"):
        read_map(odd["huge_header"], "maps.alpha")


def test_map_with_nan_pixels_names_the_file_and_field(tmp_path):
    from hostile import MapSpec

    from pavonine.base.map_files import read_map

    path = MapSpec(8, 8, 1, "float", ".exr", nans=3).write(tmp_path / "nan")
    with pytest.raises(InputError) as caught:
        read_map(path, "maps.gradation")
    assert str(caught.value) == f"{path}: maps.gradation: contains NaN or infinite values"


def _float_exr(path: Path, pixels: np.ndarray) -> Path:
    import OpenImageIO as oiio

    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), oiio.ImageSpec(pixels.shape[1], pixels.shape[0], 1, "float"))
    out.write_image(pixels.astype(np.float32)[..., None].copy())
    out.close()
    return path


@pytest.mark.parametrize(("value", "words"), [(-3.0, "min -3, max 0.5"), (7.0, "min 0.5, max 7")])
def test_float_map_out_of_range_names_the_file_and_field(tmp_path, value, words):
    """Values beyond [0, 1] are refused, not clipped; within ``RANGE_TOLERANCE`` (float round-off)
    they are read, clamped."""
    from pavonine.base.map_files import RANGE_TOLERANCE, read_map

    pixels = np.full((8, 8), value)
    pixels[0, 0] = 0.5
    path = _float_exr(tmp_path / "melanin.exr", pixels)
    with pytest.raises(InputError) as caught:
        read_map(path, "maps.melanin")
    assert str(caught.value) == f"{path}: maps.melanin: values outside [0, 1] ({words})"
    slack = RANGE_TOLERANCE / 2
    _float_exr(path, np.clip(pixels, -slack, 1 + slack))
    values = read_map(path, "maps.melanin")
    assert values.min() == 0.0 or values.max() == 1.0
    assert values.min() >= 0.0 and values.max() <= 1.0


# ----------------------------------------------------------------------------- the commands
def test_compare_of_a_30000x30000_png(huge_pngs):
    path = huge_pngs["30000"]
    refused(["compare", str(path), str(path)], f"{path}: 30000x30000: 900,000,000 pixels", 30)


def test_validate_does_not_decode_a_20000x20000_map_it_flagged(tmp_path, huge_pngs):
    from pxr import Usd

    from pavonine.materials.parameters import preset
    from pavonine.schemas.authoring import create_feather_material

    maps = {name: str(huge_pngs["20000"]) for name in MAP_NAMES}
    stage = Usd.Stage.CreateNew(str(tmp_path / "asset.usda"))
    material = create_feather_material(stage, "/Feather", preset("paper-table1"), maps)
    stage.SetDefaultPrim(material.GetPrim())
    stage.GetRootLayer().Save()
    start = time.process_time()
    with time_limit(60):
        outcome = run_cli(["validate", str(tmp_path / "asset.usda")])
    assert outcome.code == 1, outcome.stdout + outcome.stderr
    assert "20000x20000; sides must be 1..16384" in outcome.stdout
    # Decoding six 400 M-pixel maps took about 60 s of CPU; reading six headers, milliseconds.
    assert time.process_time() - start < 20


def test_seed_2_pow_70_refused_by_every_command_with_a_seed(tmp_path):
    seed = str(2**70)
    refused(["maps", "eye", "--seed", seed, "-o", str(tmp_path / "m")], "--seed")
    refused(["render", str(SHIPPED_SCENE), "--seed", seed, "-o", str(tmp_path / "r.exr")], "--seed")
    refused(["demo", "--seed", seed, "-o", str(tmp_path / "d")], "--seed")
    refused(["check-renders", "--seed", seed], "--seed")
    assert_nothing_left(tmp_path)


def test_demo_seed_minus_1(tmp_path):
    refused(
        ["demo", "--seed", "-1", "-o", str(tmp_path / "demo")], "--seed: -1 is not in the range"
    )
    assert not (tmp_path / "demo").exists()


@pytest.mark.mitsuba  # `render` checks that Mitsuba loads before it reads its options
def test_render_resolution_100000x100000(tmp_path):
    refused(
        ["render", str(SHIPPED_SCENE), "--resolution", "100000x100000", "-o", str(tmp_path / "r.exr")],
        "--resolution: 100000x100000: 10,000,000,000 pixels exceed the pixel budget",
    )  # fmt: skip
    assert_nothing_left(tmp_path)


@pytest.mark.mitsuba
@pytest.mark.convert
def test_demo_resolution_100000x100000_refused_before_painting(tmp_path):
    out = tmp_path / "demo"
    refused(["demo", "--resolution", "100000x100000", "-o", str(out)], "--resolution", 30)
    assert not out.exists()  # nothing painted, nothing converted


def test_flip_threshold_nan(tmp_path):
    refused(
        ["compare", "--flip-threshold", "nan", "a.png", "b.png"],
        "--flip-threshold: must be a finite",
    )


def test_every_float_option_refuses_nan():
    """Every float option of every command is a FiniteFloat: NaN passes ``value <= 0``."""
    import click

    from pavonine.apps.cli import COMMANDS, cli
    from pavonine.apps.cli.values import FiniteFloat

    ctx = click.Context(cli)
    floats = []
    for name in COMMANDS:
        command = cli.get_command(ctx, name)
        subcommands = getattr(command, "commands", {name: command}).values()
        for sub in subcommands:
            for param in sub.params:
                if isinstance(param.type, click.types.FloatParamType):
                    floats.append(f"{name} {param.name}")
                if isinstance(param.type, FiniteFloat):
                    assert param.type.convert("1", param, None) == 1.0
    assert floats == [], f"plain float options (NaN gets through): {floats}"


# -------------------------------------------------------------------------------- pavonine env
HOSTILE_PATHS = [
    "/opt/it's here",
    "/opt/$(touch PWNED)",
    "/opt/`touch PWNED`",
    "/opt/a\\'; touch PWNED; echo '",
    "/opt/tab\there",
    "/opt/new\nline",
    "/opt/\u2019; touch PWNED; \u2018",
    "/opt/$env:HOME",
    "/opt/%PATH%",
    "/opt/\\",
]


@pytest.mark.parametrize("shell", ["bash", "sh"])
def test_env_lines_are_shell_safe_when_evaluated(tmp_path, shell):
    """The printed lines, evaluated by the shell, set exactly the hostile value and run nothing."""
    from pavonine.schemas.plugin import env_value

    for value in HOSTILE_PATHS:
        env = {**os.environ, "PXR_PLUGINPATH_NAME": value}
        printed = subprocess.run(
            [sys.executable, "-m", "pavonine.apps.cli", "env", "--shell", "sh"],
            env=env,
            capture_output=True,
            text=True,
            check=True,
        ).stdout
        script = printed + 'printf %s "$PXR_PLUGINPATH_NAME"'
        result = subprocess.run(
            [shell, "-c", script], cwd=tmp_path, capture_output=True, text=True, check=True
        )
        assert result.stdout == env_value(existing=value)
        assert not (tmp_path / "PWNED").exists()


def _single_quoted(line: str, prefix: str, quotes: str, backslash: bool) -> str:
    """Decode ``prefix'…'`` by a shell's single-quote rule; the rest of the line must be exactly
    one string (nothing after it that the shell would run)."""
    assert line.startswith(prefix) and line[len(prefix)] in quotes, line
    text, i, out = line[len(prefix) + 1 :], 0, []
    while i < len(text):
        c = text[i]
        if backslash and c == "\\" and i + 1 < len(text) and text[i + 1] in "\\'":
            out.append(text[i + 1])
            i += 2
        elif c in quotes and not backslash and i + 1 < len(text) and text[i + 1] in quotes:
            out.append(c)
            i += 2
        elif c in quotes:
            assert i == len(text) - 1, f"the string ends before the line does: {line!r}"
            return "".join(out)
        else:
            out.append(c)
            i += 1
    raise AssertionError(f"unterminated string: {line!r}")


@pytest.mark.parametrize("value", HOSTILE_PATHS)
def test_env_quoting_for_powershell_and_fish_by_rule(value):
    """pwsh and fish are not installed here: their single-quote rules, applied to the printed
    line, must give back the value (PowerShell: every quote character, typographic ones too,
    ends a string unless doubled; fish: backslash escapes backslash and quote)."""
    from pavonine.apps.cli.env import POWERSHELL_QUOTES, assignment

    line = assignment("PXR_PLUGINPATH_NAME", value, "powershell")
    assert _single_quoted(line, "$env:PXR_PLUGINPATH_NAME = ", POWERSHELL_QUOTES, False) == value
    line = assignment("PXR_PLUGINPATH_NAME", value, "fish")
    assert _single_quoted(line, "set -gx PXR_PLUGINPATH_NAME ", "'", True) == value


# ------------------------------------------------------------------------------------ Ctrl-C
def _cpu_seconds(pid: int) -> float:
    """User + system CPU time of a running process (Linux ``/proc``)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def test_ctrl_c_is_one_line_and_exit_130(tmp_path):
    out = tmp_path / "maps"
    proc = subprocess.Popen(
        [sys.executable, "-m", "pavonine.apps.cli", "maps", "eye", "--size", "4096", "-o", str(out)],
        stderr=subprocess.PIPE,
        text=True,
    )  # fmt: skip
    # Interrupt once the command is painting (about 9 s of CPU at this size), whatever the load:
    # after 2 s of CPU time its imports (under 1 s) are done.
    deadline = time.monotonic() + 120
    while _cpu_seconds(proc.pid) < 2.0 and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.1)
    proc.send_signal(signal.SIGINT)
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    lines = stderr.strip().splitlines()
    assert (
        len(lines) == 1
        and lines[0].startswith("error: ")
        and lines[0].endswith(" maps: interrupted")
    ), lines
    assert_nothing_left(out)


def console_script(tmp_path: Path) -> Path:
    """The ``pavonine`` console script as pip writes it for ``pyproject.toml``'s entry point: the
    installed one if it is current, else the same text in ``tmp_path`` (an environment installed
    before the entry point changed)."""
    import tomllib

    project = tomllib.loads((Path(__file__).parents[2] / "pyproject.toml").read_text())
    module, function = project["project"]["scripts"]["pavonine"].split(":")
    installed = Path(sys.executable).parent / "pavonine"
    if installed.exists() and f"from {module} import {function}\n" in installed.read_text():
        return installed
    script = tmp_path / "pavonine"
    script.write_text(
        f"#!{sys.executable}\nimport re\nimport sys\nfrom {module} import {function}\n"
        "if __name__ == '__main__':\n"
        "    sys.argv[0] = re.sub(r'(-script\\.pyw|\\.exe)?$', '', sys.argv[0])\n"
        f"    sys.exit({function}())\n"
    )
    script.chmod(0o755)
    return script


#: Where Pavonine's own code lives (src/, each folder its import path).
PAVONINE_CODE = [Path(__file__).parents[2] / "src" / "pavonine"]
#: Pavonine's first lines, which arm its Ctrl-C handling (pavonine/__init__.py →
#: pavonine.base.interrupt).
ARMING = ("pavonine/__init__.py", "pavonine/base/__init__.py", "pavonine/base/interrupt.py")


def _before_pavonine_code(stderr: str) -> bool:
    """True when an interrupt ended the process before Pavonine's Ctrl-C handling was armed: in
    the interpreter's own initialisation (its streams, ``site`` and the ``.pth`` files), or in
    the console script's ``from pavonine.console import main`` while importlib (and an editable
    install's finder) looks for the package and the first line of ``pavonine/__init__.py``
    imports :mod:`pavonine.base.interrupt`. No other frame may be Pavonine's code."""
    if stderr.startswith("Fatal Python error: init_"):  # init_import_site, init_sys_streams…
        return True
    if "KeyboardInterrupt" not in stderr:
        return False
    frames = re.findall(r'^\s*File "([^"]+)", line \d+, in (\S+)', stderr, flags=re.MULTILINE)
    for file, where in frames:
        path = Path(file).resolve()
        if any(path.is_relative_to(folder) for folder in PAVONINE_CODE):
            if not (file.endswith(ARMING) and where == "<module>"):
                return False
    return True


def test_ctrl_c_at_any_moment_from_start_up_is_one_line_and_exit_130(tmp_path):
    """Ctrl-C 0.02 s to 1.5 s after ``pavonine validate`` starts: while Python starts, while the
    command line and USD load (``import pavonine`` used to load USD, before any handling was in
    place: a traceback), while the command runs. Always one line and exit 130, or exit 0 if it
    had finished; never a traceback, never a USD warning swallowing the interrupt.

    Before Pavonine's first line runs, Python's own start-up (``site`` and the environment's
    ``.pth`` files) owns SIGINT and fails with "Fatal Python error: init_import_site", or
    importlib reports the interrupt in its own frames: accepted at any delay when no frame of the
    report is Pavonine's code past its arming lines (a loaded machine can stretch the start-up
    past any fixed delay: CI saw it at 0.5 s). A silent death by SIGINT is accepted only for a
    delay shorter than twice the start-up of a bare interpreter with the same ``site``, measured
    here."""
    script = console_script(tmp_path)
    asset = Path(__file__).parents[2] / "assets" / "feathers" / "eye_feather" / "eye_feather.usd"
    starts = []
    for _ in range(3):
        began = time.monotonic()
        subprocess.run([sys.executable, "-c", "pass"], check=True)
        starts.append(time.monotonic() - began)
    python_start_up = 2 * max(starts)
    outcomes = []
    for delay in (0.02, 0.05, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5, 0.7, 1.0, 1.5):
        proc = subprocess.Popen([script, "validate", asset], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)  # fmt: skip
        time.sleep(delay)
        proc.send_signal(signal.SIGINT)
        _, stderr = proc.communicate(timeout=120)
        outcomes.append((delay, proc.returncode, stderr))
        if _before_pavonine_code(stderr):
            continue  # Python's own start-up or import machinery, before any Pavonine code
        if delay < python_start_up and proc.returncode == -signal.SIGINT and not stderr:
            continue  # Python's default SIGINT handler, before Pavonine's was installed
        assert "Traceback" not in stderr and "Tf_PyPostProcessModule" not in stderr, (delay, stderr)
        if proc.returncode == 0:
            continue  # finished before the interrupt
        lines = stderr.strip().splitlines()
        assert proc.returncode == 130, (delay, proc.returncode, stderr)
        assert len(lines) == 1 and lines[0].startswith("error: pavonine"), (delay, stderr)
        assert lines[0].endswith(": interrupted"), (delay, stderr)
    assert sum(code == 130 for _, code, _ in outcomes) >= 5, outcomes  # most were interrupted


def test_out_of_memory_within_the_budget_is_named_not_internal(tmp_path, monkeypatch):
    """Maps under the pixel budget may still exhaust a small machine: a MemoryError is reported
    as bad input naming the recipe, not as an "internal error"."""
    from pavonine.pipeline.convert import batch

    def exhausted(*args, **kwargs):
        raise MemoryError

    monkeypatch.setattr(batch, "load_maps", exhausted)
    result = batch._convert_safely(str(recipe_file(tmp_path)), str(tmp_path / "out"), False)
    assert result.bad_input and "out of memory" in result.error and "internal" not in result.error


def test_validate_reports_maps_over_a_lowered_pixel_budget(tmp_path):
    from pxr import Usd

    from pavonine.materials.parameters import preset
    from pavonine.schemas.authoring import create_feather_material

    maps_dir = write_maps(tmp_path / "maps", 16, 32)
    maps = {name: str(maps_dir / f"{name}.png") for name in MAP_NAMES}
    stage = Usd.Stage.CreateNew(str(tmp_path / "asset.usda"))
    material = create_feather_material(stage, "/Feather", preset("paper-table1"), maps)
    stage.SetDefaultPrim(material.GetPrim())
    stage.GetRootLayer().Save()
    outcome = run_cli(["validate", "--max-pixels", "100", str(tmp_path / "asset.usda")])
    assert outcome.code == 1
    assert "16x32: 512 pixels exceed the pixel budget of 100" in outcome.stdout


def test_max_pixels_flag_lasts_only_as_long_as_its_command(tmp_path, huge_pngs):
    refused(["compare", "--max-pixels", "10", "a.png", "b.png"], "no such file")
    assert limits.max_pixels() == limits.DEFAULT_MAX_PIXELS


def test_a_truncated_png_map_is_one_line_without_libpngs_own(tmp_path):
    """libpng prints "libpng error: …" itself while OpenImageIO decodes; the user sees one line,
    OpenImageIO's first reason (not its three lines escaped into one)."""
    maps = write_maps(tmp_path / "maps", 64, 128)
    png = maps / "ocellar.png"
    png.write_bytes(png.read_bytes()[: png.stat().st_size // 2])
    recipe = recipe_file(tmp_path, maps)
    out = tmp_path / "out"
    done = subprocess.run(
        [sys.executable, "-m", "pavonine.apps.cli", "convert", str(recipe), "-o", str(out)],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert done.returncode == 2, done.stderr
    assert done.stderr.startswith("error: ") and done.stderr.count("\n") == 1, done.stderr
    assert re.search(
        f"{re.escape(str(png))}: maps.ocellar: (unreadable|cannot read) image \\(", done.stderr
    )
    assert "\\n" not in done.stderr
    assert_nothing_left(out)
