"""The CLI convention, checked on every registered command (commands added later included).

The registry is walked, not listed by hand: a new command gets its ``--help``, usage-error and
``-v/-q`` checks for free, and a new command with ``--json`` fails here until it has an example
invocation in ``EXAMPLES`` whose report matches the schema it documents.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from collections.abc import Callable, Iterator
from pathlib import Path

import click
import jsonschema
import numpy as np
import pytest
from click.testing import CliRunner

from pavonine.apps.cli import COMMANDS, cli
from pavonine.apps.cli.options import json_schema

REPO = Path(__file__).resolve().parents[2]
DATA = Path(__file__).resolve().parents[1] / "data"

#: Commands that print something other than a report (``env`` prints a shell line).
NOT_REPORTING = {"env", "view"}  # view: a server; what it prints is its URL


def walk(group: click.Group = cli, path: tuple[str, ...] = ()) -> Iterator[tuple[str, ...]]:
    """Every leaf command's path below ``group`` (``("baseline", "list")``, …)."""
    ctx = click.Context(group, info_name="pavonine")
    for name in group.list_commands(ctx):
        command = group.get_command(ctx, name)
        if isinstance(command, click.Group):
            yield from walk(command, (*path, name))
        else:
            yield (*path, name)


def command_at(path: tuple[str, ...]) -> click.Command:
    command: click.Command = cli
    for name in path:
        command = command.get_command(click.Context(command), name)  # type: ignore[union-attr]
    return command


LEAVES = sorted(walk())
IDS = [" ".join(p) for p in LEAVES]


def invoke(*args: str, **kwargs):
    return CliRunner().invoke(cli, list(args), **kwargs)


def test_the_registry_is_what_the_walk_sees():
    assert {p[0] for p in LEAVES} == set(COMMANDS)


@pytest.mark.parametrize("path", LEAVES, ids=IDS)
def test_help_exits_0_and_lists_the_global_options(path):
    result = invoke(*path, "--help")
    assert result.exit_code == 0, result.output
    assert result.stdout.startswith(f"Usage: pavonine {' '.join(path)}")
    assert "-v, --verbose" in result.stdout and "-q, --quiet" in result.stdout
    command = command_at(path)
    outputs = [p for p in command.params if p.name == "output"]
    for param in outputs:  # -o/--output, never another spelling
        assert param.opts == ["-o", "--output"], path
    assert not [p for p in command.params if "-o" in p.opts and p.name != "output"]


def one_error_line(result, needle: str) -> str:
    assert result.exit_code == 2, result.output
    assert result.stdout == "", result.stdout
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("error: ") and needle in lines[0], lines[0]
    return lines[0]


@pytest.mark.parametrize("path", LEAVES, ids=IDS)
def test_unknown_option_is_one_line_exit_2(path):
    line = one_error_line(invoke(*path, "--no-such-option"), "--no-such-option: no such option")
    assert f"(see 'pavonine {' '.join(path)} --help')" in line


def numeric_options(path: tuple[str, ...]) -> list[click.Option]:
    return [
        p
        for p in command_at(path).params
        if isinstance(p, click.Option)
        and not p.is_flag
        and not p.count
        and isinstance(p.type, click.types._NumberParamTypeBase)
    ]


def required_arguments(path: tuple[str, ...]) -> list[click.Argument]:
    return [p for p in command_at(path).params if isinstance(p, click.Argument) and p.required]


WITH_NUMBERS = [p for p in LEAVES if numeric_options(p)]
WITH_ARGUMENTS = [p for p in LEAVES if required_arguments(p)]


@pytest.mark.parametrize("path", WITH_NUMBERS, ids=[" ".join(p) for p in WITH_NUMBERS])
def test_bad_number_is_one_line_exit_2(path):
    """Every option taking a number rejects a word with one line naming the option."""
    for param in numeric_options(path):
        name = max(param.opts, key=len)
        one_error_line(invoke(*path, name, "plenty"), f"{name}: 'plenty' is not a valid")


@pytest.mark.parametrize("path", WITH_ARGUMENTS, ids=[" ".join(p) for p in WITH_ARGUMENTS])
def test_missing_argument_is_one_line_exit_2(path):
    name = required_arguments(path)[0].human_readable_name
    one_error_line(invoke(*path), f"{name}: missing argument")


def test_unknown_command_is_one_line_exit_2():
    one_error_line(invoke("paint"), "pavonine: No such command 'paint'")


