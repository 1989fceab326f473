"""Generate ``docs/cli.md`` from the click commands themselves, so the reference cannot drift.

python -m pavonine.apps.cli.reference > docs/cli.md
"""

from __future__ import annotations

from typing import Any

import click

from pavonine.apps.cli import cli
from pavonine.apps.cli.options import json_schema, required_extras

HEADER = """# `pavonine` command-line reference

Generated from the commands' own help by `python -m pavonine.apps.cli.reference > docs/cli.md`;
`tests/apps/test_cli_reference.py` fails when this page is stale.

## Conventions

Every command follows the same rules (`apps/cli/options.py`, imported as
`pavonine.apps.cli.options`, implements them; `tests/apps/test_cli_convention.py` walks every
registered command and checks them):

* **`-o/--output PATH`** is where the command writes: a file or a folder, as its help says.
  Optional extra outputs have their own names (`--png`, `--report`, `--json`, `--junit`).
* **`--json FILE|-`** on every command that reports: a JSON object with the documented keys
  below each command (a JSON Schema), written to FILE, or to stdout for `-` (then nothing else
  goes to stdout). Keys are only ever added. FILE is checked writable before the command starts,
  so an unwritable report path leaves nothing written.
* **`-v/--verbose`, `-q/--quiet`**, before the command or after it: messages go to stderr
  through Python's `logging` (rich's handler on a terminal, `level: message` lines otherwise);
  `-q` keeps only warnings and errors and hides progress bars, `-v` adds details, `-vv` debug.
  Progress bars are drawn on stderr, and only when it is a terminal.
* **`--threads N`** (or `$PAVONINE_THREADS`) on commands that compute: Dr.Jit, OpenImageIO and
  BLAS worker threads while the command runs [default: one per core]; a caller that runs commands
  in its own process (`CliRunner`, a tool) gets its previous limits back afterwards.
* **`--ocio-config`, `--display`, `--view`, `--exposure`** on commands that write display images
  (PNGs): the OpenColorIO display transform. The config defaults to `$OCIO`, else the pinned,
  versioned built-in `ocio://cg-config-v4.0.0_aces-v2.0_ocio-v2.5` with `sRGB - Display` /
  `Un-tone-mapped`; another config defaults to its own display and view. PNGs record the transform;
  `compare` decodes a PNG with the one it records. EXRs are always scene-linear Rec.709.
* **`--junit FILE`** on `validate` and `check-renders`: results as JUnit XML for CI test reports.
* **Errors** are one line on stderr, `error: <file, option or field>: <message>`, with exit status
  2 for bad input and usage errors (unknown option, bad value, missing argument, a missing optional
  extra) and nothing written; 1 where a command documents a "findings"/"differ" outcome.
* **Extras**: `pip install pavonine` has the optics and the schema (`spectra`, `figures`, `maps`,
  `validate`, `compare --method stat`, `baseline list`, `env`, `doctor`; PNGs through the pinned
  config's default view without OpenColorIO); `[convert]` adds `convert`, `bake`, `package`,
  `export`; `[render]` adds `render`, `check-renders`, `baseline update`, FLIP and reports in
  `compare`, and every other OCIO view or config; `demo` needs both; `[farm]` (Dask) adds
  `render --workers/--scheduler` and `convert --scheduler` (without it, a batch of images renders
  in this process); `[all]` is all three. Each command below says which extra it needs;
  a command whose extra is missing says which one to install, on one line, and exits with 2.
* **Shell completion** (click's): `eval "$(_PAVONINE_COMPLETE=bash_source pavonine)"` in
  `~/.bashrc`; `zsh_source` for zsh (`~/.zshrc`);
  `_PAVONINE_COMPLETE=fish_source pavonine | source` for fish.
"""


WIDTH = {"terminal_width": 100, "max_content_width": 100}


def schema_lines(schema: dict[str, Any], prefix: str = "") -> list[str]:
    """A JSON Schema's properties as Markdown bullets (``key`` (type, required): description)."""
    lines = []
    required = set(schema.get("required", []))
    for key, spec in schema.get("properties", {}).items():
        kind = spec.get("type", "enum" if "enum" in spec else "any")
        kind = " or ".join(kind) if isinstance(kind, list) else kind
        flags = f"{kind}, required" if key in required else kind
        text = spec.get("description", "")
        if "enum" in spec:
            text = (text + "; " if text else "") + "one of " + ", ".join(map(str, spec["enum"]))
        lines.append(f"{prefix}* `{key}` ({flags}){': ' + text if text else ''}")
        lines += schema_lines(spec, prefix + "  ")
        items = spec.get("items")
        if isinstance(items, dict) and "properties" in items:
            lines.append(f"{prefix}  * each item:")
            lines += schema_lines(items, prefix + "    ")
        extra = spec.get("additionalProperties")
        if isinstance(extra, dict) and "properties" in extra:
            lines.append(f"{prefix}  * each value:")
            lines += schema_lines(extra, prefix + "    ")
    return lines


def _sections(command: click.Command, ctx: click.Context, path: str) -> list[str]:
    """Help of ``command`` and, for groups, of each subcommand, depth first."""
    parts = [f"## {path}\n\n```text\n{command.get_help(ctx)}\n```\n"]
    extras = required_extras(command)
    if extras:
        names = ", ".join(f"`[{e}]`" for e in extras)
        parts.append(f"Needs the {names} extra{'s' * (len(extras) > 1)}.\n")
    schema = json_schema(command)
    if schema is not None:
        parts.append("`--json` report keys:\n\n" + "\n".join(schema_lines(schema)) + "\n")
    if isinstance(command, click.Group):
        for name in command.list_commands(ctx):
            sub = command.get_command(ctx, name)
            with click.Context(sub, info_name=name, parent=ctx, **WIDTH) as sub_ctx:
                parts += _sections(sub, sub_ctx, f"{path} {name}")
    return parts


def render_reference() -> str:
    """The Markdown reference of every registered command."""
    # The group's own context settings (``-h/--help``): click caches each command's help option,
    # so a context built without them would render differently depending on what ran first.
    with click.Context(cli, info_name="pavonine", **WIDTH, **cli.context_settings) as ctx:
        return "\n".join([HEADER, *_sections(cli, ctx, "pavonine")])


if __name__ == "__main__":
    print(render_reference(), end="")
