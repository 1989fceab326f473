"""``materials/pavonine_feather.mtlx``: valid MaterialX, mirrors the schema, hue follows the class.

The hue test evaluates the shipped graph headless: its arithmetic nodes (class switch, gradation
mix, Eq. 1) are walked node by node as written in the file; the ``dielectric_bsdf`` thin film they
feed is evaluated with the Airy formula (``materialx.thin_film_reflectance``), because MaterialX's
shader generators need a GPU/OSL runtime to execute.
"""

from __future__ import annotations

import shutil
import subprocess

import MaterialX as mx
import numpy as np
import pytest

from pavonine.materials import colour, materialx
from pavonine.materials.layers import optical_distance
from pavonine.materials.parameters import preset
from pavonine.pipeline.maps.paint import ocellar_class, ocellar_grey
from pavonine.schemas.authoring import CLASS_ATTRS, SCALAR_ATTRS

WAVELENGTHS = np.arange(380.0, 781.0, 5.0)


@pytest.fixture(scope="module")
def doc():
    document = mx.createDocument()
    mx.readFromXmlFile(document, str(materialx.MTLX_PATH))
    return document


def test_shipped_file_is_current():
    assert materialx.MTLX_PATH.read_text() == materialx.document_text(), (
        "run: python -m pavonine.materials.materialx"
    )


def test_document_validates_against_standard_libraries():
    ok, message = materialx.validate_file()
    assert ok, message


@pytest.mark.skipif(shutil.which("mxvalidate") is None, reason="mxvalidate not installed")
def test_mxvalidate_passes():
    result = subprocess.run(
        ["mxvalidate", str(materialx.MTLX_PATH)], capture_output=True, text=True, check=False
    )
    assert result.returncode == 0 and "is a valid MaterialX document" in result.stdout


def test_validation_catches_a_broken_graph(tmp_path, doc):
    broken = mx.createDocument()
    broken.copyContentFrom(doc)
    broken.getNodeGraph(materialx.NODEGRAPH).getNode("long_film_thickness").getInput(
        "in1"
    ).setNodeName("no_such_node")
    path = tmp_path / "broken.mtlx"
    mx.writeToXmlFile(broken, str(path))
    ok, _message = materialx.validate_file(path)
    assert not ok


def test_graph_uses_only_standard_nodes(doc):
    libraries = materialx.load_libraries()
    for node in doc.getNodeGraph(materialx.NODEGRAPH).getNodes():
        assert libraries.getMatchingNodeDefs(node.getCategory()), node.getCategory()
        assert node.getNodeDef() is None or node.getNodeDef().getName().startswith("ND_")
    impl = doc.getNodeDef(materialx.NODEDEF).getImplementation()
    assert impl is not None and impl.getName() == materialx.NODEGRAPH


def test_nodedef_inputs_mirror_the_schema(doc):
    nodedef = doc.getNodeDef(materialx.NODEDEF)
    names = {i.getName() for i in nodedef.getActiveInputs()}
    for k in range(materialx.MAX_CLASSES):
        for axis, field in CLASS_ATTRS:
            quantity = {
                "interval": "layer_interval",
                "radius": "rod_radius",
                "count": "layer_count",
            }
            assert materialx.class_input(k, axis, quantity[field]) in names
    scalar = {
        "melanin_index", "medium_index", "crescent_sigma", "block_sigma",
        "rod_length", "interference", "melanin_color",
    }  # fmt: skip
    assert len(scalar) == len(SCALAR_ATTRS) and scalar <= names
    defaults = materialx.input_values(preset("paper-table1"))
    for name, value in defaults.items():
        written = nodedef.getInput(name).getValue()
        if isinstance(value, tuple):
            assert tuple(written) == pytest.approx(value, rel=1e-6), name
        else:
            assert written == value or written == pytest.approx(value), name