# ----------------------------------------------------------------------------------- --json
def _write_exr_pair(tmp: Path) -> list[str]:
    from pavonine.render.imageio import write_exr

    rng = np.random.default_rng(0)
    base = np.full((16, 16, 3), 0.4, np.float32)
    write_exr(tmp / "a.exr", base + 0.01 * rng.normal(size=base.shape).astype(np.float32))
    write_exr(tmp / "b.exr", base + 0.01 * rng.normal(size=base.shape).astype(np.float32))
    return [str(tmp / "a.exr"), str(tmp / "b.exr"), "-o", str(tmp / "heat")]


def _small_recipe(tmp: Path) -> list[str]:
    from pavonine.pipeline.maps.paint import MAP_NAMES, generate_maps, write_maps

    write_maps(generate_maps("blue", 48, seed=1), tmp / "m")
    maps = "\n".join(f'{m} = "m/{m}.png"' for m in MAP_NAMES)
    (tmp / "small.toml").write_text(
        f'name = "small"\n[maps]\n{maps}\n[material]\npreset = "blue"\n'
        "[geometry]\nlength_cm = 10\n[geometry.lod]\nhigh = 800\nmedium = 400\nlow = 200\n"
    )
    return [str(tmp / "small.toml"), "-o", str(tmp / "assets")]


def _fake_store(tmp: Path, monkeypatch) -> list[str]:
    """A scene and a stand-in renderer (a noisy flat image), so baselines take milliseconds."""
    from pavonine.apps.compare import baselines

    def render(stage, settings, *, progress=False, limits=None):
        width, height = settings.resolution
        rng = np.random.default_rng(settings.seed)
        truth = np.full((height, width, 3), 0.5, np.float32)
        variance = np.full_like(truth, 0.01 / settings.spp)
        rgb = truth + rng.normal(size=truth.shape).astype(np.float32) * np.sqrt(variance)
        return baselines.SceneRender(rgb, variance, {"fake": True})

    monkeypatch.setattr(baselines, "render_scene", render)
    (tmp / "scenes").mkdir()
    (tmp / "scenes" / "flat.usda").write_text(
        '#usda 1.0\n(\n    renderSettingsPrimPath = "/Render/Settings"\n)\n'
    )
    return ["--scenes-dir", str(tmp / "scenes"), "--baselines-dir", str(tmp / "baselines")]


def _with_baseline(tmp: Path, monkeypatch) -> list[str]:
    store = _fake_store(tmp, monkeypatch)
    made = invoke("baseline", "update", "flat", "--resolution", "16x16", *store)
    assert made.exit_code == 0, made.output
    return store


def _small_train(tmp: Path) -> list[str]:
    """A two-row train over two shipped feathers (their paths made absolute)."""
    feathers = REPO / "assets" / "feathers"
    (tmp / "train.toml").write_text(
        'name = "small_train"\nversion = "1.0"\nseed = 1\nlod = "low"\n[components]\n'
        f'eye = "{feathers}/eye_feather/eye_feather.usd"\n'
        f'blue = "{feathers}/blue_feather/blue_feather.usd"\n'
        '[[rows]]\ncomponent = "eye"\ncount = 5\nradius_cm = 10\nspan_deg = 120\n'
        '[[rows]]\ncomponent = "blue"\ncount = 3\nradius_cm = 2\nspan_deg = 90\n'
    )
    return [str(tmp / "train.toml"), "-o", str(tmp / "assemblies")]


#: Command path → (arguments given a temporary folder and monkeypatch, accepted exit codes).
EXAMPLES: dict[tuple[str, ...], tuple[Callable, set[int]]] = {
    ("spectra",): (lambda tmp, mp: ["--preset", "blue", "--observe", "20"], {0}),
    ("figures",): (lambda tmp, mp: ["-o", str(tmp)], {0}),
    ("maps",): (lambda tmp, mp: ["eye", "-o", str(tmp), "--size", "32"], {0}),
    ("convert",): (lambda tmp, mp: _small_recipe(tmp), {0}),
    ("validate",): (lambda tmp, mp: [str(DATA / "schema" / "minimal_feather.usda")], {0}),
    ("render",): (
        lambda tmp, mp: [
            str(DATA / "render" / "bare_quad.usda"),
            *("-o", str(tmp / "q.exr"), "--png", "--spp", "1", "--resolution", "8x8"),
        ],
        {0},
    ),
    ("compare",): (lambda tmp, mp: _write_exr_pair(tmp), {0, 1}),
    ("baseline", "list"): (lambda tmp, mp: [], {0}),
    ("baseline", "update"): (
        lambda tmp, mp: ["flat", "--resolution", "16x16", *_fake_store(tmp, mp)],
        {0},
    ),
    ("check-renders",): (lambda tmp, mp: _with_baseline(tmp, mp), {0}),
    ("demo",): (
        lambda tmp, mp: [*("-o", str(tmp), "--size", "64", "--spp", "1"), "--resolution", "8x12"],
        {0},
    ),
    ("doctor",): (lambda tmp, mp: [], {0}),
    ("bake",): (lambda tmp, mp: [str(_asset_copy(tmp)), "--resolution", "32"], {0}),
    ("package",): (lambda tmp, mp: [str(_asset_copy(tmp)), "-o", str(tmp / "eye.usdz")], {0}),
    ("export",): (lambda tmp, mp: [str(_asset_copy(tmp)), "-o", str(tmp / "eye.glb")], {0}),
    ("assemble", "train"): (lambda tmp, mp: _small_train(tmp), {0}),
}

