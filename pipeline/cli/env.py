"""``pavonine env``: the shell lines that let other USD tools see Pavonine's schema and node."""

from __future__ import annotations

import os
import shlex

import click

from pavonine.materials.materialx import MTLX_PATH
from pavonine.schemas.plugin import ENV_VAR, append_paths, env_value

#: Where a USD build with usdMtlx looks for MaterialX node definitions.
MTLX_ENV_VAR = "PXR_MTLX_PLUGIN_SEARCH_PATHS"


def env_lines(validators: bool = False) -> dict[str, str]:
    """Variable → value: the schema plugin (and, on request, the validator plugin) appended to
    ``PXR_PLUGINPATH_NAME``, and the folder of ``pavonine_feather.mtlx`` appended to
    ``PXR_MTLX_PLUGIN_SEARCH_PATHS``; existing values are kept."""
    return {
        ENV_VAR: env_value(validators=validators),
        MTLX_ENV_VAR: append_paths(os.environ.get(MTLX_ENV_VAR, ""), [str(MTLX_PATH.parent)]),
    }


@click.command("env")
@click.option(
    "--shell",
    type=click.Choice(["sh", "fish", "powershell"]),
    default="sh",
    show_default=True,
    help="Syntax of the printed lines.",
)
@click.option(
    "--validators",
    is_flag=True,
    help="Also register Pavonine's USD validators (a Python plugin: only for a Python that can "
    "import pavonine).",
)
def env(shell: str, validators: bool) -> None:
    """Print the environment that makes PavonineFeatherAPI and the MaterialX node visible to USD.

    Use it in processes that do not import pavonine (usdview, DCCs, other renderers):

        eval "$(pavonine env)"

    PXR_PLUGINPATH_NAME gets the schema's plugin folder (only the schema: any USD process can
    load it); PXR_MTLX_PLUGIN_SEARCH_PATHS gets the folder of pavonine_feather.mtlx (the node
    ND_pavonine_feather_surfaceshader, for USD builds with MaterialX). Existing values are kept.
    With --validators, PXR_PLUGINPATH_NAME also gets the validator plugin, which imports
    pavonine.schemas.validation.
    """
    for name, value in env_lines(validators).items():
        if shell == "fish":
            click.echo(f"set -gx {name} {shlex.quote(value)}")
        elif shell == "powershell":
            click.echo(f"$env:{name} = '{value}'")
        else:
            click.echo(f"export {name}={shlex.quote(value)}")