@pytest.mark.parametrize("name", ["yellow", "blue"])
def test_graph_thickness_is_eq1_optical_distance(doc, name):
    params = preset(name)
    stack = params.classes[0].long[0]
    distance_um = optical_distance(
        stack.interval, stack.radius, params.melanin_index, params.medium_index
    )
    expected_nm = materialx.FILM_ORDER_FACTOR * 1000.0 * distance_um / params.melanin_index
    assert materialx.film_thickness_nm(params, "long", doc=doc) == pytest.approx(
        expected_nm, rel=1e-9
    )


def test_class_switch_and_gradation_mix(doc):
    params = preset("paper-table1")
    # class 3 long axis: d 0.23 -> 0.17, a 0.075 (Table 1); gradation picks the interpolated stack
    for gradation in (0.0, 0.25, 1.0):
        (stack, _short) = params.stacks(3, gradation)
        distance = optical_distance(stack.interval, stack.radius)
        expected = materialx.FILM_ORDER_FACTOR * 1000.0 * distance / 2.0
        got = materialx.film_thickness_nm(
            params, "long", ocellar=float(ocellar_grey(3)), gradation=gradation, doc=doc
        )
        assert got == pytest.approx(expected, rel=1e-5)


@pytest.mark.parametrize("classes", [1, 3, 6])
def test_class_index_reads_the_ocellar_map_like_the_renderer(doc, classes):
    """The graph's class index from the ocellar grey is the one the maps define."""
    greys = np.append((np.arange(40) + 0.37) / 40, [0.0, 1.0])  # no exact ties
    expected = ocellar_class(greys, classes=classes)
    for grey, k in zip(greys, expected, strict=True):
        values = {"ocellar": float(grey), "class_count": classes}
        assert materialx.evaluate_node(doc, "class_index", values) == k, grey


def test_hue_follows_class_parameters(doc):
    rgb = {}
    peak = {}
    for name in ("yellow", "blue"):
        reflectance = materialx.graph_reflectance(preset(name), WAVELENGTHS, doc=doc)
        rgb[name] = colour.reflectance_to_linear_srgb(WAVELENGTHS, reflectance)
        peak[name] = WAVELENGTHS[np.argmax(reflectance)]
    # Multilayer first-order peak λ = 2·D (Eq. 4 at normal incidence): 600 nm and 504 nm.
    assert peak["yellow"] == pytest.approx(600.0, abs=10.0)
    assert peak["blue"] == pytest.approx(504.0, abs=10.0)
    yellow, blue = rgb["yellow"], rgb["blue"]
    assert blue[2] / blue[0] > 1.5 * (yellow[2] / yellow[0])
    assert yellow[0] > yellow[2] and blue[2] > blue[0]
    # Across Table 1, the black class (short intervals) is bluer than the white class.
    table = preset("paper-table1")
    white = colour.reflectance_to_linear_srgb(
        WAVELENGTHS, materialx.graph_reflectance(table, WAVELENGTHS, ocellar_grey(0), 0.5, doc=doc)
    )
    black = colour.reflectance_to_linear_srgb(
        WAVELENGTHS, materialx.graph_reflectance(table, WAVELENGTHS, ocellar_grey(5), 0.5, doc=doc)
    )
    assert black[2] / black[0] > white[2] / white[0]


def test_thin_film_formula_limits():
    # No film: bare substrate Fresnel reflectance ((1 - n)/(1 + n))².
    bare = materialx.thin_film_reflectance(WAVELENGTHS, 0.0, 2.0, 1.53)
    assert np.allclose(bare, ((1 - 1.53) / (1 + 1.53)) ** 2)
    # Quarter-wave film at 600 nm: maximum ((1·1.53 − n²)/(1·1.53 + n²))² there.
    quarter = materialx.thin_film_reflectance(np.array([600.0]), 600.0 / (4 * 2.0), 2.0, 1.53)
    assert quarter[0] == pytest.approx(((1.53 - 4.0) / (1.53 + 4.0)) ** 2)
