"""``pavonine validate PATH…``: USD's validators plus Pavonine's, one line per finding."""

from __future__ import annotations

import json
import re
import sys

import click

EXIT_CLEAN, EXIT_ERRORS, EXIT_UNREADABLE = 0, 1, 2

# Tf error text: "\tError in '<function>' at line N in file F : '<message>'", repeated.
_TF_MESSAGE = re.compile(
    r"Error in '[^']*' at line \d+ in file [^\n]*? : '(.*?)'\s*(?=\tError in|$)", re.S
)


def parser_message(exc: Exception) -> str:
    """The first, most specific message of a USD error (the parser's own), on one line."""
    match = _TF_MESSAGE.search(str(exc))
    text = match.group(1) if match else str(exc)
    return " ".join(text.split()) or type(exc).__name__


def open_stage(path: str):
    """Open ``path`` as a stage; raise ``ValueError`` with the parser's one-line message."""
    import os

    from pxr import Tf, Usd

    if not os.path.isfile(path):
        raise ValueError("no such file")
    try:
        stage = Usd.Stage.Open(path)
    except Tf.ErrorException as exc:
        raise ValueError(parser_message(exc)) from None
    if stage is None:
        raise ValueError("USD could not open this file")
    return stage


@click.command("validate")
@click.argument("paths", nargs=-1, required=True, type=click.Path(dir_okay=False))
@click.option(
    "--json",
    "as_json",
    is_flag=True,
    help="Print a JSON object {findings: [...], unreadable: [...]}.",
)
@click.option("--warnings/--no-warnings", default=True, show_default=True, help="Report warnings.")
def validate(paths: tuple[str, ...], as_json: bool, warnings: bool) -> None:
    """Validate USD layers: USD's own UsdValidation validators plus Pavonine's.

    One line per finding: ERROR|WARNING <prim path> <field>: <message>. Exit status 0 when
    clean (warnings allowed), 1 when any error was found, 2 when an input cannot be read
    (the parser's message is printed on stderr).
    """
    import pavonine  # noqa: F401  (registers the schema plugin before USD builds its registries)
    from pavonine.schemas.findings import validate_stage

    findings = []
    unreadable = []
    for path in paths:
        try:
            stage = open_stage(path)
        except ValueError as exc:
            unreadable.append({"file": path, "message": str(exc)})
            click.echo(f"error: {path}: {exc}", err=True)
            continue
        for finding in validate_stage(stage, file=path):
            if finding.severity == "WARNING" and not warnings:
                continue
            findings.append(finding)
    if as_json:
        click.echo(
            json.dumps(
                {"findings": [f.as_dict() for f in findings], "unreadable": unreadable}, indent=2
            )
        )
    else:
        for finding in findings:
            prefix = f"{finding.file}: " if len(paths) > 1 else ""
            click.echo(prefix + finding.line())
    if unreadable:
        sys.exit(EXIT_UNREADABLE)
    sys.exit(EXIT_ERRORS if any(f.severity == "ERROR" for f in findings) else EXIT_CLEAN)
