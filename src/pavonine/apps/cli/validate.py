"""``pavonine validate PATH…``: USD's validators plus Pavonine's, one line per finding."""

from __future__ import annotations

import re
import sys
import time
from pathlib import Path

import click

from pavonine.apps.cli.options import (
    emit_json,
    json_option,
    junit_option,
    say,
)
from pavonine.apps.cli.values import max_pixels_option
from pavonine.base.errors import one_line_errors

EXIT_CLEAN, EXIT_ERRORS, EXIT_UNREADABLE = 0, 1, 2

_FINDING = {
    "type": "object",
    "required": ["severity", "path", "field", "message", "validator", "file"],
    "properties": {
        "severity": {"enum": ["ERROR", "WARNING"]},
        "path": {"type": "string", "description": "prim or property path ('/': the layer)"},
        "field": {"type": "string", "description": "attribute, or the error's name"},
        "message": {"type": "string"},
        "validator": {"type": "string", "description": "the UsdValidation validator"},
        "file": {"type": "string"},
    },
}
JSON_SCHEMA = {
    "type": "object",
    "required": ["files", "findings", "unreadable"],
    "properties": {
        "files": {"type": "integer", "description": "files given"},
        "findings": {"type": "array", "items": _FINDING},
        "unreadable": {
            "type": "array",
            "description": "inputs USD could not open (exit 2)",
            "items": {
                "type": "object",
                "required": ["file", "message"],
                "properties": {"file": {"type": "string"}, "message": {"type": "string"}},
            },
        },
    },
}

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
    from pavonine.schemas.findings import quiet_usd_stderr

    try:
        with quiet_usd_stderr():  # composition errors come back as findings, on one line each
            stage = Usd.Stage.Open(path)
    except Tf.ErrorException as exc:
        raise ValueError(parser_message(exc)) from None
    if stage is None:
        raise ValueError("USD could not open this file")
    return stage


@click.command("validate")
@click.argument("paths", nargs=-1, required=True, type=click.Path(dir_okay=False))
@click.option("--warnings/--no-warnings", default=True, show_default=True, help="Report warnings.")
@json_option(JSON_SCHEMA)
@junit_option
@max_pixels_option
@one_line_errors
def validate(
    paths: tuple[str, ...], warnings: bool, json_target: str | None, junit: Path | None
) -> None:
    """Validate USD layers: USD's own UsdValidation validators plus Pavonine's.

    One line per finding: ERROR|WARNING <prim path> <field>: <message>, then a summary
    ("N files, no findings" when clean). Exit status 0 when clean (warnings allowed), 1 when
    any error was found, 2 when an input cannot be read (the parser's message is printed on
    stderr). --junit writes one test case per file, failing on its errors.
    """
    import pavonine  # noqa: F401  (registers the schema plugin before USD builds its registries)
    from pavonine.apps.cli.usd_diagnostics import reported_by_command
    from pavonine.schemas.findings import validate_stage

    reported_by_command()  # USD's composition warnings are findings here
    findings = []
    unreadable = []
    seconds: dict[str, float] = {}
    for path in paths:
        start = time.perf_counter()
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
        seconds[path] = time.perf_counter() - start
    for finding in findings:
        prefix = f"{finding.file}: " if len(paths) > 1 else ""
        say(prefix + finding.line())
    say(summary(len(paths), findings, unreadable))
    emit_json(
        json_target,
        {
            "files": len(paths),
            "findings": [f.as_dict() for f in findings],
            "unreadable": unreadable,
        },
    )
    if junit is not None:
        _write_junit(junit, paths, findings, unreadable, seconds)
    if unreadable:
        sys.exit(EXIT_UNREADABLE)
    sys.exit(EXIT_ERRORS if any(f.severity == "ERROR" for f in findings) else EXIT_CLEAN)


def summary(files: int, findings: list, unreadable: list) -> str:
    """``N files, no findings``, or the counts of errors, warnings and unreadable files."""
    noun = "file" if files == 1 else "files"
    errors = sum(f.severity == "ERROR" for f in findings)
    warnings = len(findings) - errors
    if not findings and not unreadable:
        return f"{files} {noun}, no findings"
    parts = [f"{errors} error{'s' * (errors != 1)}", f"{warnings} warning{'s' * (warnings != 1)}"]
    if unreadable:
        parts.append(f"{len(unreadable)} unreadable")
    return f"{files} {noun}: {', '.join(parts)}"


def _write_junit(target: Path, paths, findings, unreadable, seconds) -> None:
    """One test case per file: a failure per error, warnings as output, unreadable as an error."""
    from pavonine.apps.cli.junit import Case, Problem, write_junit

    broken = {u["file"]: u["message"] for u in unreadable}
    cases = []
    for path in paths:
        case = Case("pavonine.validate", path, seconds.get(path, 0.0))
        if path in broken:
            case.problems.append(Problem(broken[path], kind="error"))
        mine = [f for f in findings if f.file == path]
        for finding in mine:
            if finding.severity == "ERROR":
                case.problems.append(
                    Problem(finding.line(), f"{finding.validator}: {finding.line()}")
                )
        case.output = "\n".join(f.line() for f in mine if f.severity == "WARNING")
        cases.append(case)
    write_junit(target, "pavonine validate", cases)
