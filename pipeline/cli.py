"""The ``pavonine`` command line: a click group whose subcommands load lazily.

Each subcommand lives in its own module (``pavonine.pipeline.cmd_*``); importing them lazily keeps
``pavonine --help`` fast and keeps Mitsuba/USD out of commands that do not need them.
"""

from __future__ import annotations

import importlib
import sys

import click

from pavonine import __version__

# command name -> "module:attribute"; one line per command.
COMMANDS: dict[str, str] = {
    "demo": "pavonine.pipeline.cmd_demo:demo",
    "doctor": "pavonine.pipeline.cmd_doctor:doctor",
    "spectra": "pavonine.pipeline.cmd_spectra:spectra",
    "figures": "pavonine.pipeline.cmd_figures:figures",
    "render": "pavonine.pipeline.cmd_render:render",
    "validate": "pavonine.pipeline.cmd_validate:validate",
    "env": "pavonine.pipeline.cmd_env:env",
    "compare": "pavonine.pipeline.cmd_compare:compare",
    "baseline": "pavonine.pipeline.cmd_baseline:baseline",
    "check-renders": "pavonine.pipeline.cmd_check_renders:check_renders",
    "maps": "pavonine.pipeline.cmd_maps:maps",
    "convert": "pavonine.pipeline.cmd_convert:convert",
}


class LazyGroup(click.Group):
    """A click group that imports a subcommand only when it is invoked or listed in help."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(COMMANDS)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        target = COMMANDS.get(cmd_name)
        if target is None:
            return None
        module_name, attr = target.split(":")
        return getattr(importlib.import_module(module_name), attr)


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="pavonine")
def cli() -> None:
    """Pavonine: peacock-feather structural colour, from optics to USD assets to spectral renders."""


def main(argv: list[str] | None = None) -> None:
    """Console-script entry point."""
    cli.main(args=argv, prog_name="pavonine", standalone_mode=True)


if __name__ == "__main__":
    main(sys.argv[1:])
