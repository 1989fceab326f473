"""Validators of the rod and layer parameters on a PavonineFeatherAPI material: the API sits on
a Material, the six per-class arrays agree in length, and every value is physical (the rules
:meth:`pavonine.materials.parameters.FeatherParameters.validate` applies to the optics).
"""

from __future__ import annotations

import math

from pxr import Usd, UsdShade

from pavonine.materials import materialx
from pavonine.materials.parameters import (
    AXES,
    INTERFERENCE_MODES,
    LayerStack,
    ParameterError,
)
from pavonine.schemas import authoring
from pavonine.schemas.feather_api import (
    WARN,
    has_feather_api,
    schema_value,
    validation_error,
)
from pavonine.schemas.plugin import SCHEMA_NAME

ANGLE_MAX = 60.0
#: Tolerance of the preview colour drift check (linear sRGB, absolute).


def feather_api_on_material(prim: Usd.Prim, time_range=None) -> list:
    """PavonineFeatherAPI may only be applied to Material prims."""
    if prim.IsPseudoRoot() or not has_feather_api(prim):
        return []
    if prim.IsA(UsdShade.Material):
        return []
    kind = prim.GetTypeName() or "typeless prim"
    return [
        validation_error(
            prim,
            "FeatherApiNotOnMaterial",
            f"{SCHEMA_NAME} can only be applied to a Material, but this prim is a {kind}",
        )
    ]


def _class_arrays(prim: Usd.Prim) -> tuple[dict[str, list], list]:
    arrays: dict[str, list] = {}
    errors = []
    for (axis, field), (name, _vtype) in authoring.CLASS_ATTRS.items():
        value = schema_value(prim, name)
        if value is None:
            errors.append(
                validation_error(prim, "MissingValue", "no value and no schema fallback", name)
            )
            continue
        arrays[f"{axis}_{field}"] = [(float(v[0]), float(v[1])) for v in value]
    return arrays, errors


def _attr_of(axis: str, field: str) -> str:
    return authoring.CLASS_ATTRS[(axis, field)][0]


def _check_stack_values(prim: Usd.Prim, arrays: dict[str, list]) -> list:
    """Each class end's stack, checked by :meth:`LayerStack.validate` (the rules the optics use)."""
    errors = []
    n = min(len(v) for v in arrays.values())
    for axis in AXES:
        columns = [arrays.get(f"{axis}_{q}") for q in ("interval", "radius", "count")]
        if any(column is None for column in columns):
            continue
        for k in range(n):
            for e, end in enumerate(("black", "white")):
                stack = LayerStack(*(column[k][e] for column in columns))
                try:
                    stack.validate("stack")
                except ParameterError as exc:
                    quantity = exc.field.rsplit(".", 1)[1]
                    message = f"class {k} {end} end: {exc.reason}"
                    errors.append(
                        validation_error(prim, exc.kind, message, _attr_of(axis, quantity))
                    )
    return errors


def _check_scalars(prim: Usd.Prim) -> list:
    errors = []
    for name in ("pavonine:melaninIndex", "pavonine:mediumIndex", "pavonine:rodLength"):
        value = schema_value(prim, name)
        if value is None or not math.isfinite(value) or value <= 0:
            errors.append(
                validation_error(
                    prim, "NotPositive", f"must be positive and finite, got {value}", name
                )
            )
    n_ml, n_0 = (
        schema_value(prim, "pavonine:melaninIndex"),
        schema_value(prim, "pavonine:mediumIndex"),
    )
    if n_ml is not None and n_0 is not None and n_ml > 0 and n_0 > 0 and n_ml == n_0:
        errors.append(
            validation_error(
                prim,
                "NoIndexContrast",
                "equals pavonine:mediumIndex: the rods cannot reflect",
                "pavonine:melaninIndex",
                WARN,
            )
        )
    for name in ("pavonine:crescentSigma", "pavonine:blockSigma"):
        value = schema_value(prim, name)
        if value is None or not math.isfinite(value) or not 0 < value <= ANGLE_MAX:
            errors.append(
                validation_error(
                    prim,
                    "AngleOutOfRange",
                    f"must lie in (0, {ANGLE_MAX:g}] degrees, got {value}",
                    name,
                )
            )
    mode = schema_value(prim, "pavonine:interference")
    if mode not in INTERFERENCE_MODES:
        errors.append(
            validation_error(
                prim,
                "UnknownInterference",
                f"must be one of {list(INTERFERENCE_MODES)}, got {mode!r}",
                "pavonine:interference",
            )
        )
    color = schema_value(prim, "pavonine:melaninColor")
    if color is None or not all(math.isfinite(c) and 0.0 <= c <= 1.0 for c in color):
        errors.append(
            validation_error(
                prim,
                "ColorOutOfRange",
                f"components must lie in [0, 1], got {color}",
                "pavonine:melaninColor",
            )
        )
    return errors


def _check_lattice(prim: Usd.Prim) -> list:
    """The whole material through :meth:`FeatherParameters.validate`: optional per-class arrays,
    dispersive indices, and the rod lattice (an error in the physical mode, a warning per class
    and axis whose staggered rods would overlap in the paper modes)."""
    try:
        params = authoring.read_feather_parameters(prim)
    except ParameterError as exc:
        return [validation_error(prim, "ArrayLengthMismatch", exc.reason, exc.field)]
    try:
        params.validate()
    except ParameterError as exc:
        message = f"{exc.field}: {exc.reason}"
        return [validation_error(prim, exc.kind, message, authoring.attribute_of_field(exc.field))]
    return [
        validation_error(prim, "StaggeredRodsOverlap", message, _attr_of(axis, "radius"), WARN)
        for _, axis, message in params.geometry_warnings()
    ]


def feather_parameters(prim: Usd.Prim, time_range=None) -> list:
    """Array lengths agree (>= 1) and every value is physical."""
    if prim.IsPseudoRoot() or not has_feather_api(prim):
        return []
    arrays, errors = _class_arrays(prim)
    if arrays:
        lengths = {_attr_of(*key.split("_", 1)): len(v) for key, v in arrays.items()}
        reference = (
            lengths[_attr_of("long", "interval")]
            if _attr_of("long", "interval") in lengths
            else max(lengths.values())
        )
        for name, n in lengths.items():
            if n != reference:
                errors.append(
                    validation_error(
                        prim,
                        "ArrayLengthMismatch",
                        f"has {n} class{'es' * (n != 1)} but pavonine:long:layerInterval has {reference}; "
                        "all six per-class arrays must have the same length",
                        name,
                    )
                )
            elif n == 0:
                errors.append(
                    validation_error(prim, "NoClasses", "needs at least one ocellar class", name)
                )
        errors += _check_stack_values(prim, arrays)
    errors += _check_scalars(prim)
    if not errors:
        errors += _check_lattice(prim)
    if len(next(iter(arrays.values()), [])) > materialx.MAX_CLASSES:
        errors.append(
            validation_error(
                prim,
                "TooManyClassesForMaterialX",
                f"MaterialX shader carries only the first {materialx.MAX_CLASSES} classes",
                _attr_of("long", "interval"),
                WARN,
            )
        )
    return errors
