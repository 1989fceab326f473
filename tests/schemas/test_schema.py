"""PavonineFeatherAPI: generation, registration, fallbacks, authoring round trip."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import pavonine  # noqa: F401  (registers the plugin before any stage exists)
from pavonine.materials.parameters import (
    FeatherParameters,
    LayerStack,
    OcellarClass,
    ParameterError,
    preset,
)
from pavonine.schemas import generate, plugin
from pavonine.schemas.authoring import (
    DISPLACEMENT_HEIGHT_ATTR,
    MAP_ATTRS,
    create_feather_material,
    read_feather_parameters,
    resolve_maps,
)

ROOT = Path(__file__).resolve().parents[2]
DATA = Path(__file__).resolve().parents[1] / "data" / "schema"
DOCS = ROOT / "docs" / "schema.md"


def run_python(code: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    """Run ``code`` in a fresh interpreter (USD's registries are per process)."""
    base = {k: v for k, v in os.environ.items() if k != "PXR_PLUGINPATH_NAME"}
    base.update(env or {})
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=base, check=False
    )


def docs_example() -> str:
    """The hand-written ``usda`` example of docs/schema.md."""
    blocks = re.findall(r"```usda\n(.*?)```", DOCS.read_text(), flags=re.S)
    assert blocks, "docs/schema.md has no ```usda example"
    return blocks[0]


# --- generation ------------------------------------------------------------------------------


def test_generated_files_are_fresh():
    assert generate.stale_files() == [], "run: python -m pavonine.schemas.generate"


def test_schema_source_fallbacks_match_parameters():
    assert generate.source_mismatches() == []


def test_stale_detection_notices_an_edit(tmp_path):
    for name in generate.GENERATED:
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text((plugin.PLUGIN_DIR / name).read_text())
    assert generate.stale_files(tmp_path) == []
    edited = (tmp_path / "generatedSchema.usda").read_text().replace("= 15", "= 16", 1)
    (tmp_path / "generatedSchema.usda").write_text(edited)
    assert generate.stale_files(tmp_path) == ["generatedSchema.usda"]


def test_schema_plugin_declares_only_the_schema_and_validators_live_apart():
    text = plugin.PLUG_INFO.read_text()
    assert "@PLUG_INFO" not in text
    info = json.loads(text)
    assert [p["Name"] for p in info["Plugins"]] == ["pavonine"]
    schema = info["Plugins"][0]
    assert schema["Type"] == "resource" and "Validators" not in schema["Info"]
    assert schema["Info"]["Types"]["PavonineFeatherAPI"]["schemaKind"] == "singleApplyAPI"
    validators = json.loads(plugin.VALIDATORS_PLUG_INFO.read_text())["Plugins"]
    assert [p["Name"] for p in validators] == [plugin.VALIDATOR_PLUGIN_NAME]
    assert validators[0]["Type"] == "python"
    assert set(validators[0]["Info"]["Validators"]) == set(generate.VALIDATORS)
    assert plugin.VALIDATORS_DIR != plugin.PLUGIN_DIR


# --- the schema contract -----------------------------------------------------------------------


def test_schema_definition_fallbacks_docs_and_units():
    from pxr import Usd

    definition = Usd.SchemaRegistry().FindAppliedAPIPrimDefinition("PavonineFeatherAPI")
    assert definition is not None
    expected = generate.fallback_values()
    names = set(definition.GetPropertyNames())
    assert set(expected) | {a for a in MAP_ATTRS.values()} | {DISPLACEMENT_HEIGHT_ATTR} == names
    assert definition.GetAttributeFallbackValue(DISPLACEMENT_HEIGHT_ATTR) == 0.0
    for name, value in expected.items():
        fallback = definition.GetAttributeFallbackValue(name)
        assert generate._flat(fallback) == generate._flat(value), name
    for name in names:
        brief = definition.GetPropertyDefinition(name).GetDocumentation()
        assert len(brief) > 20, name
        if "layerInterval" in name or "rodRadius" in name or name == "pavonine:rodLength":
            assert "(um" in brief, f"{name} documents no unit: {brief}"
        if "Sigma" in name:
            assert "degrees" in brief, name
    assert definition.GetAttributeFallbackValue("pavonine:blockSigma") == 8.0


