"""Property-based fuzzing of recipes, maps and command-line arguments (issue 14).

The property (``hostile.assert_clean``): every run ends with exit 0, or exit 1/2 with exactly
one ``error: <file or field>: <message>`` line on stderr; never a traceback, never a hang
(``hostile.time_limit``), no partial output. The generators live in ``tests/hostile.py``.

Marked ``fuzz`` (run by ``.ci/run``). Example counts are modest so that CI stays fast, and the
examples are the same on every run (derandomized), so a CI failure belongs to the change under
test, not to the day's draw. Set ``PAVONINE_FUZZ_SCALE=10`` (a multiplier) for a longer hunt:
then the examples are drawn at random, new each run.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest
from hostile import (
    CLI_ANY,
    CLI_OPTIONS,
    MAP_NAMES,
    RATTLE_KEYS,
    RECIPE_KEYS,
    TRAIN_KEYS,
    assert_clean,
    assert_nothing_left,
    map_specs,
    mutated,
    odd_files,
    odd_recipe_texts,
    run_cli,
    small_feather_recipe,
    small_rattle_recipe,
    small_train_recipe,
    time_limit,
    to_toml,
)
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pavonine.base.errors import InputError

#: A numpy warning (an overflowing cast, an invalid value) is an unhandled case: fail on it.
pytestmark = [pytest.mark.fuzz, pytest.mark.filterwarnings("error::RuntimeWarning")]

SCALE = max(1, int(os.environ.get("PAVONINE_FUZZ_SCALE", "1")))
SHIPPED_SCENE = Path(__file__).resolve().parents[2] / "assets" / "scenes" / "blue_feather_sun.usda"


def examples(count: int):
    """Hypothesis settings for ``count`` examples (× PAVONINE_FUZZ_SCALE), no deadline (the
    time limit is ``hostile.time_limit``), fixtures shared across examples; the same examples
    every run unless PAVONINE_FUZZ_SCALE asks for a hunt."""
    return settings(
        max_examples=count * SCALE,
        derandomize=SCALE == 1,
        database=None if SCALE == 1 else settings.default.database,
        deadline=None,
        suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
    )


@pytest.fixture(scope="module")
def workspace(tmp_path_factory) -> Path:
    """Six valid 16x32 maps, a component asset, odd files and a tiny EXR pair."""
    from pavonine.base.map_files import write_map

    folder = tmp_path_factory.mktemp("fuzz")
    for name in MAP_NAMES:
        write_map(
            folder / "maps" / f"{name}.png", np.full((32, 16), 1.0 if name == "alpha" else 0.5)
        )
    (folder / "eye.usda").write_text("#usda 1.0\n")
    odd_files(folder / "odd")
    return folder


def _one_line(error: InputError, path: Path) -> None:
    text = str(error)
    assert "\n" not in text and "\r" not in text, repr(text)
    assert text.startswith(str(path)), text


# ------------------------------------------------------------------------------------ recipes
@examples(150)
@given(data=st.data())
def test_feather_recipes_parse_or_fail_on_one_line(workspace, tmp_path_factory, data):
    from pavonine.pipeline.convert.recipe import parse_recipe

    table = data.draw(mutated(small_feather_recipe(workspace / "maps"), RECIPE_KEYS))
    path = tmp_path_factory.mktemp("recipe") / "r.toml"
    path.write_text(to_toml(table), encoding="utf-8")
    with time_limit(10):
        try:
            recipe = parse_recipe(path)
        except InputError as exc:
            _one_line(exc, path)
            return
    assert recipe.name == table["name"]


@examples(60)
@given(content=odd_recipe_texts)
def test_files_that_are_no_recipe_fail_on_one_line(tmp_path_factory, content):
    from pavonine.pipeline.convert.recipe import parse_recipe

    path = tmp_path_factory.mktemp("odd") / "r.toml"
    path.write_bytes(content)
    with time_limit(10), pytest.raises(InputError) as caught:
        parse_recipe(path)
    _one_line(caught.value, path)


@examples(100)
@given(data=st.data())
def test_train_recipes_parse_or_fail_on_one_line(workspace, tmp_path_factory, data):
    from pavonine.pipeline.assemble.recipe import parse_train_recipe

    table = data.draw(mutated(small_train_recipe(workspace / "eye.usda"), TRAIN_KEYS))
    path = tmp_path_factory.mktemp("train") / "t.toml"
    path.write_text(to_toml(table), encoding="utf-8")
    with time_limit(10):
        try:
            parse_train_recipe(path)
        except InputError as exc:
            _one_line(exc, path)


@examples(100)
@given(data=st.data())
def test_rattle_recipes_parse_or_fail_on_one_line(workspace, tmp_path_factory, data):
    """The ``[rattle]`` keys (issue 35): out of range, NaN, a wrong type, a missing or unknown
    key parse or fail on one line naming the file and ``rattle.<key>``."""
    from pavonine.pipeline.assemble.recipe import parse_train_recipe

    table = data.draw(mutated(small_rattle_recipe(workspace / "eye.usda"), RATTLE_KEYS))
    path = tmp_path_factory.mktemp("rattle") / "t.toml"
    path.write_text(to_toml(table), encoding="utf-8")
    with time_limit(10):
        try:
            recipe = parse_train_recipe(path)
        except InputError as exc:
            _one_line(exc, path)
            assert ": rattle" in str(exc), str(exc)
            return
    rattle = recipe.rattle
    if isinstance(table.get("rattle"), dict):
        assert rattle is not None and rattle.samples_per_period() >= 4
        assert len(rattle.times()) <= 4096 and np.all(np.isfinite(rattle.times()))


@pytest.mark.convert
@examples(12)
@given(data=st.data())
def test_convert_of_hostile_recipes_is_clean(workspace, tmp_path_factory, data):
    table = data.draw(mutated(small_feather_recipe(workspace / "maps"), RECIPE_KEYS))
    folder = tmp_path_factory.mktemp("convert")
    path = folder / "r.toml"
    path.write_text(to_toml(table), encoding="utf-8")
    outcome = run_cli(["convert", str(path), "-o", str(folder / "out")], seconds=120)
    assert_clean(outcome, table)
    if outcome.code != 0:
        assert_nothing_left(folder / "out")


# --------------------------------------------------------------------------------------- maps
@examples(80)
@given(spec=map_specs)
def test_maps_read_or_fail_on_one_line(tmp_path_factory, spec):
    from pavonine.base.map_files import read_data_map

    path = spec.write(tmp_path_factory.mktemp("map") / "m")
    with time_limit(10):
        try:
            data = read_data_map(path, "maps.alpha")
        except InputError as exc:
            _one_line(exc, path)
            assert str(exc).startswith(f"{path}: maps.alpha: ")
            return
    assert data.values.shape == (spec.height, spec.width)
    assert np.all(np.isfinite(data.values)) and data.values.min() >= 0 and data.values.max() <= 1


@pytest.mark.convert
@examples(12)
@given(spec=st.one_of(map_specs, st.sampled_from(["loop", "fifo", "dev_zero", "huge_header",
                                                   "text", "empty", "folder", "dangling"])),
       name=st.sampled_from(MAP_NAMES))  # fmt: skip
def test_convert_with_a_hostile_map_is_clean(workspace, tmp_path_factory, spec, name):
    folder = tmp_path_factory.mktemp("mapconvert")
    maps = folder / "maps"
    shutil.copytree(workspace / "maps", maps)
    (maps / f"{name}.png").unlink()
    if isinstance(spec, str):
        (maps / f"{name}.png").symlink_to(workspace / "odd" / f"{spec}.png" if spec != "dev_zero"
                                          else Path("/dev/zero"))  # fmt: skip
        target = maps / f"{name}.png"
    else:
        target = spec.write(maps / name)
    table = small_feather_recipe(maps)
    table["maps"][name] = str(target)
    (folder / "r.toml").write_text(to_toml(table))
    outcome = run_cli(["convert", str(folder / "r.toml"), "-o", str(folder / "out")], seconds=120)
    assert_clean(outcome, (spec, name))
    if outcome.code != 0:
        assert ": maps." in outcome.stderr, outcome.stderr  # a map's file and field are named
        assert_nothing_left(folder / "out")


# ------------------------------------------------------------------------- command-line options
#: Values of CLI_OPTIONS that are valid on some commands: ``--max-pixels 0`` lifts the render
#: ceilings (``limit_options``), so those commands start work instead of refusing it.
VALID_HERE = {("render", "--max-pixels"): {"0"}, ("check-renders", "--max-pixels"): {"0"}}
#: The expensive commands and the options of CLI_OPTIONS they take, with their other arguments.
REFUSING = {
    "render": (
        [str(SHIPPED_SCENE)],
        ["--seed", "--resolution", "--spp", "--time", "--exposure", "--threads", "--max-pixels"],
    ),
    "demo": ([], ["--seed", "--resolution", "--spp", "--size", "--exposure", "--threads"]),
    "maps": (["eye"], ["--seed", "--size"]),
    "check-renders": ([], ["--seed", "--max-pixels"]),
    "compare": (["a.exr", "b.exr"], ["--exposure", "--max-pixels"]),
    "convert": (["recipe.toml"], ["--jobs", "--max-pixels"]),
    "bake": (["asset.usd"], ["--resolution", "--max-pixels"]),
}


@examples(40)
@given(data=st.data())
def test_bad_option_values_are_refused_before_any_work(tmp_path_factory, data):
    command = data.draw(st.sampled_from(sorted(REFUSING)))
    positional, options = REFUSING[command]
    chosen = data.draw(st.lists(st.sampled_from(options), min_size=1, max_size=3, unique=True))
    args = [command, *positional]
    for option in chosen:
        bad = [v for v in CLI_OPTIONS[option] if v not in VALID_HERE.get((command, option), ())]
        args += [option, data.draw(st.sampled_from(bad))]
    out = tmp_path_factory.mktemp("refused")
    if command in ("render",):
        args += ["-o", str(out / "x.exr")]
    elif command in ("demo", "maps", "convert"):
        args += ["-o", str(out / "o")]
    outcome = run_cli(args, seconds=60)
    assert_clean(outcome, args, codes=(2,))
    assert_nothing_left(out)


@examples(40)
@given(data=st.data())
def test_spectra_options_any_value_is_clean(tmp_path_factory, data):
    names = ["--gradation", "--incidence", "--azimuth", "--structural-share", "--observe",
             "--class"]  # fmt: skip
    chosen = data.draw(st.lists(st.sampled_from(names), max_size=3, unique=True))
    args = ["spectra"]
    for option in chosen:
        args += [option, data.draw(st.sampled_from(CLI_ANY[option]))]
    if data.draw(st.booleans()):
        args += [
            "--interval",
            data.draw(st.sampled_from(["150", "0", "-1", "1e308", "nan", "0.5"])),
        ]
        args += ["--radius", data.draw(st.sampled_from(["50", "0", "1e-300", "inf"]))]
        args += ["--layers", data.draw(st.sampled_from(["4", "0", "0.5", str(2**31), "1e308"]))]
    out = tmp_path_factory.mktemp("spectra") / "out"
    outcome = run_cli([*args, "-o", str(out)], seconds=120)
    assert_clean(outcome, args)
    if outcome.code != 0:
        assert_nothing_left(out)


@pytest.fixture(scope="module")
def exr_pair(tmp_path_factory) -> tuple[Path, Path]:
    from pavonine.render.imageio import write_exr

    folder = tmp_path_factory.mktemp("exr")
    rng = np.random.default_rng(3)
    a, b = folder / "a.exr", folder / "b.exr"
    write_exr(a, rng.random((8, 8, 3), dtype=np.float32), {})
    write_exr(b, rng.random((8, 8, 3), dtype=np.float32), {})
    return a, b


@pytest.mark.mitsuba
@examples(30)
@given(data=st.data())
def test_compare_options_and_paths_any_value_is_clean(workspace, exr_pair, tmp_path_factory, data):
    odd = [*sorted((workspace / "odd").glob("*.png")), Path("/dev/zero")]
    test, ref = exr_pair
    if data.draw(st.booleans()):
        test = data.draw(st.sampled_from(odd))
    names = ["--significance", "--pass-ratio", "--flip-threshold", "--ref-spp", "--test-spp"]
    chosen = data.draw(st.lists(st.sampled_from(names), max_size=3, unique=True))
    args = [
        "compare",
        str(test),
        str(ref),
        "--method",
        data.draw(st.sampled_from(["stat", "flip"])),
    ]
    for option in chosen:
        args += [option, data.draw(st.sampled_from(CLI_ANY[option]))]
    out = tmp_path_factory.mktemp("compare") / "out"
    outcome = run_cli([*args, "-o", str(out)], seconds=60)
    assert_clean(outcome, args)
    if outcome.code == 2:
        assert_nothing_left(out)


@examples(20)
@given(kind=st.sampled_from(["eye", "blue", "yellow", "fishtail", "owl"]),
       size=st.sampled_from(["16", "17", "15", "0", "-1", "nan", "20000"]),
       seed=st.sampled_from(["0", str(2**32 - 1), str(2**32), "-1"]),
       fmt=st.sampled_from(["png", "exr", "jpg"]))  # fmt: skip
def test_maps_command_any_value_is_clean(tmp_path_factory, kind, size, seed, fmt):
    out = tmp_path_factory.mktemp("maps") / "out"
    args = ["maps", kind, "--size", size, "--seed", seed, "--format", fmt, "-o", str(out)]
    outcome = run_cli(args, seconds=60)
    assert_clean(outcome, args)
    if outcome.code != 0:
        assert_nothing_left(out)
    else:
        assert all((out / f"{name}.{fmt}").is_file() for name in MAP_NAMES)


@examples(20)
@given(command=st.sampled_from(["validate", "convert", "bake", "export", "package",
                                "assemble train"]),
       kind=st.sampled_from(["missing", "folder", "fifo", "dev_zero", "loop", "dangling", "empty",
                             "text"]))  # fmt: skip
def test_path_arguments_that_are_not_files_are_clean(workspace, tmp_path_factory, command, kind):
    path = Path("/dev/zero") if kind == "dev_zero" else workspace / "odd" / f"{kind}.png"
    out = tmp_path_factory.mktemp("paths") / "out"
    args = [*command.split(), str(path)]
    if command in ("convert", "assemble train"):
        args += ["-o", str(out)]
    outcome = run_cli(args, seconds=30)
    assert_clean(outcome, args)
    assert outcome.code != 0
    assert_nothing_left(out)
