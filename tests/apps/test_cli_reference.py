"""docs/cli.md is generated from the commands and must be current."""

from pathlib import Path

from pavonine.apps.cli.reference import render_reference

DOC = Path(__file__).resolve().parents[2] / "docs" / "cli.md"


def test_cli_reference_is_current():
    assert DOC.read_text() == render_reference(), (
        "docs/cli.md is stale: run `python -m pavonine.apps.cli.reference > docs/cli.md`"
    )
