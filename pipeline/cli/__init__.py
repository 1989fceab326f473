"""The ``pavonine`` command line: a click group whose subcommands load lazily.

Each subcommand lives in its own module (``pavonine.pipeline.cli.*``); importing them lazily keeps
``pavonine --help`` fast and keeps Mitsuba/USD out of commands that do not need them.
"""

from __future__ import annotations

import importlib

import click

from pavonine import __version__

# command name -> "module:attribute"; one line per command.
COMMANDS: dict[str, str] = {
    "demo": "pavonine.pipeline.cli.demo:demo",
    "doctor": "pavonine.pipeline.cli.doctor:doctor",
    "spectra": "pavonine.pipeline.cli.spectra:spectra",
    "figures": "pavonine.pipeline.cli.figures:figures",
    "render": "pavonine.pipeline.cli.render:render",
    "validate": "pavonine.pipeline.cli.validate:validate",
    "env": "pavonine.pipeline.cli.env:env",
    "compare": "pavonine.pipeline.cli.compare:compare",
    "baseline": "pavonine.pipeline.cli.baseline:baseline",
    "check-renders": "pavonine.pipeline.cli.check_renders:check_renders",
    "maps": "pavonine.pipeline.cli.maps:maps",
    "convert": "pavonine.pipeline.cli.convert:convert",
    "bake": "pavonine.pipeline.cli.bake:bake",
    "package": "pavonine.pipeline.cli.package:package",
    "export": "pavonine.pipeline.cli.export:export",
    "assemble": "pavonine.pipeline.cli.assemble:assemble",
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
