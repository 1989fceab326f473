"""The ``pavonine`` command line: a click group whose subcommands load lazily.

Each subcommand lives in its own module (``pavonine.apps.cli.*``); importing them lazily keeps
``pavonine --help`` fast and keeps Mitsuba/USD out of commands that do not need them. The shared
options and conventions are in :mod:`pavonine.apps.cli.options`, the group (global ``-v/-q``,
one-line errors) in :mod:`pavonine.apps.cli.group`.
"""

from __future__ import annotations

import click

from pavonine import __version__
from pavonine.apps.cli.group import PavonineGroup

# command name -> "module:attribute"; one line per command.
COMMANDS: dict[str, str] = {
    "demo": "pavonine.apps.cli.demo:demo",
    "doctor": "pavonine.apps.cli.doctor:doctor",
    "spectra": "pavonine.apps.cli.spectra:spectra",
    "figures": "pavonine.apps.cli.figures:figures",
    "render": "pavonine.apps.cli.render:render",
    "validate": "pavonine.apps.cli.validate:validate",
    "env": "pavonine.apps.cli.env:env",
    "compare": "pavonine.apps.cli.compare:compare",
    "baseline": "pavonine.apps.cli.baseline:baseline",
    "check-renders": "pavonine.apps.cli.check_renders:check_renders",
    "maps": "pavonine.apps.cli.maps:maps",
    "convert": "pavonine.apps.cli.convert:convert",
    "bake": "pavonine.apps.cli.bake:bake",
    "package": "pavonine.apps.cli.package:package",
    "export": "pavonine.apps.cli.export:export",
    "assemble": "pavonine.apps.cli.assemble:assemble",
    "view": "pavonine.apps.cli.view:view",
}


@click.group(
    "pavonine",
    cls=PavonineGroup,
    lazy_commands=COMMANDS,
    context_settings={"help_option_names": ["-h", "--help"]},
)
@click.version_option(__version__, prog_name="pavonine")
def cli() -> None:
    """Pavonine: peacock-feather structural colour, from optics to USD assets to spectral renders.

    Shell completion: eval "$(_PAVONINE_COMPLETE=bash_source pavonine)" (zsh_source, fish_source).
    """


def main(argv: list[str] | None = None) -> None:
    """Console-script entry point."""
    cli.main(args=argv, prog_name="pavonine", standalone_mode=True)
