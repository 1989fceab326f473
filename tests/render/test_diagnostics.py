"""USD's own warnings reach the user as one ``warning:`` line each, never as USD's raw
``Warning: in _ReportErrors at line … of stage.cpp`` lines, and not twice."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from pavonine.apps.cli.usd_diagnostics import usd_warning_line

DATA = Path(__file__).parents[1] / "data" / "render"


def test_usd_commentary_becomes_one_line_led_by_the_prim():
    commentary = (
        "In </A>: Could not open asset @/x/nope.usda@ for reference introduced by @a.usda@</A>. "
        "(instantiating stage on stage @a.usda@ <0x5577f8f4ab80>)"
    )
    assert usd_warning_line(commentary) == (
        "/A: Could not open asset @/x/nope.usda@ for reference introduced by @a.usda@</A>."
    )
    assert usd_warning_line("two\nlines") == "two\\nlines"


def _missing_reference(folder: Path) -> Path:
    stage = folder / "scene.usda"
    stage.write_text(
        f"#usda 1.0\n(\n    subLayers = [@{DATA / 'bare_quad.usda'}@]\n)\n"
        'def Xform "A" (\n    prepend references = @./nope.usda@\n)\n{\n}\n'
    )
    return stage


def _pavonine(*args: str) -> subprocess.CompletedProcess:
    command = [sys.executable, "-m", "pavonine.apps.cli", *args]
    return subprocess.run(command, capture_output=True, text=True, timeout=300)


@pytest.mark.mitsuba
def test_render_says_a_missing_reference_once_in_its_own_words(tmp_path):
    stage = _missing_reference(tmp_path)
    done = _pavonine("render", str(stage), "-o", str(tmp_path / "o.exr"), "--spp", "1",
                     "--resolution", "8x8")  # fmt: skip
    assert done.returncode == 0, done.stderr
    lines = done.stderr.splitlines()
    assert not any(line.startswith("Warning: in ") for line in lines), done.stderr
    assert sum("nope.usda" in line for line in lines) == 1, done.stderr


def test_usd_warnings_become_one_log_line_each_unless_refused_or_reported(tmp_path):
    import logging

    from pxr import Usd

    from pavonine.apps.cli.usd_diagnostics import REPORTED, usd_warnings_to_log
    from pavonine.base.errors import InputError

    stage = _missing_reference(tmp_path)
    logger = logging.getLogger("test_usd_diagnostics")  # not under "pavonine": its own handler
    logger.propagate = False
    records: list[str] = []
    handler = logging.Handler()
    handler.emit = lambda record: records.append(record.getMessage())
    logger.addHandler(handler)
    with usd_warnings_to_log(logger):
        Usd.Stage.Open(str(stage))
        Usd.Stage.Open(str(stage), Usd.Stage.LoadAll)  # the same warning again, said once
    assert len(records) == 1 and records[0].startswith("USD: /A: Could not open asset")
    records.clear()
    with pytest.raises(InputError), usd_warnings_to_log(logger):
        Usd.Stage.Open(str(stage))
        raise InputError("x", "bad input: its one error line is the answer")
    with usd_warnings_to_log(logger, {REPORTED: True}):
        Usd.Stage.Open(str(stage))
    assert records == []


def test_validate_reports_usd_warnings_as_findings_only(tmp_path):
    stage = _missing_reference(tmp_path)
    checked = _pavonine("validate", str(stage))
    assert "nope.usda" in checked.stdout  # a finding
    assert "nope.usda" not in checked.stderr and "Warning: in " not in checked.stderr