def test_fallbacks_are_paper_table1():
    from pxr import Usd, UsdShade

    stage = Usd.Stage.CreateInMemory()
    material = UsdShade.Material.Define(stage, "/M")
    material.GetPrim().ApplyAPI("PavonineFeatherAPI")
    assert read_feather_parameters(material) == preset("paper-table1")


def test_api_only_appliable_to_material():
    from pxr import Usd, UsdShade

    stage = Usd.Stage.CreateInMemory()
    material = UsdShade.Material.Define(stage, "/M").GetPrim()
    mesh = stage.DefinePrim("/Mesh", "Mesh")
    assert material.CanApplyAPI("PavonineFeatherAPI")
    assert not mesh.CanApplyAPI("PavonineFeatherAPI")


# --- registration order, other processes -------------------------------------------------------

_PROBE = """
from pxr import Usd
stage = Usd.Stage.Open({path!r})
prim = stage.GetPrimAtPath("/Feather")
print(prim.HasAPI("PavonineFeatherAPI"), prim.GetTypeName(),
      prim.GetAttribute("pavonine:melaninIndex").Get(),
      prim.GetAttribute("pavonine:crescentSigma").Get(),
      prim.GetAttribute("pavonine:long:layerInterval").Get())
"""


def test_registering_after_a_stage_exists_silently_fails():
    code = f"""
from pxr import Plug, Usd
Usd.Stage.Open({str(DATA / "minimal_feather.usda")!r})
Plug.Registry().RegisterPlugins({str(plugin.PLUG_INFO)!r})
print(Usd.SchemaRegistry().FindAppliedAPIPrimDefinition("PavonineFeatherAPI") is None)
from pavonine.schemas.plugin import require_schema, SchemaNotRegisteredError
try:
    require_schema()
except SchemaNotRegisteredError as exc:
    print("raised:", exc)
"""
    result = run_python(code)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0] == "True"
    assert lines[1].startswith("raised:") and "pavonine env" in lines[1]


def test_import_pavonine_first_defines_the_schema():
    code = "import pavonine\n" + _PROBE.format(path=str(DATA / "minimal_feather.usda"))
    result = run_python(code)
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("True Material 2.0 12.5 [(0.19, 0.17)]")


_DEFINED = (
    "print(Usd.SchemaRegistry().FindAppliedAPIPrimDefinition('PavonineFeatherAPI') is not None)"
)


@pytest.mark.parametrize(
    "before",
    [
        "import pavonine\nassert 'pxr' not in sys.modules  # import pavonine does not load USD",
        "from pxr import Plug\nimport pavonine",  # pxr first, no registry yet: registered at once
        "import importlib.util, pavonine\nassert importlib.util.find_spec('pxr')  # a probe only",
        "import pavonine, pavonine\nfrom pxr import Sdf",
    ],
    ids=["pavonine-then-usd", "pxr-then-pavonine", "probe-then-usd", "sdf-first"],
)
def test_the_schema_is_registered_before_any_use_of_usd_whatever_the_import_order(before):
    code = f"import sys\n{before}\nfrom pxr import Usd\n{_DEFINED}\n" + _PROBE.format(
        path=str(DATA / "minimal_feather.usda")
    )
    result = run_python(code)
    assert result.returncode == 0, result.stderr
    assert result.stdout.splitlines()[0] == "True", result.stdout
    assert result.stdout.splitlines()[1].startswith("True Material 2.0 12.5"), result.stdout


