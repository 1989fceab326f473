"""benchmarks/mtlx_examples.py on a document it is given here (CI has no MaterialX checkout):
the usdMtlx-style translation reaches the renderer with its graph, file prefix and colour space,
and its ``inputs`` check finds an input that nobody translates or warns about."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

SCRIPT = Path(__file__).parents[2] / "benchmarks" / "mtlx_examples.py"

DOCUMENT = """<?xml version="1.0"?>
<materialx version="1.39" colorspace="lin_rec709" fileprefix="textures/">
  <nodegraph name="NG_tiles">
    <input name="tiling" type="vector2" value="2.0, 2.0" />
    <tiledimage name="image_color" type="color3">
      <input name="file" type="filename" value="red.png" colorspace="srgb_texture" />
      <input name="uvtiling" type="vector2" interfacename="tiling" />
    </tiledimage>
    <output name="out_color" type="color3" nodename="image_color" />
  </nodegraph>
  <standard_surface name="SR_tiles" type="surfaceshader">
    <input name="base_color" type="color3" nodegraph="NG_tiles" output="out_color" />
    <input name="specular_roughness" type="float" value="0.6" />
    <input name="subsurface" type="float" value="0.5" />
  </standard_surface>
  <surfacematerial name="Tiles" type="material">
    <input name="surfaceshader" type="surfaceshader" nodename="SR_tiles" />
  </surfacematerial>
</materialx>
"""


@pytest.fixture(scope="module")
def script():
    sys.path.insert(0, str(SCRIPT.parent))
    spec = importlib.util.spec_from_file_location("mtlx_examples", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_translation_reaches_the_renderer_and_the_inputs_check_can_fail(
    tmp_path, script, restore_variant
):
    from pxr import UsdShade
    from render_helpers import image

    from pavonine.base.backend import select_variant
    from pavonine.render.diagnostics import Diagnostics
    from pavonine.render.shading import translate_material

    select_variant()  # textures become Mitsuba objects
    (tmp_path / "textures").mkdir()
    image(tmp_path / "textures" / "red.png", np.full((4, 4, 3), (255, 0, 0), np.uint8))
    path = tmp_path / "tiles.mtlx"
    path.write_text(DOCUMENT)
    doc, names = script.materials_of(path)
    assert names == ["Tiles"]
    stage_path = tmp_path / "tiles.usda"
    script.write_stage(doc, "Tiles", stage_path)

    from pxr import Usd

    stage = Usd.Stage.Open(str(stage_path))
    tiles = stage.GetPrimAtPath("/Looks/Tiles/NG_tiles/image_color")
    assert UsdShade.Shader(tiles).GetShaderId() == "ND_tiledimage_color3"
    file = UsdShade.Shader(tiles).GetInput("file").GetAttr()
    assert file.GetColorSpace() == "srgb_texture"
    assert Path(file.Get().resolvedPath) == tmp_path / "textures" / "red.png"
    diag = Diagnostics()
    material = UsdShade.Material(stage.GetPrimAtPath("/Looks/Tiles"))
    from pavonine.render.diagnostics import StageWarning

    with pytest.warns(StageWarning, match="subsurface is not translated"):
        spec = translate_material(material, Usd.TimeCode.Default(), diag)
    base = spec.bsdf["base_color"]
    assert base["type"] == "bitmap" and "to_uv" in base  # the graph's interface tiling
    assert np.array(base["to_uv"].matrix)[0, 0] == pytest.approx(2.0)
    node_id, authored = script.authored_surface_inputs(doc, "Tiles")
    assert set(authored) == {"base_color", "specular_roughness", "subsurface"}
    assert script.dropped_inputs(node_id, authored, diag.messages) == []
    assert script.dropped_inputs(node_id, authored, []) == ["subsurface"]  # unwarned: dropped