_EYE_ASSET: list[Path] = []  # set by the eye_asset fixture for the examples that need it


def _asset_copy(tmp: Path) -> Path:
    """A copy of the session's converted eye feather (conftest's ``eye_asset``)."""
    import shutil

    source = _EYE_ASSET[0].parent
    shutil.copytree(source, tmp / source.name)
    return tmp / source.name


@pytest.mark.parametrize("path", LEAVES, ids=IDS)
def test_every_reporting_command_has_json_with_a_schema(path):
    schema = json_schema(command_at(path))
    if path[0] in NOT_REPORTING:
        assert schema is None
        return
    assert schema is not None, f"{' '.join(path)}: add @json_option(SCHEMA) (docs/cli.md)"
    jsonschema.Draft202012Validator.check_schema(schema)
    assert path in EXAMPLES, f"add an example invocation of {' '.join(path)} to EXAMPLES"


#: Examples that render (Mitsuba llvm) skip without its libraries; those that build meshes run
#: with pymeshlab or, without its libraries, the NumPy fallback (the convert marker).
NEEDS = {("convert",): ["convert"], ("demo",): ["convert", "render"], ("render",): ["render"]}
NEEDS |= {("check-renders",): ["mitsuba"], ("baseline", "update"): ["mitsuba"]}
NEEDS |= {("doctor",): ["mitsuba"]}
NEEDS |= {("bake",): ["convert"], ("package",): ["convert"], ("export",): ["convert"]}
JSON_CASES = [
    pytest.param(p, id=" ".join(p), marks=[getattr(pytest.mark, m) for m in NEEDS.get(p, [])])
    for p in sorted(EXAMPLES)
]


def _example(path, tmp_path, monkeypatch, request) -> tuple[list[str], set[int]]:
    """The example invocation of ``path`` (its arguments, run in ``tmp_path``) and its exit codes."""
    if path in (("bake",), ("package",), ("export",)):
        _EYE_ASSET[:] = [request.getfixturevalue("eye_asset")]
    make_args, exit_codes = EXAMPLES[path]
    monkeypatch.chdir(tmp_path)
    return make_args(tmp_path, monkeypatch), exit_codes


@pytest.mark.parametrize("path", JSON_CASES)
def test_json_to_stdout_is_the_documented_report_and_nothing_else(
    path, tmp_path, monkeypatch, request
):
    args, exit_codes = _example(path, tmp_path, monkeypatch, request)
    result = invoke(*path, *args, "--json", "-")
    assert result.exit_code in exit_codes, result.output
    report = json.loads(result.stdout)  # anything else on stdout would break this
    jsonschema.validate(report, json_schema(command_at(path)))


def _files(folder: Path) -> dict[str, tuple[int, int]]:
    return {
        str(p.relative_to(folder)): (p.stat().st_mtime_ns, p.stat().st_size)
        for p in folder.rglob("*")
        if p.is_file()
    }


@pytest.mark.parametrize("report", ["under-a-file", "uncreatable-folder"])
@pytest.mark.parametrize("path", JSON_CASES)
def test_an_unwritable_json_report_stops_the_command_before_it_writes(
    path, report, tmp_path, monkeypatch, request
):
    """The report is written last: its path is checked first, or the outputs would be left.
    Checked: a folder that is a file, and a folder that cannot be made (under /proc)."""
    if report == "uncreatable-folder" and not os.path.isdir("/proc/self"):
        pytest.skip("needs Linux's /proc")
    args, _ = _example(path, tmp_path, monkeypatch, request)
    (tmp_path / "afile").write_text("")
    before = _files(tmp_path)
    where = "afile" if report == "under-a-file" else "/proc/pavonine-nowhere"
    target = tmp_path / "afile" / "r.json" if report == "under-a-file" else Path(where) / "r.json"
    result = invoke(*path, *args, "--json", str(target))
    assert result.exit_code == 2, result.output
    assert result.stderr.count("\n") == 1 and where in result.stderr, result.stderr
    assert _files(tmp_path) == before