def test_ctrl_c_while_usd_loads_is_held_until_the_module_is_complete():
    """USD's module loader turns an exception raised inside it into a printed warning: a Ctrl-C
    while ``pxr`` loads was lost (the program ran on) or left a half-made module. It is held
    and raised once the module is complete; the module is then usable."""
    code = f"""
import os, signal, threading, pavonine
threading.Timer(0.03, os.kill, (os.getpid(), signal.SIGINT)).start()
try:
    from pxr import Usd
    print("not interrupted")
except KeyboardInterrupt:
    print("interrupted")
from pxr import Usd
{_DEFINED}
print(signal.getsignal(signal.SIGINT) is signal.default_int_handler)
"""
    result = run_python(code)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["interrupted", "True", "True"], result.stdout
    assert "Tf_PyPostProcessModule" not in result.stderr and not result.stderr.strip()


def test_stage_without_plugin_loads_keeps_values_plain_material():
    result = run_python(_PROBE.format(path=str(DATA / "minimal_feather.usda")))
    assert result.returncode == 0, result.stderr
    # Unknown API ignored; authored values kept; no fallbacks (melaninIndex not authored).
    assert result.stdout.split(" ", 4) == ["False", "Material", "None", "12.5", "[(0.19, 0.17)]\n"]
    keep = run_python(
        "from pxr import Usd\n"
        f"s = Usd.Stage.Open({str(DATA / 'minimal_feather.usda')!r})\n"
        "print(list(s.GetPrimAtPath('/Feather').GetMetadata('apiSchemas').GetAppliedItems()))"
    )
    assert keep.stdout.strip() == "['PavonineFeatherAPI']"


def test_env_line_makes_schema_visible_to_a_process_without_pavonine(tmp_path):
    from pxr import Usd

    stage = Usd.Stage.CreateNew(str(tmp_path / "asset.usda"))
    create_feather_material(stage, "/Feather", preset("blue"))
    stage.GetRootLayer().Save()
    env_line = subprocess.run(
        [sys.executable, "-m", "pavonine.apps.cli", "env"],
        capture_output=True,
        text=True,
        env={k: v for k, v in os.environ.items() if k != "PXR_PLUGINPATH_NAME"},
        check=True,
    ).stdout.strip()
    match = re.match(r"export PXR_PLUGINPATH_NAME=(\S+)\n", env_line)
    assert match, env_line
    assert match.group(1) == str(plugin.PLUGIN_DIR)  # the schema only, not the validators
    code = _PROBE.format(path=str(tmp_path / "asset.usda")) + (
        "import sys; print('pavonine' in sys.modules)\n"
        "d = Usd.SchemaRegistry().FindAppliedAPIPrimDefinition('PavonineFeatherAPI')\n"
        "print(d.GetAttributeFallbackValue('pavonine:blockSigma'))\n"
    )
    result = run_python(code, env={"PXR_PLUGINPATH_NAME": match.group(1)})
    assert result.returncode == 0, result.stderr
    first, imported, block = result.stdout.splitlines()
    assert first.startswith("True Material 2.0 15.0 [(0.15, 0.15)]")
    assert imported == "False"
    assert block == "8.0"
    # A hand-written layer there: unauthored values come from the schema fallbacks.
    minimal = run_python(
        _PROBE.format(path=str(DATA / "minimal_feather.usda")),
        env={"PXR_PLUGINPATH_NAME": match.group(1)},
    )
    assert minimal.stdout.startswith("True Material 2.0 12.5 [(0.19, 0.17)]"), minimal.stderr


def test_env_appends_to_existing_value():
    value = plugin.env_value(os.pathsep.join(["/opt/a", "/opt/b"]))
    assert value.split(os.pathsep) == ["/opt/a", "/opt/b", str(plugin.PLUGIN_DIR)]
    assert plugin.env_value(value) == value


# --- authoring API -----------------------------------------------------------------------------


