"""Property-based fuzzing of ``pavonine render`` and ``pavonine validate`` with hostile layers.

The generators are in :mod:`usd_fuzz` (one place to extend). The property, for every layer:

* the command ends with exit 0 (``render``: a finite image written; warnings name a prim), or
  with its documented non-zero status (``render``: 2; ``validate``: 1 for findings, 2 for an
  unreadable file) and, for 2, exactly one ``error: <file or field>: <message>`` line and no
  image;
* never a traceback (an exception escaping the command), never a NaN or infinite pixel;
* never a hang: each example must finish within :data:`EXAMPLE_SECONDS` (measured, and checked
  after the fact: a hang inside Mitsuba cannot be interrupted in-process).

``test_fuzz_*`` is marked ``fuzz`` (the slow part; ``.ci/run`` still runs it, derandomised so CI
is reproducible; ``PAVONINE_FUZZ_EXAMPLES=N`` runs more). ``test_smoke_*`` runs a few fixed
examples of each generator on every run.
"""

from __future__ import annotations

import os
import tempfile
import time
import traceback
from pathlib import Path

import numpy as np
import pytest
import usd_fuzz
from click.testing import CliRunner
from hypothesis import HealthCheck, event, given, settings

from pavonine.apps.cli import cli

pytestmark = pytest.mark.mitsuba

EXAMPLES = int(os.environ.get("PAVONINE_FUZZ_EXAMPLES", "25"))
EXAMPLE_SECONDS = 90.0
#: Renders stay tiny: 16×12 at most (CLI override), 1 spp, few instances (the ceiling is tested
#: in test_render_limits; here it keeps Mitsuba's per-instance tracing short).
RENDER_ARGS = ["--resolution", "16x12", "--spp", "1", "--max-instances", "60", "-q"]
FUZZ = settings(
    max_examples=EXAMPLES,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)


def write(files: dict[str, str], folder: Path) -> Path:
    for name, text in files.items():
        (folder / name).write_text(text, encoding="utf-8")
    return folder / "scene.usda"


def invoke(*args) -> tuple[int, str, str, float]:
    """(exit status, stdout, stderr, seconds); an escaping exception fails as a traceback."""
    started = time.monotonic()
    result = CliRunner().invoke(cli, [str(a) for a in args])
    seconds = time.monotonic() - started
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        trace = "".join(traceback.format_exception(result.exception))
        pytest.fail(f"traceback from pavonine {' '.join(map(str, args))}:\n{trace}")
    return result.exit_code, result.stdout, result.stderr, seconds


def error_lines(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.startswith("error: ")]


def check_render(files: dict[str, str]) -> None:
    """The render property (module docstring) for one generated stage."""
    from pavonine.render.imageio import read_exr

    with tempfile.TemporaryDirectory() as tmp:
        stage = write(files, Path(tmp))
        out = Path(tmp) / "out" / "image.exr"
        code, _, stderr, seconds = invoke("render", stage, "-o", out, *RENDER_ARGS)
        assert seconds < EXAMPLE_SECONDS, f"hang: {seconds:.0f} s\n{files['scene.usda']}"
        assert "Traceback" not in stderr, stderr
        event(f"render exit {code}" + (f": {error_lines(stderr)[0][:60]}" if code else ""))
        if code == 0:
            pixels = np.asarray(read_exr(out)[0])
            assert np.isfinite(pixels).all(), f"non-finite image\n{files['scene.usda']}"
            assert pixels.shape == (12, 16, 3)
        else:
            assert code == 2, f"exit {code}: {stderr}\n{files['scene.usda']}"
            lines = error_lines(stderr)
            assert len(lines) == 1, f"{stderr}\n{files['scene.usda']}"
            assert len(lines[0].split(": ", 2)) == 3, lines[0]  # error: <where>: <message>
            assert not out.exists()


def check_validate(files: dict[str, str]) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        stage = write(files, Path(tmp))
        code, stdout, stderr, seconds = invoke("validate", stage)
        assert seconds < EXAMPLE_SECONDS
        assert code in (0, 1, 2), stderr
        assert "Traceback" not in stderr + stdout
        if code == 2:
            assert len(error_lines(stderr)) == 1, stderr


@pytest.mark.render
@settings(FUZZ, max_examples=3)
@given(files=usd_fuzz.layers())
def test_smoke_render_hostile_layers(files):
    check_render(files)


@pytest.mark.fuzz
@pytest.mark.render
@FUZZ
@given(files=usd_fuzz.layers())
def test_fuzz_render_hostile_layers(files):
    check_render(files)


@pytest.mark.fuzz
@FUZZ
@given(files=usd_fuzz.layers())
def test_fuzz_validate_hostile_layers(files):
    check_validate(files)


@pytest.mark.render
def test_deep_stage_renders_never_crashes():
    """3000 nested Xforms over a quad (valid USD): rendered, framed by its bounds (the
    segmentation fault of issue 35 was there), the same image as the quad under one Xform."""
    from pavonine.render.imageio import read_exr

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "deep.exr"
        stage = write(usd_fuzz.deep_layers(), Path(tmp))
        code, _, stderr, seconds = invoke("render", stage, "-o", out, *RENDER_ARGS)
        assert code == 0 and "Traceback" not in stderr, stderr
        assert seconds < EXAMPLE_SECONDS
        pixels = np.asarray(read_exr(out)[0])
        assert pixels.shape == (12, 16, 3) and np.isfinite(pixels).all()
        shallow = Path(tmp) / "shallow"
        shallow.mkdir()
        stage = write(usd_fuzz.deep_layers(1), shallow)
        code, _, stderr, _ = invoke("render", stage, "-o", shallow / "one.exr", *RENDER_ARGS)
        assert code == 0, stderr
        assert np.array_equal(pixels, np.asarray(read_exr(shallow / "one.exr")[0]))


def test_stage_beyond_the_nesting_limit_is_one_line_naming_it(monkeypatch):
    from pavonine.base import nesting

    monkeypatch.setattr(nesting, "MAX_NESTING", usd_fuzz.DEEP - 1)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "deep.exr"
        code, _, stderr, _ = invoke(
            "render", write(usd_fuzz.deep_layers(), Path(tmp)), "-o", out, *RENDER_ARGS
        )
        assert code == 2, stderr
        (line,) = error_lines(stderr)
        assert f"prims nested {usd_fuzz.DEEP + 1:,} deep" in line
        assert f"beyond the limit of {usd_fuzz.DEEP - 1:,} levels (MAX_NESTING)" in line
        assert len(line) < 400 and not out.exists()