# ----------------------------------------------------------------------- -v / -q, logging
@click.command("probe")
def probe() -> None:
    """A command registered only by this test: it has no -v/-q of its own."""
    from pavonine.apps.cli.options import log, say

    log.debug("debug line")
    log.info("info line")
    log.warning("warning line")
    say("result line")


def test_verbosity_reaches_commands_added_later(monkeypatch):
    monkeypatch.setitem(COMMANDS, "probe", f"{__name__}:probe")
    plain = invoke("probe")
    assert plain.exit_code == 0
    assert plain.stdout == "result line\n"
    assert plain.stderr == "info: info line\nwarning: warning line\n"
    for args in (("-q", "probe"), ("probe", "-q")):
        assert invoke(*args).stderr == "warning: warning line\n"
    for args in (("-v", "probe"), ("probe", "--verbose")):
        assert invoke(*args).stderr.startswith("debug: debug line\ninfo: info line\n")
    assert invoke("-v", "probe", "-q").stderr == "info: info line\nwarning: warning line\n"


@pytest.mark.mitsuba
def test_threads_option_holds_while_the_command_runs_and_not_after(monkeypatch):
    """``--threads 1`` bounds Dr.Jit, the limit Pavonine hands to workers and the BLAS/OpenMP
    variables while the command's body runs; afterwards (and after a usage error found once the
    option was parsed) the process is as it was, so in-process callers never inherit it."""
    import drjit as dr

    from pavonine.apps.farm import cli as farm
    from pavonine.base import backend
    from pavonine.base.errors import InputError

    def state() -> tuple:
        return dr.thread_count(), backend.thread_count(), os.environ.get("OMP_NUM_THREADS")

    before = state()
    seen = []

    def spy(stage, *args, **kwargs):
        seen.append(state())
        raise InputError(str(stage), "stopped by the test")

    monkeypatch.setattr(farm, "render_views", spy)
    stage = str(DATA / "render" / "bare_quad.usda")
    result = invoke("render", stage, "--threads", "1", "--spp", "1")
    assert result.exit_code != 0 and "stopped by the test" in result.stderr, result.output
    assert seen == [(1, 1, "1")]
    assert state() == before
    assert invoke("render", "--threads", "1").exit_code == 2  # no STAGE: a usage error
    assert state() == before
    one_error_line(invoke("render", "x.usda", "--threads", "0"), "--threads: 0 is not in the range")


# --------------------------------------------------------------------------- completion
@pytest.mark.parametrize(
    ("words", "cword", "expected"),
    [
        ("pavonine check-", 1, "check-renders"),
        ("pavonine render x.usda --sp", 3, "--spp"),
        ("pavonine baseline ", 2, "update"),
    ],
)
def test_shell_completion_sees_lazy_commands_and_their_options(words, cword, expected, monkeypatch):
    """The completion documented in docs/cli.md (click's ``_PAVONINE_COMPLETE``)."""
    result = CliRunner().invoke(
        cli,
        [],
        prog_name="pavonine",
        env={"_PAVONINE_COMPLETE": "bash_complete", "COMP_WORDS": words, "COMP_CWORD": str(cword)},
    )
    assert result.exit_code == 0
    assert f"plain,{expected}" in result.stdout.splitlines()


# ------------------------------------------------------------------- without the extras
BLOCKER = textwrap.dedent(
    """
    import importlib.abc, sys

    class Missing(importlib.abc.MetaPathFinder):
        # Stand-in for an install without the [render], [convert] and [farm] extras.
        BLOCKED = {BLOCKED!r}

        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in self.BLOCKED:
                raise ModuleNotFoundError(f"No module named {{name!r}}", name=name)
            return None

    sys.meta_path.insert(0, Missing())
    import pavonine
    from pavonine.apps.cli import main
    main(sys.argv[1:])
    """
)
EXTRA_MODULES = ("mitsuba", "drjit", "PyOpenColorIO", "flip_evaluator", "jinja2")
EXTRA_MODULES += ("pymeshlab", "xatlas", "MaterialX", "dask", "distributed")