def test_docs_example_reads_back_exactly_with_schema_fallbacks(tmp_path):
    from pxr import Usd

    path = tmp_path / "example.usda"
    path.write_text(docs_example())
    stage = Usd.Stage.Open(str(path))
    params = read_feather_parameters(stage.GetPrimAtPath("/Feather"))
    stack = params.classes[0]
    assert len(params.classes) == 1
    assert stack.long == (LayerStack(0.19, 0.07, 4), LayerStack(0.17, 0.065, 6))
    assert stack.short == (LayerStack(0.15, 0.065, 10), LayerStack(0.15, 0.065, 12))
    assert params.crescent_sigma_deg == 12.5
    assert params.interference == "intensity"
    defaults = preset("paper-table1")
    assert params.melanin_index == defaults.melanin_index == 2.0
    assert params.block_sigma_deg == defaults.block_sigma_deg
    assert params.melanin_color == defaults.melanin_color
    params.validate()


def test_round_trip_presets_through_a_file(tmp_path):
    from pxr import Usd

    path = tmp_path / "feathers.usda"
    stage = Usd.Stage.CreateNew(str(path))
    names = ("paper-table1", "freyer2020", "yellow", "blue")
    for name in names:
        create_feather_material(stage, f"/Looks/{name.replace('-', '_')}", preset(name))
    stage.GetRootLayer().Save()
    reopened = Usd.Stage.Open(str(path))
    for name in names:
        prim = reopened.GetPrimAtPath(f"/Looks/{name.replace('-', '_')}")
        assert read_feather_parameters(prim) == preset(name)


_len = st.floats(min_value=0.05, max_value=0.4, allow_nan=False)


@st.composite
def feather_parameters(draw) -> FeatherParameters:
    def stack():
        interval = draw(_len)
        radius = draw(st.floats(min_value=0.01, max_value=2 * interval / 3.1416))
        return LayerStack(interval, radius, draw(st.integers(1, 40)))

    classes = tuple(
        OcellarClass(long=(stack(), stack()), short=(stack(), stack()))
        for _ in range(draw(st.integers(1, 8)))
    )
    return FeatherParameters(
        classes=classes,
        melanin_index=draw(st.floats(1.1, 3.0)),
        medium_index=draw(st.floats(1.0, 1.1)),
        crescent_sigma_deg=draw(st.floats(1.0, 60.0)),
        block_sigma_deg=draw(st.floats(1.0, 60.0)),
        rod_length_um=draw(st.floats(0.5, 20.0)),
        interference=draw(st.sampled_from(["paper", "intensity"])),
        melanin_color=tuple(draw(st.floats(0.0, 1.0)) for _ in range(3)),
    )


@settings(max_examples=15, deadline=None)
@given(params=feather_parameters())
def test_round_trip_is_exact(params):
    from pxr import Sdf, Usd

    stage = Usd.Stage.CreateInMemory()
    material = create_feather_material(stage, "/Feather", params)
    assert read_feather_parameters(material) == params
    # and through the text format
    text = stage.GetRootLayer().ExportToString()
    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.ImportFromString(text)
    again = Usd.Stage.Open(layer)
    assert read_feather_parameters(again.GetPrimAtPath("/Feather")) == params


def test_create_rejects_bad_parameters_and_maps():
    from pxr import Usd

    stage = Usd.Stage.CreateInMemory()
    bad = preset("yellow").with_(
        classes=(
            OcellarClass(
                long=(LayerStack(0.1, 0.08, 4),) * 2, short=(LayerStack(0.1, 0.05, 4),) * 2
            ),
        )
    )
    with pytest.raises(ParameterError, match="rods overlap"):
        create_feather_material(stage, "/A", bad)
    with pytest.raises(ParameterError, match="unknown map"):
        create_feather_material(stage, "/B", preset("blue"), {"albedo": "./maps/a.png"})
    fractional = preset("yellow").with_(
        classes=(
            OcellarClass(
                long=(LayerStack(0.19, 0.07, 4.5),) * 2, short=(LayerStack(0.15, 0.065, 4),) * 2
            ),
        )
    )
    with pytest.raises(ParameterError, match="whole layer counts"):
        create_feather_material(stage, "/C", fractional)


