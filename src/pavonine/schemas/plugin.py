"""Registration of Pavonine's two USD plugins: the schema, and (opt-in) the validators.

* ``schemas/plugInfo.json`` declares only the codeless ``PavonineFeatherAPI`` schema (a resource
  plugin): any USD process can load it, with or without Pavonine's Python package.
* ``schemas/validators/plugInfo.json`` declares Pavonine's ``UsdValidation`` validators, a Python
  plugin whose code is ``pavonine.schemas.validation``: only a process that can import
  ``pavonine`` may load it, so it lives in its own folder and is added on request
  (``pavonine env --validators``).

USD builds its schema registry and its validation registry once, from the plugins known at that
moment: a plugin registered after the first stage (or ``Usd.SchemaRegistry``) was created is
*silently* ignored for schema definitions, and one registered after the first
``UsdValidation.ValidationRegistry()`` for validators. ``import pavonine`` therefore calls
:func:`register` (both plugins: where Pavonine is importable its validators can load) before
anything else touches USD; other processes use ``PXR_PLUGINPATH_NAME`` (see ``pavonine env``).
This module imports only ``pxr.Plug`` so that ``import pavonine`` stays light.
"""

from __future__ import annotations

import os
from pathlib import Path

#: Directory holding the schema plugin: ``plugInfo.json`` and ``generatedSchema.usda``.
PLUGIN_DIR = Path(__file__).resolve().parent
PLUG_INFO = PLUGIN_DIR / "plugInfo.json"
#: Directory holding the validator plugin's ``plugInfo.json`` (Python code: ``validation.py``).
VALIDATORS_DIR = PLUGIN_DIR / "validators"
VALIDATORS_PLUG_INFO = VALIDATORS_DIR / "plugInfo.json"
#: Directory of USD shader definitions (``ND_….usda``) of the MaterialX nodes a converted asset
#: uses, for Sdr's filesystem discovery in USD builds without usdMtlx
#: (:mod:`pavonine.pipeline.shading.sdr_defs`).
SHADER_DEFS_DIR = PLUGIN_DIR / "shaderDefs"
#: Their extension: a discovery type of USD's shader-definition parser.
SHADER_DEFS_EXTENSION = "usda"

SCHEMA_NAME = "PavonineFeatherAPI"
PLUGIN_NAME = "pavonine"
VALIDATOR_PLUGIN_NAME = "pavonine.schemas.validation"
ENV_VAR = "PXR_PLUGINPATH_NAME"


class SchemaNotRegisteredError(RuntimeError):
    """The USD schema registry was built before Pavonine's plugin was registered."""


def register(validators: bool = True) -> None:
    """Register Pavonine's schema plugin, and its validator plugin unless ``validators`` is
    false, with USD's plugin registry (idempotent, cheap)."""
    from pxr import Plug

    registry = Plug.Registry()
    if registry.GetPluginWithName(PLUGIN_NAME) is None:
        registry.RegisterPlugins(str(PLUG_INFO))
    if validators and registry.GetPluginWithName(VALIDATOR_PLUGIN_NAME) is None:
        registry.RegisterPlugins(str(VALIDATORS_PLUG_INFO))


def plugin_dirs(validators: bool = False) -> list[str]:
    """The plugin folders a process needs: the schema's, plus the validators' on request."""
    dirs = [str(PLUGIN_DIR)]
    if validators:
        dirs.append(str(VALIDATORS_DIR))
    return dirs


def append_paths(existing: str | None, paths: list[str]) -> str:
    """``existing`` (an ``os.pathsep`` list) with ``paths`` appended, each at most once."""
    parts = [p for p in (existing or "").split(os.pathsep) if p]
    for path in paths:
        if path not in parts:
            parts.append(path)
    return os.pathsep.join(parts)


def env_value(existing: str | None = None, validators: bool = False) -> str:
    """``PXR_PLUGINPATH_NAME`` with Pavonine's plugin folder(s) appended to ``existing``."""
    if existing is None:
        existing = os.environ.get(ENV_VAR, "")
    return append_paths(existing, plugin_dirs(validators))


def require_schema() -> None:
    """Raise :class:`SchemaNotRegisteredError` unless USD knows ``PavonineFeatherAPI``."""
    from pxr import Usd

    if Usd.SchemaRegistry().FindAppliedAPIPrimDefinition(SCHEMA_NAME) is None:
        raise SchemaNotRegisteredError(
            f"USD does not define {SCHEMA_NAME}: a USD stage or schema registry was created "
            "before pavonine registered its plugin. Import pavonine before using pxr.Usd, or "
            f"set {ENV_VAR} as printed by `pavonine env`."
        )
