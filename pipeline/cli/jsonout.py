"""``--json [FILE|-]`` for commands that report: a machine-readable report to FILE or stdout."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import click

from pavonine.pipeline.errors import atomic_path

#: ``--json`` alone (or ``--json -``) writes to stdout, and then nothing else does.
json_option = click.option(
    "--json",
    "json_target",
    is_flag=False,
    flag_value="-",
    default=None,
    metavar="[FILE|-]",
    help="Write a JSON report to FILE, or to stdout with '-' (then nothing else goes there).",
)


def write_json(report: Any, target: str | None) -> None:
    """Write ``report`` as JSON to ``target`` (a file, atomically; ``-`` for stdout)."""
    if target is None:
        return
    text = json.dumps(report, indent=2, sort_keys=True) + "\n"
    if target == "-":
        click.echo(text, nl=False)
        return
    with atomic_path(Path(target)) as tmp:
        tmp.write_text(text)


def say(message: str, json_target: str | None) -> None:
    """Print a human line on stdout unless the JSON report goes there."""
    if json_target != "-":
        click.echo(message)