def test_maps_and_bound_shaders(tmp_path):
    from pxr import Sdf, Usd, UsdShade

    from pavonine.materials.materialx import NODEDEF

    stage = Usd.Stage.CreateNew(str(tmp_path / "sub" / "asset.usda"))
    maps = {"alpha": "./maps/alpha.png", "ocellar": "./maps/ocellar.png"}
    material = create_feather_material(stage, "/Feather", preset("paper-table1"), maps)
    stage.GetRootLayer().Save()
    prim = material.GetPrim()
    assert prim.GetAttribute("pavonine:alphaMap").Get() == Sdf.AssetPath("./maps/alpha.png")
    assert prim.GetAttribute("pavonine:alphaMap").GetColorSpace() == "raw"
    resolved = resolve_maps(material)
    assert resolved["alpha"] == str(tmp_path / "sub" / "maps" / "alpha.png")
    assert resolved["ocellar"] == str(tmp_path / "sub" / "maps" / "ocellar.png")
    assert resolved["gradation"] is None and resolved["melanin"] is None
    (tmp_path / "sub" / "maps").mkdir()
    (tmp_path / "sub" / "maps" / "alpha.png").write_bytes(b"")
    reopened = Usd.Stage.Open(str(tmp_path / "sub" / "asset.usda"))
    assert resolve_maps(reopened.GetPrimAtPath("/Feather"))["alpha"] == str(
        tmp_path / "sub" / "maps" / "alpha.png"
    )

    mtlx = material.ComputeSurfaceSource("mtlx")[0]
    preview = material.ComputeSurfaceSource()[0]
    assert mtlx.GetShaderId() == NODEDEF
    assert preview.GetShaderId() == "UsdPreviewSurface"
    assert tuple(mtlx.GetInput("class3_long_layer_interval").Get()) == pytest.approx((0.23, 0.17))
    assert mtlx.GetInput("melanin_index").Get() == 2.0
    texture = UsdShade.Shader(stage.GetPrimAtPath("/Feather/AlphaTexture"))
    assert texture.GetInput("sourceColorSpace").Get() == "raw"
    diffuse = preview.GetInput("diffuseColor").Get()
    assert all(0.0 <= c <= 1.0 for c in diffuse) and max(diffuse) > 0.0


def test_preview_colour_follows_the_optics():
    from pxr import Usd, UsdShade

    stage = Usd.Stage.CreateInMemory()
    colours = {}
    for name in ("yellow", "blue"):
        material = create_feather_material(stage, f"/{name}", preset(name))
        shader = UsdShade.Material(material).ComputeSurfaceSource()[0]
        colours[name] = tuple(shader.GetInput("diffuseColor").Get())
    yellow, blue = colours["yellow"], colours["blue"]
    assert yellow[0] > yellow[2] and blue[2] > blue[0]


def test_removing_the_alpha_map_disconnects_the_preview_opacity():
    from pxr import Usd, UsdShade

    from pavonine.schemas.authoring import MAP_ATTRS, sync_derived_shaders

    stage = Usd.Stage.CreateInMemory()
    material = create_feather_material(
        stage, "/Feather", preset("paper-table1"), {"alpha": "a.png"}
    )
    preview = UsdShade.Material(material).ComputeSurfaceSource()[0]
    assert preview.GetInput("opacity").HasConnectedSource()
    material.GetPrim().GetAttribute(MAP_ATTRS["alpha"]).Clear()
    sync_derived_shaders(material)
    opacity = preview.GetInput("opacity")
    assert not opacity.HasConnectedSource() and opacity.Get() == 1.0
    assert not any(
        prim.GetName() in ("TexCoordReader", "AlphaTexture")
        for prim in Usd.PrimRange(material.GetPrim())
    )
