"""Feather recipes: defaults, overrides, and one-line errors naming the file and the key."""

from __future__ import annotations

import dataclasses

import pytest

from pavonine.base.errors import InputError
from pavonine.materials.parameters import freyer_class, preset
from pavonine.pipeline.convert.recipe import GeometryOptions, LodTargets, asset_seed, parse_recipe

MINIMAL = """\
name = "eye_feather"
[maps]
alpha = "m/alpha.png"
ocellar = "m/ocellar.png"
gradation = "m/gradation.png"
angle = "m/angle.png"
displacement = "m/displacement.png"
melanin = "m/melanin.png"
[material]
preset = "paper-table1"
"""


def _write(tmp_path, text: str, name: str = "r.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def _error(tmp_path, text: str) -> InputError:
    path = _write(tmp_path, text)
    with pytest.raises(InputError) as info:
        parse_recipe(path)
    assert str(path) in str(info.value)
    assert "\n" not in str(info.value)
    return info.value


def test_minimal_recipe_takes_documented_defaults(tmp_path):
    recipe = parse_recipe(_write(tmp_path, MINIMAL))
    assert recipe.name == "eye_feather"
    assert recipe.version == "1.0"
    assert recipe.maps["alpha"] == (tmp_path / "m" / "alpha.png").resolve()  # relative to recipe
    # The asset's glitter seed, unless the recipe names one, is a hash of its name.
    assert recipe.material == preset("paper-table1").with_(glitter_seed=asset_seed("eye_feather"))
    assert recipe.material.glitter == 0.0 and recipe.material.glitter_seed == 1254071087
    assert recipe.geometry == GeometryOptions()
    assert recipe.geometry.lod == LodTargets(100_000, 25_000, 5_000)


def test_overrides_reach_parameters_and_geometry(tmp_path):
    text = MINIMAL + (
        'crescent_sigma_deg = 12.5\ninterference = "intensity"\n'
        "[material.class.3.long]\ninterval = [0.22, 0.18]\ncount = 6\n"
        "[geometry]\nlength_cm = 12\nbend_cm = 0\n[geometry.lod]\nhigh = 9000\nmedium = 3000\nlow = 600\n"
    )
    recipe = parse_recipe(_write(tmp_path, text))
    params = recipe.material
    assert params.crescent_sigma_deg == pytest.approx(12.5)
    assert params.interference == "intensity"
    black, white = params.classes[3].long
    assert (black.interval, white.interval) == pytest.approx((0.22, 0.18))
    assert black.count == white.count == 6
    assert black.radius == preset("paper-table1").classes[3].long[0].radius  # untouched cell
    assert recipe.geometry.length_cm == 12 and recipe.geometry.bend_cm == 0
    assert recipe.geometry.lod == LodTargets(9000, 3000, 600)


@pytest.mark.parametrize(
    ("before", "after", "key"),
    [
        ("colour = 1\n", "", "r.toml: colour"),
        ("", "[geometry]\nlenght_cm = 3\n", "geometry.lenght_cm"),
        ("", "crescent = 3\n", "material.crescent"),
        ("", "[material.class.2.long]\nradious = 0.1\n", "material.class.2.long.radious"),
        ("", "[geometry.lod]\nultra = 5\n", "geometry.lod.ultra"),
    ],
)
def test_unknown_keys_are_rejected_naming_file_and_key(tmp_path, before, after, key):
    error = _error(tmp_path, before + MINIMAL + after)
    assert key in str(error)
    assert "unknown key" in str(error)


@pytest.mark.parametrize(
    ("extra", "key", "words"),
    [
        ("[material.class.1.short]\nradius = -0.05\n", "material.class.1.short.radius", "positive"),
        ("crescent_sigma_deg = nan\n", "material.crescent_sigma_deg", "finite"),
        ("block_sigma_deg = 80.0\n", "material.block_sigma_deg", "at most"),
        ("glitter = 1.5\n", "material.glitter", "[0, 1]"),
        ("glitter_seed = 2.5\n", "material.glitter_seed", "integer"),
        ("block_length_um = 0\n", "material.block_length_um", "positive"),
        ("[material.class.7.long]\ncount = 3\n", "material.class.7", "unknown class"),
        # rods that overlap (pi*a > 2d) are unphysical: ParameterError mapped to the recipe key
        ("[material.class.0.long]\nradius = 0.2\n", "material.class.0.long.radius", "overlap"),
        ("[geometry]\nlength_cm = -2\n", "geometry.length_cm", "positive"),
        (
            "[geometry.lod]\nhigh = 100\nmedium = 500\nlow = 100\n",
            "geometry.lod",
            "got high = 100, medium = 500, low = 100",  # the recipe's words, not a Python repr
        ),
    ],
)
def test_bad_values_name_the_key(tmp_path, extra, key, words):
    error = _error(tmp_path, MINIMAL + extra)
    assert key in str(error)
    assert words in str(error)


def test_glitter_keys_reach_the_material(tmp_path):
    text = MINIMAL + "glitter = 1.0\nglitter_seed = 77\nbarbule_width_um = 18.0\n"
    material = parse_recipe(_write(tmp_path, text)).material
    assert (material.glitter, material.glitter_seed, material.barbule_width_um) == (1.0, 77, 18.0)
    assert material.block_length_um == 25.0


def test_missing_map_key_unknown_preset_and_bad_toml(tmp_path):
    assert "maps.melanin" in str(
        _error(tmp_path, MINIMAL.replace('melanin = "m/melanin.png"\n', ""))
    )
    assert "material.preset" in str(_error(tmp_path, MINIMAL.replace("paper-table1", "ostrich")))
    assert "not valid TOML" in str(_error(tmp_path, MINIMAL + "[[[\n"))
    assert "name" in str(_error(tmp_path, MINIMAL.replace('"eye_feather"', '"eye feather"')))
    with pytest.raises(InputError, match="recipe not found"):
        parse_recipe(tmp_path / "absent.toml")


@pytest.mark.parametrize(
    ("geometry", "key"),
    [
        # 1e6 cm of cup crashed xatlas (exit 139); of bend or calamus it hung in the atlas
        ("cup_cm = 1e6", "geometry.cup_cm"),
        ("bend_cm = 1e6", "geometry.bend_cm"),
        ("calamus_cm = 1e6", "geometry.calamus_cm"),
        ("length_cm = 10\ncup_cm = 10.5", "geometry.cup_cm"),
        ("displacement_cm = 3.5", "geometry.displacement_cm"),
        ("rachis_radius_cm = 4", "geometry.rachis_radius_cm"),
        ("length_cm = 1e-9", "geometry.length_cm"),
        ("length_cm = 1e9", "geometry.length_cm"),
        ("[geometry.lod]\nhigh = 1000000000", "geometry.lod.high"),
    ],
)
def test_geometry_sizes_are_bounded(tmp_path, geometry, key):
    error = _error(tmp_path, MINIMAL + "[geometry]\n" + geometry + "\n")
    assert f"{key}: must" in str(error)


def test_geometry_bounds_are_inclusive_and_name_a_default_that_breaks_them(tmp_path):
    at_bounds = "[geometry]\nlength_cm = 10\nbend_cm = 10\ncup_cm = 10\ncalamus_cm = 10\n"
    at_bounds += "rachis_radius_cm = 1\ndisplacement_cm = 1\n"
    geometry = parse_recipe(_write(tmp_path, MINIMAL + at_bounds)).geometry
    assert (geometry.bend_cm, geometry.cup_cm, geometry.rachis_radius_cm) == (10, 10, 1)
    # a 1 cm feather keeps the default 1.5 cm bend: the error says it is the default
    error = _error(tmp_path, MINIMAL + "[geometry]\nlength_cm = 1\n")
    assert "geometry.bend_cm" in str(error) and "default" in str(error)


@pytest.mark.parametrize("count", ["4.5", "[2, 4.5]", "1e6"])
def test_layer_counts_are_whole_numbers_named_by_their_recipe_key(tmp_path, count):
    error = _error(tmp_path, MINIMAL + f"[material.class.0.long]\ncount = {count}\n")
    assert "material.class.0.long.count:" in str(error)
    assert "[" not in str(error).split("count:")[0]  # the recipe key, not class[0].long.black


def test_whole_float_layer_counts_are_accepted(tmp_path):
    recipe = parse_recipe(_write(tmp_path, MINIMAL + "[material.class.0.long]\ncount = [3.0, 7]\n"))
    black, white = recipe.material.classes[0].long
    assert (black.count, white.count) == (3, 7)


def test_a_one_item_list_is_the_same_value_at_both_ends(tmp_path):
    """``[x]`` is accepted like ``x`` (hypothesis found ``cortex = [-0.0]`` raising IndexError)."""
    text = MINIMAL + "[material.class.0]\ncortex = [0.1]\n[material.class.0.long]\ncount = [5]\n"
    cls = parse_recipe(_write(tmp_path, text)).material.classes[0]
    assert cls.cortex == pytest.approx((0.1, 0.1))
    assert (cls.long[0].count, cls.long[1].count) == (5, 5)


def test_physical_mode_keys_reach_the_material(tmp_path):
    text = MINIMAL.replace('"paper-table1"', '"freyer2020"') + (
        'lattice = "rectangular"\nmelanin_dispersion = [1.7, 20000]\nmelanin_absorption = [0.3, 250]\n'
        "keratin_dispersion = [1.55, 0]\n"
        "[material.class.2]\ncortex = [0.1, 0.12]\n"
        "[material.class.2.long]\nspacing = 0.2\nchannel = 0.04\n"
    )
    params = parse_recipe(_write(tmp_path, text)).material
    assert params.interference == "physical" and params.lattice == "rectangular"
    assert (params.melanin.cauchy_a, params.melanin.extinction) == pytest.approx((1.7, 0.3))
    assert params.melanin.extinction_scale == pytest.approx(250.0)
    assert params.keratin.cauchy_b == 0.0
    assert params.classes[2].cortex == pytest.approx((0.1, 0.12))
    assert params.classes[2].long[0].spacing == pytest.approx(0.2)
    assert params.classes[2].long[1].channel == pytest.approx(0.04)


@pytest.mark.parametrize(
    ("extra", "key"),
    [
        ("melanin_dispersion = [1.7]\n", "material.melanin_dispersion"),
        ('lattice = "hexagonal"\n', "material.lattice"),
        ("[material.class.5.long]\nspacing = 0.09\n", "material.class.5.long.spacing"),
        ("[material.class.5]\nthickness = 0.1\n", "material.class.5.thickness"),
    ],
)
def test_physical_mode_errors_name_the_key(tmp_path, extra, key):
    text = MINIMAL.replace('"paper-table1"', '"freyer2020"') + extra
    assert key in str(_error(tmp_path, text))


def test_a_class_can_take_a_measured_region_with_the_gradation_rule(tmp_path):
    text = MINIMAL.replace('"paper-table1"', '"freyer2020"') + (
        '[material.class.0]\nregion = "blue-green"\n[material.class.0.long]\ncount = 12\n'
    )
    params = parse_recipe(_write(tmp_path, text)).material
    region = freyer_class("blue-green")
    assert params.classes[0].short == region.short and params.classes[0].cortex == region.cortex
    assert params.classes[0].long[0].interval == region.long[0].interval  # cells override it
    assert [s.count for s in params.classes[0].long] == [12, 12]


@pytest.mark.parametrize("value", ['"teal"', "3"])
def test_an_unknown_region_names_the_key(tmp_path, value):
    text = MINIMAL + f"[material.class.1]\nregion = {value}\n"
    message = str(_error(tmp_path, text))
    assert "material.class.1.region: unknown region" in message and "blue-green" in message


def test_a_byte_order_mark_is_read_past(tmp_path):
    """Windows editors save UTF-8 with a byte-order mark; the recipe is the same recipe."""
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + MINIMAL.encode())
    plain = parse_recipe(_write(tmp_path, MINIMAL))
    assert dataclasses.replace(parse_recipe(path), path=plain.path) == plain


