"""Generate ``docs/cli.md`` from the click commands themselves, so the reference cannot drift.

python -m pavonine.pipeline.cli.reference > docs/cli.md
"""

from __future__ import annotations

import click

from pavonine.pipeline.cli import cli

HEADER = """# `pavonine` command-line reference

Generated from the commands' own help by `python -m pavonine.pipeline.cli.reference > docs/cli.md`;
`tests/test_cli_reference.py` fails when this page is stale.

Every command reports bad input as one line `error: <file or field>: <message>` on stderr and exits
with status 2 (1 where a command documents a "findings"/"differ" outcome), writing nothing.
"""


WIDTH = {"terminal_width": 100, "max_content_width": 100}


def _sections(command: click.Command, ctx: click.Context, path: str) -> list[str]:
    """Help of ``command`` and, for groups, of each subcommand, depth first."""
    parts = [f"## {path}\n\n```text\n{command.get_help(ctx)}\n```\n"]
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
