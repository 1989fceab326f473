"""Registration of Pavonine's USD plugin (the codeless ``PavonineFeatherAPI`` schema and validators).

USD builds its schema registry once, from the plugins known at that moment: a plugin registered
after the first stage (or ``Usd.SchemaRegistry``/``UsdValidation.ValidationRegistry``) was created
is *silently* ignored for schema definitions. ``import pavonine`` therefore calls :func:`register`
before anything else touches USD, and other processes use ``PXR_PLUGINPATH_NAME`` (see
``pavonine env``). This module imports only ``pxr.Plug`` so that ``import pavonine`` stays light.
"""

from __future__ import annotations

import os
from pathlib import Path

#: Directory holding ``plugInfo.json`` and ``generatedSchema.usda``.
PLUGIN_DIR = Path(__file__).resolve().parent
PLUG_INFO = PLUGIN_DIR / "plugInfo.json"

SCHEMA_NAME = "PavonineFeatherAPI"
PLUGIN_NAME = "pavonine"
VALIDATOR_PLUGIN_NAME = "pavonine.schemas.validation"
ENV_VAR = "PXR_PLUGINPATH_NAME"


class SchemaNotRegisteredError(RuntimeError):
    """The USD schema registry was built before Pavonine's plugin was registered."""


def register() -> None:
    """Register Pavonine's plugins with USD's plugin registry (idempotent, cheap)."""
    from pxr import Plug

    registry = Plug.Registry()
    if registry.GetPluginWithName(PLUGIN_NAME) is None:
        registry.RegisterPlugins(str(PLUG_INFO))


def env_value(existing: str | None = None) -> str:
    """``PXR_PLUGINPATH_NAME`` with Pavonine's plugin directory appended to ``existing``."""
    if existing is None:
        existing = os.environ.get(ENV_VAR, "")
    parts = [p for p in existing.split(os.pathsep) if p]
    mine = str(PLUGIN_DIR)
    if mine not in parts:
        parts.append(mine)
    return os.pathsep.join(parts)


def require_schema() -> None:
    """Raise :class:`SchemaNotRegisteredError` unless USD knows ``PavonineFeatherAPI``."""
    from pxr import Usd

    if Usd.SchemaRegistry().FindAppliedAPIPrimDefinition(SCHEMA_NAME) is None:
        raise SchemaNotRegisteredError(
            f"USD does not define {SCHEMA_NAME}: a USD stage or schema registry was created "
            "before pavonine registered its plugin. Import pavonine before using pxr.Usd, or "
            f"set {ENV_VAR} as printed by `pavonine env`."
        )
