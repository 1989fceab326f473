"""``pavonine validate``: USD's validators plus Pavonine's, one line per finding, exit codes."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import pavonine  # noqa: F401
from pavonine.apps.cli import cli
from pavonine.materials.parameters import preset
from pavonine.schemas.authoring import create_feather_material

DATA = Path(__file__).resolve().parents[1] / "data" / "schema"
DOCS = Path(__file__).resolve().parents[2] / "docs" / "schema.md"
LINE = re.compile(r"^(ERROR|WARNING) (/\S*) (\S+): (.+)$")


def run(*args: str):
    result = CliRunner().invoke(cli, ["validate", *args], catch_exceptions=False)
    return result.exit_code, result.stdout, result.stderr


def write_png(path: Path, channels: int = 1, size: int = 32, colourful: bool = False) -> str:
    import OpenImageIO as oiio

    path.parent.mkdir(parents=True, exist_ok=True)
    pixels = np.tile(np.linspace(0, 1, size, dtype=np.float32)[None, :, None], (size, 1, channels))
    if colourful:
        pixels[..., 0] = 1.0 - pixels[..., 0]
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), oiio.ImageSpec(size, size, channels, "uint8"))
    out.write_image(pixels)
    out.close()
    return str(path)


def test_docs_example_validates_clean(tmp_path):
    block = re.findall(r"```usda\n(.*?)```", DOCS.read_text(), flags=re.S)[0]
    path = tmp_path / "example.usda"
    path.write_text(block)
    code, out, err = run(str(path))
    assert (code, out) == (0, "1 file, no findings\n"), out + err
    assert block == (DATA / "minimal_feather.usda").read_text()


@pytest.mark.parametrize(
    ("name", "field", "words"),
    [
        ("negative_radius.usda", "pavonine:long:rodRadius", "class 2 black end: must be positive"),
        ("unequal_arrays.usda", "pavonine:short:layerInterval", "has 2 classes"),
        ("overlapping_rods.usda", "pavonine:long:rodRadius", "rods overlap"),
        ("missing_map.usda", "pavonine:ocellarMap", "does not exist"),
        ("not_an_image.usda", "pavonine:gradationMap", "OpenImageIO cannot read"),
        ("api_on_mesh.usda", "apiSchemas", "can only be applied to a Material"),
    ],
)
def test_bad_assets_exit_1_naming_the_field(name, field, words):
    code, out, _err = run(str(DATA / name))
    assert code == 1
    *lines, summary = out.splitlines()
    assert all(LINE.match(line) for line in lines), out
    assert re.fullmatch(r"1 file: [1-9]\d* errors?, \d+ warnings?", summary), summary
    hits = [m for m in map(LINE.match, lines) if m.group(1) == "ERROR" and m.group(3) == field]
    assert hits and any(words in m.group(4) for m in hits), out


@pytest.mark.parametrize(
    ("name", "parser_words"),
    [("truncated.usda", "Expected }"), ("broken_syntax.usda", "Expected )")],
)
def test_unreadable_usda_exits_2_with_the_parser_message(name, parser_words):
    code, out, err = run(str(DATA / name))
    assert code == 2
    assert out == "1 file: 0 errors, 0 warnings, 1 unreadable\n"
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"error: {DATA / name}: ") and parser_words in lines[0]
    assert re.search(rf"{name}:\d+:\d+:", lines[0])  # file:line:column from the parser
    assert "Traceback" not in err


def test_missing_file_exits_2():
    code, _out, err = run("/nonexistent/feather.usda")
    assert code == 2 and "no such file" in err


def authored_asset(
    tmp_path: Path, material: str = "freyer2020", **map_kwargs
) -> tuple[Path, object]:
    from pxr import Usd, UsdGeom

    maps = {
        key: f"./maps/{key}.png"
        for key in ("alpha", "ocellar", "gradation", "angle", "displacement", "melanin")
    }
    for key in maps:
        write_png(tmp_path / "maps" / f"{key}.png", **map_kwargs.get(key, {}))
    stage = Usd.Stage.CreateNew(str(tmp_path / "asset.usda"))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    material = create_feather_material(stage, "/Feather", preset(material), maps)
    stage.SetDefaultPrim(material.GetPrim())
    stage.GetRootLayer().Save()
    return tmp_path / "asset.usda", stage


def test_authored_asset_with_maps_is_clean_and_json(tmp_path):
    path, _stage = authored_asset(tmp_path)
    code, out, err = run(str(path))
    assert (code, out) == (0, "1 file, no findings\n"), out + err
    code, out, _ = run("--json", "-", str(path))
    assert code == 0 and json.loads(out) == {"files": 1, "findings": [], "unreadable": []}


def test_paper_table1_warns_about_staggered_rods_per_class_and_axis(tmp_path):
    """Table 1's class 4 short axis (d = 0.11 um, a = 0.065 um) fails d >= sqrt(3)*a: a warning in
    the paper mode naming class and axis, an error once the material is switched to physical."""
    path, stage = authored_asset(tmp_path, "paper-table1")
    code, out, _ = run("--json", "-", str(path))
    findings = json.loads(out)["findings"]
    assert code == 0
    assert [(f["severity"], f["field"]) for f in findings] == [
        ("WARNING", "pavonine:short:rodRadius")
    ]
    assert "class 4 short axis" in findings[0]["message"]
    stage.GetPrimAtPath("/Feather").GetAttribute("pavonine:interference").Set("physical")
    stage.GetRootLayer().Save()
    code, out, _ = run("--json", "-", str(path))
    errors = [f for f in json.loads(out)["findings"] if f["severity"] == "ERROR"]
    assert code == 1 and "class[4].short" in errors[0]["message"], errors


def test_drifted_derived_shader_is_an_error(tmp_path):
    path, stage = authored_asset(tmp_path)
    stage.GetPrimAtPath("/Feather").GetAttribute("pavonine:crescentSigma").Set(30.0)
    stage.GetRootLayer().Save()
    code, out, _ = run("--json", "-", str(path))
    assert code == 1
    fields = {
        (f["path"], f["field"]) for f in json.loads(out)["findings"] if f["severity"] == "ERROR"
    }
    assert ("/Feather/FeatherMtlx", "inputs:crescent_sigma") in fields
    assert ("/Feather/PreviewSurface", "inputs:roughness") in fields


def test_colour_map_warns_and_non_raw_colour_space_errors(tmp_path):
    from pxr import UsdShade

    path, stage = authored_asset(tmp_path, melanin={"channels": 3, "colourful": True})
    code, out, _ = run(str(path))
    assert code == 0 and "WARNING /Feather pavonine:melaninMap:" in out
    UsdShade.Shader(stage.GetPrimAtPath("/Feather/AlphaTexture")).GetInput("sourceColorSpace").Set(
        "sRGB"
    )
    stage.GetPrimAtPath("/Feather").GetAttribute("pavonine:gradationMap").SetColorSpace("sRGB")
    stage.GetRootLayer().Save()
    code, out, _ = run(str(path))
    assert code == 1
    assert "ERROR /Feather/AlphaTexture inputs:sourceColorSpace:" in out
    assert "ERROR /Feather pavonine:gradationMap: data map must be read raw" in out


def write_exr(path: Path, value: float, size: int = 32) -> Path:
    """A single-channel float EXR map holding ``value`` everywhere (``write_map`` would clip)."""
    import OpenImageIO as oiio

    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), oiio.ImageSpec(size, size, 1, "float"))
    out.write_image(np.full((size, size, 1), value, dtype=np.float32))
    out.close()
    return path


def use_map(stage, key: str, path: Path) -> None:
    from pxr import Sdf

    attr = stage.GetPrimAtPath("/Feather").GetAttribute(f"pavonine:{key}Map")
    attr.Set(Sdf.AssetPath(f"./maps/{path.name}"))
    stage.GetRootLayer().Save()


@pytest.mark.parametrize(
    ("key", "damage", "words"),
    [
        ("ocellar", "truncated", "OpenImageIO cannot read pixels of"),
        ("melanin", float("nan"), "contains NaN or infinite values"),
        ("melanin", -3.0, "values outside [0, 1] (min -3, max -3)"),
        ("gradation", 7.0, "values outside [0, 1] (min 7, max 7)"),
    ],
)
def test_single_channel_map_with_bad_pixels_is_an_error_naming_file_and_attribute(
    tmp_path, key, damage, words
):
    """Pixels are decoded for any channel count: a truncated PNG whose header is intact, NaN and
    out-of-range values are errors, as ``convert`` refuses them (docs/pipeline.md: in [0, 1])."""
    path, stage = authored_asset(tmp_path)
    if damage == "truncated":  # noise, so that half of the file is well past its header
        from pavonine.base.map_files import write_map

        file = tmp_path / "maps" / f"{key}.png"
        write_map(file, np.random.default_rng(1).random((32, 32)))
        data = file.read_bytes()
        file.write_bytes(data[: len(data) // 2])
    else:
        file = write_exr(tmp_path / "maps" / f"{key}.exr", damage)
        use_map(stage, key, file)
    code, out, _ = run(str(path))
    assert code == 1, out
    line = next(line for line in out.splitlines() if line.startswith("ERROR"))
    assert line.startswith(f"ERROR /Feather pavonine:{key}Map: ") and str(file) in line, out
    assert words in line, out


def test_float_map_within_the_round_off_tolerance_is_clean(tmp_path):
    from pavonine.base.map_files import RANGE_TOLERANCE

    path, stage = authored_asset(tmp_path)
    use_map(stage, "melanin", write_exr(tmp_path / "maps" / "melanin.exr", 1 + RANGE_TOLERANCE / 2))
    use_map(
        stage, "gradation", write_exr(tmp_path / "maps" / "gradation.exr", -RANGE_TOLERANCE / 2)
    )
    code, out, err = run(str(path))
    assert (code, out) == (0, "1 file, no findings\n"), out + err


@pytest.mark.parametrize(
    ("odd", "common", "alike"),
    [
        (["gradation"], 32, "alphaMap, ocellarMap, angleMap, displacementMap, melaninMap are"),
        (["angle", "displacement", "melanin"], 64, "alphaMap, ocellarMap, gradationMap are"),
    ],
)
def test_maps_of_another_size_are_named_with_their_sizes(tmp_path, odd, common, alike):
    """Each map whose size differs from most maps' (the alpha map's on a tie) is named with its
    file and size; the maps of the common size are named with theirs."""
    size = {key: 32 if common == 64 else 64 for key in odd}
    keys = ("alpha", "ocellar", "gradation", "angle", "displacement", "melanin")
    sizes = {key: {"size": size.get(key, common)} for key in keys}
    path, _stage = authored_asset(tmp_path, **sizes)
    code, out, _ = run("--json", "-", str(path))
    findings = [f for f in json.loads(out)["findings"] if f["message"].startswith("maps differ")]
    assert code == 0
    assert [(f["severity"], f["field"]) for f in findings] == [
        ("WARNING", f"pavonine:{key}Map") for key in odd
    ]
    for key, finding in zip(odd, findings, strict=True):
        odd_size = size[key]
        assert finding["message"] == (
            f"maps differ in size: {tmp_path / 'maps' / key}.png is {odd_size}x{odd_size}, "
            f"while {alike} {common}x{common}"
        )


def test_several_files_prefix_lines_and_worst_exit_wins(tmp_path):
    shutil.copy(DATA / "minimal_feather.usda", tmp_path / "good.usda")
    code, out, _ = run(str(tmp_path / "good.usda"), str(DATA / "negative_radius.usda"))
    assert code == 1 and out.startswith(f"{DATA / 'negative_radius.usda'}: ERROR /Feather")
    code, _, _ = run(str(DATA / "negative_radius.usda"), str(DATA / "truncated.usda"))
    assert code == 2


def test_junit_report_has_a_case_per_file_failing_on_errors(tmp_path):
    """--junit: read back with junitparser, the parser CI plug-ins are built on."""
    from junitparser import Error, Failure, JUnitXml

    good = tmp_path / "good.usda"
    shutil.copy(DATA / "minimal_feather.usda", good)
    files = [str(good), str(DATA / "negative_radius.usda"), str(DATA / "truncated.usda")]
    code, out, _ = run("--junit", str(tmp_path / "validate.xml"), *files)
    assert code == 2 and out.endswith("3 files: 1 error, 0 warnings, 1 unreadable\n")
    suites = list(JUnitXml.fromfile(str(tmp_path / "validate.xml")))
    assert len(suites) == 1 and suites[0].name == "pavonine validate"
    suite = suites[0]
    assert (suite.tests, suite.failures, suite.errors) == (3, 1, 1)
    cases = {case.name: case for case in suite}
    assert set(cases) == set(files)
    assert cases[str(good)].is_passed
    [failure] = cases[files[1]].result
    assert isinstance(failure, Failure) and "pavonine:long:rodRadius" in failure.message
    [error] = cases[files[2]].result
    assert isinstance(error, Error) and "Expected }" in error.message


def test_validators_are_registered_through_usd():
    from pxr import UsdValidation

    from pavonine.schemas.validation import validator_names

    registry = UsdValidation.ValidationRegistry()
    keyword = {m.name for m in registry.GetValidatorMetadataForKeyword("PavonineValidators")}
    assert keyword == set(validator_names())
    validator = registry.GetOrLoadValidatorByName(validator_names()[0])
    assert list(validator.GetMetadata().GetSchemaTypes()) == ["PavonineFeatherAPI"]


WRONG_TYPES = {
    "string pavonine:crescentSigma": '"x"',
    "string pavonine:long:rodRadius": '"x"',
    "float pavonine:long:rodRadius": "0.07",
    "string pavonine:alphaMap": '"alpha.png"',
}


@pytest.mark.parametrize("declaration", sorted(WRONG_TYPES))
def test_wrongly_typed_attribute_is_a_finding_not_a_crash(tmp_path, declaration):
    layer = tmp_path / "wrong.usda"
    layer.write_text(
        '#usda 1.0\n(\n    defaultPrim = "Feather"\n    metersPerUnit = 0.01\n    upAxis = "Y"\n)\n'
        'def Material "Feather" (\n    prepend apiSchemas = ["PavonineFeatherAPI"]\n)\n{\n'
        f"    {declaration} = {WRONG_TYPES[declaration]}\n}}\n"
    )
    result = CliRunner().invoke(cli, ["validate", str(layer)])
    name = declaration.split()[1]
    assert result.exit_code == 1, result.output
    assert result.exception is None or isinstance(result.exception, SystemExit), result.exception
    # USD's own validator names the mismatch; Pavonine's validators must not crash on it.
    assert any(
        line.startswith("ERROR") and name in line and "type" in line.lower()
        for line in result.output.splitlines()
    )
