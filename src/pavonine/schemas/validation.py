"""Pavonine's USD validators, registered with ``UsdValidation`` the way USD registers its own.

``validators/plugInfo.json`` declares the validators (plugin ``pavonine.schemas.validation``, keyword
``PavonineValidators``, schema type ``PavonineFeatherAPI``) so that USD's
``ValidationRegistry`` knows their metadata before anything is loaded; the first
``GetOrLoadValidatorByName`` imports this module (USD's Python-plugin loading), whose top level
registers the task functions with ``RegisterPluginPrimValidator`` — the Python counterpart of
``TF_REGISTRY_FUNCTION(UsdValidationRegistry)`` in a C++ plugin.

:func:`pavonine.schemas.findings.validate_stage` runs every registered validator (USD's own and
these) through one ``UsdValidation.ValidationContext`` for ``pavonine validate``. The plugin
folder is ``schemas/validators/``, separate from the schema's (``pavonine env --validators``).

The tasks live by what they check: :mod:`~pavonine.schemas.parameter_validators` (the API on a
Material; rod and layer parameters), :mod:`~pavonine.schemas.map_validators` (the six maps),
:mod:`~pavonine.schemas.shader_validators` (the derived MaterialX and preview shaders, baked
textures), all reading the schema through :mod:`~pavonine.schemas.feather_api`.
"""

from __future__ import annotations

from collections.abc import Callable

from pxr import UsdValidation

from pavonine.schemas.feather_api import ERROR, METADATA_FIELD, WARN
from pavonine.schemas.map_validators import feather_maps
from pavonine.schemas.parameter_validators import feather_api_on_material, feather_parameters
from pavonine.schemas.plugin import VALIDATOR_PLUGIN_NAME
from pavonine.schemas.shader_validators import feather_derived_shaders, prepare

KEYWORD = "PavonineValidators"


class ValidatorsNotRegisteredError(RuntimeError):
    """USD's validation registry was built before Pavonine's validator plugin was registered."""


#: Validator name (as in plugInfo.json) -> prim task.
TASKS: dict[str, Callable] = {
    "FeatherApiOnMaterial": feather_api_on_material,
    "FeatherParameters": feather_parameters,
    "FeatherMaps": feather_maps,
    "FeatherDerivedShaders": feather_derived_shaders,
}


def register() -> None:
    """Register the prim tasks with USD's ValidationRegistry (metadata from
    ``validators/plugInfo.json``, which must be known before the registry was first built)."""
    from pxr import Tf

    registry = UsdValidation.ValidationRegistry()
    for name, task in TASKS.items():
        full = f"{VALIDATOR_PLUGIN_NAME}:{name}"
        if registry.HasValidator(full):
            continue
        try:
            registry.RegisterPluginPrimValidator(full, task)
        except Tf.ErrorException:
            raise ValidatorsNotRegisteredError(
                f"USD does not know the validator {full}: UsdValidation.ValidationRegistry() was "
                "created before pavonine registered its validator plugin. Import pavonine before "
                "using pxr.UsdValidation, or set PXR_PLUGINPATH_NAME as printed by "
                "`pavonine env --validators`."
            ) from None


def validator_names() -> list[str]:
    """Fully qualified names of Pavonine's validators."""
    return [f"{VALIDATOR_PLUGIN_NAME}:{name}" for name in TASKS]


register()

__all__ = [
    "ERROR",
    "METADATA_FIELD",
    "TASKS",
    "WARN",
    "ValidatorsNotRegisteredError",
    "prepare",
    "validator_names",
]
