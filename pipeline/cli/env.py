"""``pavonine env``: the shell lines that let other USD tools see Pavonine's schema and node."""

from __future__ import annotations

import os
import shlex

import click

from pavonine.materials.materialx import MTLX_PATH
from pavonine.schemas.plugin import (
    ENV_VAR,
    SHADER_DEFS_DIR,
    SHADER_DEFS_EXTENSION,
    append_paths,
    env_value,
)

#: Where a USD build with usdMtlx looks for MaterialX node definitions.
MTLX_ENV_VAR = "PXR_MTLX_PLUGIN_SEARCH_PATHS"
#: Where Sdr's filesystem discovery looks for shader definition files, and which extensions it
#: takes (USD 25.08 and later; earlier builds read ``PXR_NDR_FS_PLUGIN_…``).
SDR_PATHS_ENV_VAR = "PXR_SDR_FS_PLUGIN_SEARCH_PATHS"
SDR_EXTS_ENV_VAR = "PXR_SDR_FS_PLUGIN_ALLOWED_EXTS"


def env_lines(validators: bool = False) -> dict[str, str]:
    """Variable → value: the schema plugin (and, on request, the validator plugin) appended to
    ``PXR_PLUGINPATH_NAME``, the folder of ``pavonine_feather.mtlx`` to
    ``PXR_MTLX_PLUGIN_SEARCH_PATHS``, and the shader definitions of the asset's MaterialX nodes
    (:mod:`pavonine.pipeline.shading.sdr_defs`) to Sdr's filesystem discovery (folder and
    ``usda`` extension); existing values are kept."""

    def append(name: str, paths: list[str]) -> str:
        return append_paths(os.environ.get(name, ""), paths)

    return {
        ENV_VAR: env_value(validators=validators),
        MTLX_ENV_VAR: append(MTLX_ENV_VAR, [str(MTLX_PATH.parent)]),
        SDR_PATHS_ENV_VAR: append(SDR_PATHS_ENV_VAR, [str(SHADER_DEFS_DIR)]),
        SDR_EXTS_ENV_VAR: append(SDR_EXTS_ENV_VAR, [SHADER_DEFS_EXTENSION]),
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
    """Print the environment that makes PavonineFeatherAPI and the MaterialX nodes visible to USD.

    Use it in processes that do not import pavonine (usdview, DCCs, other renderers):

        eval "$(pavonine env)"

    PXR_PLUGINPATH_NAME gets the schema's plugin folder (only the schema: any USD process can
    load it); PXR_MTLX_PLUGIN_SEARCH_PATHS gets the folder of pavonine_feather.mtlx (the node
    ND_pavonine_feather_surfaceshader, for USD builds with MaterialX).
    PXR_SDR_FS_PLUGIN_SEARCH_PATHS gets the USD shader definitions of the MaterialX nodes a
    converted asset uses and PXR_SDR_FS_PLUGIN_ALLOWED_EXTS gets usda, so that Sdr knows them in
    USD builds without usdMtlx (usd-core) too. Existing values are kept.
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