def test_form_keys_reach_the_options(tmp_path):
    from pavonine.pipeline.convert.barb_form import FormOptions

    text = MINIMAL + (
        "[geometry.form]\nenabled = false\ncamber = 0.1\nbow = 0\nbow_out = 0.05\n"
        "droop_deg = 30\nroot_jitter = 0.2\nlength_jitter = 0.25\nclump = 0.3\n"
        "clump_size = 6\nseed = 7\nfan_lift = 0.5\n"
    )
    form = parse_recipe(_write(tmp_path, text)).geometry.form
    assert form == FormOptions(False, 0.1, 0.0, 0.05, 30.0, 0.2, 0.25, 0.3, 6.0, 7, 0.5)
    assert parse_recipe(_write(tmp_path, MINIMAL)).geometry.form == FormOptions()


@pytest.mark.parametrize(
    ("extra", "key", "words"),
    [
        ("camber = 5", "geometry.form.camber", "must lie in [0, 0.2], got 5"),
        ("camber = nan", "geometry.form.camber", "finite"),
        ('camber = "0.1"', "geometry.form.camber", "expected a number"),
        ("bow = -0.1", "geometry.form.bow", "must not be negative"),
        ("bow_out = 0.5", "geometry.form.bow_out", "must lie in [0, 0.2]"),
        ("droop_deg = 90", "geometry.form.droop_deg", "must lie in [0, 80]"),
        ("droop_deg = inf", "geometry.form.droop_deg", "finite"),
        ("root_jitter = 1", "geometry.form.root_jitter", "must lie in [0, 0.3]"),
        ("length_jitter = true", "geometry.form.length_jitter", "expected a number"),
        ("length_jitter = 1", "geometry.form.length_jitter", "must lie in [0, 0.9]"),
        ("clump = 1.5", "geometry.form.clump", "must lie in [0, 1]"),
        ("clump = nan", "geometry.form.clump", "finite"),
        ('clump = "0.5"', "geometry.form.clump", "expected a number"),
        ("clump_size = 0.5", "geometry.form.clump_size", "must lie in [1, 20]"),
        ("clump_size = inf", "geometry.form.clump_size", "finite"),
        ("fan_lift = 2", "geometry.form.fan_lift", "must lie in [0, 1], got 2"),
        ("fan_lift = nan", "geometry.form.fan_lift", "finite"),
        ('fan_lift = "1"', "geometry.form.fan_lift", "expected a number"),
        ("clump_size = []", "geometry.form.clump_size", "expected a number"),
        ("seed = -1", "geometry.form.seed", "must not be negative"),
        ("seed = 1.5", "geometry.form.seed", "integer"),
        ("seed = 4294967296", "geometry.form.seed", "[0, 2147483647]"),
        ('enabled = "yes"', "geometry.form.enabled", "true or false"),
        ("clumps = 3", "geometry.form.clumps", "unknown key"),
    ],
)
def test_bad_form_keys_name_the_key(tmp_path, extra, key, words):
    error = _error(tmp_path, MINIMAL + "[geometry.form]\n" + extra + "\n")
    assert f"r.toml: {key}" in str(error) and words in str(error)


def test_form_must_be_a_table(tmp_path):
    error = _error(tmp_path, MINIMAL + "[geometry]\nform = 3\n")
    assert "geometry.form: expected a table" in str(error)
