"""The PavonineFeatherAPI as Pavonine's USD validators read it: attribute values typed as the
schema declares them (the schema fallback where an attribute is authored with another type),
whether a prim has the API, and the ``UsdValidation.ValidationError`` for one finding on a prim
or one of its attributes.
"""

from __future__ import annotations

import functools

from pxr import Usd, UsdValidation

from pavonine.schemas import authoring
from pavonine.schemas.plugin import SCHEMA_NAME

ERROR = UsdValidation.ValidationErrorType.Error
WARN = UsdValidation.ValidationErrorType.Warn

#: Error name -> field reported when the error is about prim metadata rather than a property.
METADATA_FIELD = {"FeatherApiNotOnMaterial": "apiSchemas"}


def validation_error(
    prim: Usd.Prim, name: str, message: str, attr: str | None = None, severity=ERROR
) -> UsdValidation.ValidationError:
    """A finding ``name`` on ``prim``, sited on its attribute ``attr`` when the prim has one."""
    has_property = attr is not None and prim.HasProperty(attr)
    path = prim.GetPath().AppendProperty(attr) if has_property else prim.GetPath()
    site = UsdValidation.ValidationErrorSite(prim.GetStage(), path)
    return UsdValidation.ValidationError(name, severity, [site], message)


@functools.cache
def _schema_definition() -> Usd.PrimDefinition | None:
    return Usd.SchemaRegistry().FindAppliedAPIPrimDefinition(SCHEMA_NAME)


def schema_type(name: str):
    """The value type the schema declares for property ``name`` (None if not a schema property)."""
    definition = _schema_definition()
    spec = definition.GetAttributeDefinition(name) if definition else None
    return spec.GetTypeName() if spec else None


def typed_attr(prim: Usd.Prim, name: str) -> Usd.Attribute | None:
    """The attribute, unless it is authored with a type other than the schema's."""
    attr = prim.GetAttribute(name)
    if not attr:
        return None
    declared, authored = schema_type(name), authoring.authored_type(attr)
    return attr if declared is None or authored in (None, declared) else None


def schema_value(prim: Usd.Prim, name: str):
    """The attribute's value; the schema fallback where it is authored with the wrong type
    (USD's own type-mismatch validator reports that)."""
    attr = typed_attr(prim, name)
    if attr is not None:
        return attr.Get()
    definition = _schema_definition()
    return definition.GetAttributeFallbackValue(name) if definition else None


def has_feather_api(prim: Usd.Prim) -> bool:
    """The prim has the PavonineFeatherAPI applied, or lists it (an unregistered schema)."""
    return SCHEMA_NAME in prim.GetAppliedSchemas() or SCHEMA_NAME in _listed_api_schemas(prim)


def _listed_api_schemas(prim: Usd.Prim) -> list[str]:
    listop = prim.GetMetadata("apiSchemas")
    return list(listop.GetAppliedItems()) if listop else []
