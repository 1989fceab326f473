"""``pavonine env``: the shell line that lets other USD tools see Pavonine's schema."""

from __future__ import annotations

import shlex

import click

from pavonine.schemas.plugin import ENV_VAR, env_value


@click.command("env")
@click.option(
    "--shell",
    type=click.Choice(["sh", "fish", "powershell"]),
    default="sh",
    show_default=True,
    help="Syntax of the printed line.",
)
def env(shell: str) -> None:
    """Print the PXR_PLUGINPATH_NAME setting that registers PavonineFeatherAPI with USD.

    Use it in processes that do not import pavonine (usdview, DCCs, other renderers):

        eval "$(pavonine env)"

    The current value of PXR_PLUGINPATH_NAME is kept; Pavonine's schema directory is appended.
    """
    value = env_value()
    if shell == "fish":
        click.echo(f"set -gx {ENV_VAR} {shlex.quote(value)}")
    elif shell == "powershell":
        click.echo(f"$env:{ENV_VAR} = '{value}'")
    else:
        click.echo(f"export {ENV_VAR}={shlex.quote(value)}")