def run_without_extras(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    code = BLOCKER.format(BLOCKED=set(EXTRA_MODULES))
    return subprocess.run(
        [sys.executable, "-c", code, *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=300,
        check=False,
    )


def test_base_install_has_optics_and_schema(tmp_path):
    """``pip install pavonine``: spectra, maps and validate work without Mitsuba or OCIO."""
    spectra = run_without_extras("spectra", "--preset", "blue", "-o", "s", cwd=tmp_path)
    assert spectra.returncode == 0, spectra.stderr
    assert (tmp_path / "s" / "spectra_blue.png").is_file()
    report = run_without_extras("spectra", "--preset", "blue", "--json", "-", cwd=tmp_path)
    with_extras = invoke("spectra", "--preset", "blue", "--json", "-")
    assert json.loads(report.stdout)["spectra"] == json.loads(with_extras.stdout)["spectra"]
    valid = run_without_extras(
        "validate", str(DATA / "schema" / "minimal_feather.usda"), cwd=tmp_path
    )
    assert valid.returncode == 0 and valid.stdout == "1 file, no findings\n", valid.stderr
    maps = run_without_extras("maps", "blue", "-o", "m", "--size", "16", cwd=tmp_path)
    assert maps.returncode == 0 and (tmp_path / "m" / "alpha.png").is_file(), maps.stderr
    doctor = run_without_extras("doctor", "--json", "-", cwd=tmp_path)
    info = json.loads(doctor.stdout)
    assert info["extras"] == {"convert": False, "render": False, "farm": False}
    assert info["variant"] is None


@pytest.mark.convert
def test_convert_extra_works_without_the_renderer(tmp_path):
    """``pip install pavonine[convert]``: maps, convert (with its baking) without Mitsuba/OCIO."""
    render_only = ("mitsuba", "drjit", "PyOpenColorIO", "flip_evaluator", "jinja2")
    args = _small_recipe(tmp_path)
    code = BLOCKER.format(BLOCKED=set(render_only))
    result = subprocess.run(
        [sys.executable, "-c", code, "convert", *args, "--json", "-"],
        capture_output=True, text=True, cwd=tmp_path, timeout=600, check=False,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    [converted] = json.loads(result.stdout)["converted"]
    assert Path(converted["asset"]).is_file()


@pytest.mark.parametrize(
    ("args", "extra"),
    [
        (["render", str(DATA / "render" / "bare_quad.usda"), "-o", "q.exr"], "render"),
        (["convert", "missing.toml", "-o", "out"], "convert"),
        (["demo", "-o", "d"], "render"),
        (["check-renders"], "render"),
        (["spectra", "--view", "Raw"], "render"),
    ],
)
def test_missing_extra_is_one_line_naming_it(tmp_path, args, extra):
    result = run_without_extras(*args, cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: pavonine"), result.stderr
    assert f"needs the [{extra}] extra" in lines[0]
    assert f"pip install 'pavonine[{extra}]'" in lines[0]
    assert not list(tmp_path.iterdir())  # checked before anything is written


@pytest.mark.mitsuba
def test_farm_options_without_the_farm_extra_are_one_line_naming_it(tmp_path):
    """``--workers``/``--scheduler`` need ``[farm]``; said before anything is written."""
    code = BLOCKER.format(BLOCKED={"dask", "distributed"})
    stage = str(DATA / "render" / "bare_quad.usda")
    for option in (["--workers", "2"], ["--scheduler", "tcp://127.0.0.1:1"]):
        result = subprocess.run(
            [sys.executable, "-c", code, "render", stage, "-o", "q.exr", *option],
            capture_output=True, text=True, cwd=tmp_path, timeout=300, check=False,
        )  # fmt: skip
        assert result.returncode == 2, result.stderr
        lines = result.stderr.splitlines()
        assert len(lines) == 1 and lines[0].startswith(f"error: {option[0]}: "), result.stderr
        assert "needs the [farm] extra" in lines[0] and "pip install 'pavonine[farm]'" in lines[0]
        assert not list(tmp_path.iterdir())


def test_the_log_handler_survives_a_closed_earlier_stderr(capsys):
    """The handler writes to whatever ``sys.stderr`` is; the one it last wrote to may be closed
    by now (pytest's fd capture of an earlier test, a tool's own redirection): that must not
    raise 'I/O operation on closed file' (seen in CI, depending on test order)."""
    import logging

    from pavonine.apps.cli.options import _LevelFormatter, _StderrHandler

    handler = _StderrHandler()
    handler.setFormatter(_LevelFormatter())
    gone = open(os.devnull, "wb", buffering=0)  # closed on purpose
    gone.close()
    handler.stream = gone
    record = logging.LogRecord("pavonine", logging.WARNING, "", 0, "after the runner", (), None)
    handler.emit(record)
    assert "warning: after the runner" in capsys.readouterr().err
