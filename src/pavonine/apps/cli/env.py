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


#: Characters PowerShell reads as a single quote (it folds the typographic ones into ``'``).
POWERSHELL_QUOTES = "'\u2018\u2019\u201a\u201b"
SHELLS = ("sh", "fish", "powershell")


def quote(value: str, shell: str) -> str:
    """``value`` as one literal word of ``shell``: evaluating it never runs code.

    * ``sh`` (POSIX sh, bash, zsh, dash): single quotes, ``'`` written as ``'"'"'``
      (:func:`shlex.quote`).
    * ``fish``: single quotes, in which fish still reads backslash-backslash and
      backslash-quote as escapes, so both are escaped with a backslash.
    * ``powershell``: single quotes (no variable or subexpression expansion) in which each
      quote character, including the typographic ones PowerShell folds into ``'``, is doubled.
    """
    if shell == "sh":
        return shlex.quote(value)
    if shell == "fish":
        return "'" + value.replace("\\", "\\\\").replace("'", "\\'") + "'"
    if shell == "powershell":
        return "'" + "".join(c * 2 if c in POWERSHELL_QUOTES else c for c in value) + "'"
    raise ValueError(f"unknown shell {shell!r}; known: {', '.join(SHELLS)}")


def assignment(name: str, value: str, shell: str) -> str:
    """The line of ``shell`` that sets and exports ``name`` to ``value``."""
    if shell == "fish":
        return f"set -gx {name} {quote(value, 'fish')}"
    if shell == "powershell":
        return f"$env:{name} = {quote(value, 'powershell')}"
    return f"export {name}={quote(value, 'sh')}"


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
    type=click.Choice(SHELLS),
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
    USD builds without usdMtlx (usd-core) too. Existing values are kept. Values are quoted for
    the chosen shell, so evaluating the lines never runs code, whatever the paths contain.
    With --validators, PXR_PLUGINPATH_NAME also gets the validator plugin, which imports
    pavonine.schemas.validation.
    """
    for name, value in env_lines(validators).items():
        click.echo(assignment(name, value, shell))
