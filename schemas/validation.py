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
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Iterable

from pxr import Usd, UsdShade, UsdValidation

from pavonine.materials import materialx
from pavonine.materials.parameters import (
    AXES,
    INTERFERENCE_MODES,
    LayerStack,
    ParameterError,
)
from pavonine.schemas import authoring
from pavonine.schemas.plugin import SCHEMA_NAME, VALIDATOR_PLUGIN_NAME

KEYWORD = "PavonineValidators"


class ValidatorsNotRegisteredError(RuntimeError):
    """USD's validation registry was built before Pavonine's validator plugin was registered."""


ERROR = UsdValidation.ValidationErrorType.Error
WARN = UsdValidation.ValidationErrorType.Warn

#: Largest map side accepted (pixels); smallest side below which a map is suspicious.
MAX_MAP_SIZE = 16384
MIN_MAP_SIZE = 16
#: Angles in degrees: the normal spreads must lie in (0, ANGLE_MAX].
ANGLE_MAX = 60.0
#: Tolerance of the preview colour drift check (linear sRGB, absolute).
PREVIEW_TOLERANCE = 2e-3


# ---------------------------------------------------------------------------------------------
# Helpers building UsdValidation errors
# ---------------------------------------------------------------------------------------------


#: Error name -> field reported when the error is about prim metadata rather than a property.
METADATA_FIELD = {"FeatherApiNotOnMaterial": "apiSchemas"}


def _error(
    prim: Usd.Prim, name: str, message: str, attr: str | None = None, severity=ERROR
) -> UsdValidation.ValidationError:
    has_property = attr is not None and prim.HasProperty(attr)
    path = prim.GetPath().AppendProperty(attr) if has_property else prim.GetPath()
    site = UsdValidation.ValidationErrorSite(prim.GetStage(), path)
    return UsdValidation.ValidationError(name, severity, [site], message)


@functools.cache
def _schema_definition() -> Usd.PrimDefinition | None:
    return Usd.SchemaRegistry().FindAppliedAPIPrimDefinition(SCHEMA_NAME)


def _schema_type(name: str):
    """The value type the schema declares for property ``name`` (None if not a schema property)."""
    definition = _schema_definition()
    spec = definition.GetAttributeDefinition(name) if definition else None
    return spec.GetTypeName() if spec else None


def _typed_attr(prim: Usd.Prim, name: str) -> Usd.Attribute | None:
    """The attribute, unless it is authored with a type other than the schema's."""
    attr = prim.GetAttribute(name)
    if not attr:
        return None
    declared, authored = _schema_type(name), authoring.authored_type(attr)
    return attr if declared is None or authored in (None, declared) else None


def _get(prim: Usd.Prim, name: str):
    """The attribute's value; the schema fallback where it is authored with the wrong type
    (USD's own type-mismatch validator reports that)."""
    attr = _typed_attr(prim, name)
    if attr is not None:
        return attr.Get()
    definition = _schema_definition()
    return definition.GetAttributeFallbackValue(name) if definition else None


def _has_feather_api(prim: Usd.Prim) -> bool:
    return SCHEMA_NAME in prim.GetAppliedSchemas() or SCHEMA_NAME in _listed_api_schemas(prim)


def _listed_api_schemas(prim: Usd.Prim) -> list[str]:
    listop = prim.GetMetadata("apiSchemas")
    return list(listop.GetAppliedItems()) if listop else []


# ---------------------------------------------------------------------------------------------
# Validators (prim tasks: (prim, timeRange) -> [ValidationError])
# ---------------------------------------------------------------------------------------------


def feather_api_on_material(prim: Usd.Prim, time_range=None) -> list:
    """PavonineFeatherAPI may only be applied to Material prims."""
    if prim.IsPseudoRoot() or not _has_feather_api(prim):
        return []
    if prim.IsA(UsdShade.Material):
        return []
    kind = prim.GetTypeName() or "typeless prim"
    return [
        _error(
            prim,
            "FeatherApiNotOnMaterial",
            f"{SCHEMA_NAME} can only be applied to a Material, but this prim is a {kind}",
        )
    ]


def _class_arrays(prim: Usd.Prim) -> tuple[dict[str, list], list]:
    arrays: dict[str, list] = {}
    errors = []
    for (axis, field), (name, _vtype) in authoring.CLASS_ATTRS.items():
        value = _get(prim, name)
        if value is None:
            errors.append(_error(prim, "MissingValue", "no value and no schema fallback", name))
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
                    errors.append(_error(prim, exc.kind, message, _attr_of(axis, quantity)))
    return errors


def _check_scalars(prim: Usd.Prim) -> list:
    errors = []
    for name in ("pavonine:melaninIndex", "pavonine:mediumIndex", "pavonine:rodLength"):
        value = _get(prim, name)
        if value is None or not math.isfinite(value) or value <= 0:
            errors.append(
                _error(prim, "NotPositive", f"must be positive and finite, got {value}", name)
            )
    n_ml, n_0 = _get(prim, "pavonine:melaninIndex"), _get(prim, "pavonine:mediumIndex")
    if n_ml is not None and n_0 is not None and n_ml > 0 and n_0 > 0 and n_ml == n_0:
        errors.append(
            _error(
                prim,
                "NoIndexContrast",
                "equals pavonine:mediumIndex: the rods cannot reflect",
                "pavonine:melaninIndex",
                WARN,
            )
        )
    for name in ("pavonine:crescentSigma", "pavonine:blockSigma"):
        value = _get(prim, name)
        if value is None or not math.isfinite(value) or not 0 < value <= ANGLE_MAX:
            errors.append(
                _error(
                    prim,
                    "AngleOutOfRange",
                    f"must lie in (0, {ANGLE_MAX:g}] degrees, got {value}",
                    name,
                )
            )
    mode = _get(prim, "pavonine:interference")
    if mode not in INTERFERENCE_MODES:
        errors.append(
            _error(
                prim,
                "UnknownInterference",
                f"must be one of {list(INTERFERENCE_MODES)}, got {mode!r}",
                "pavonine:interference",
            )
        )
    color = _get(prim, "pavonine:melaninColor")
    if color is None or not all(math.isfinite(c) and 0.0 <= c <= 1.0 for c in color):
        errors.append(
            _error(
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
        return [_error(prim, "ArrayLengthMismatch", exc.reason, exc.field)]
    try:
        params.validate()
    except ParameterError as exc:
        message = f"{exc.field}: {exc.reason}"
        return [_error(prim, exc.kind, message, authoring.attribute_of_field(exc.field))]
    return [
        _error(prim, "StaggeredRodsOverlap", message, _attr_of(axis, "radius"), WARN)
        for _, axis, message in params.geometry_warnings()
    ]


def feather_parameters(prim: Usd.Prim, time_range=None) -> list:
    """Array lengths agree (>= 1) and every value is physical."""
    if prim.IsPseudoRoot() or not _has_feather_api(prim):
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
                    _error(
                        prim,
                        "ArrayLengthMismatch",
                        f"has {n} classes but pavonine:long:layerInterval has {reference}; "
                        "all six per-class arrays must have the same length",
                        name,
                    )
                )
            elif n == 0:
                errors.append(_error(prim, "NoClasses", "needs at least one ocellar class", name))
        errors += _check_stack_values(prim, arrays)
    errors += _check_scalars(prim)
    if not errors:
        errors += _check_lattice(prim)
    if len(next(iter(arrays.values()), [])) > materialx.MAX_CLASSES:
        errors.append(
            _error(
                prim,
                "TooManyClassesForMaterialX",
                f"MaterialX shader carries only the first {materialx.MAX_CLASSES} classes",
                _attr_of("long", "interval"),
                WARN,
            )
        )
    return errors


def _texture_shaders(material: Usd.Prim) -> Iterable[UsdShade.Shader]:
    for prim in Usd.PrimRange(material):
        shader = UsdShade.Shader(prim)
        if shader and shader.GetShaderId() == "UsdUVTexture":
            yield shader


def _image_problems(path: str) -> tuple[list[tuple[str, str, object]], tuple[int, int] | None]:
    """[(severity, name, message)] for one image behind a resolved asset path (a file, or a
    member of a ``.usdz`` package read through Ar), and its (width, height)."""
    import numpy as np
    import OpenImageIO as oiio

    from pavonine.asset_io import local_file
    from pavonine.limits import check_image_spec, regular_file
    from pavonine.pipeline.errors import InputError

    problems: list[tuple[str, str, object]] = []
    try:
        local = local_file(path)
    except OSError as exc:
        return [(ERROR, "MapMissing", f"cannot read {path}: {exc.strerror or exc}")], None
    try:
        regular_file(local, path)  # never open a FIFO or a device: it would block or not end
    except InputError as exc:
        return [(ERROR, "MapNotAnImage", str(exc))], None
    inp = oiio.ImageInput.open(local)
    if inp is None:
        message = oiio.geterror() or "unknown format"
        return [
            (ERROR, "MapNotAnImage", f"OpenImageIO cannot read {path}: {message.splitlines()[0]}")
        ], None
    try:
        spec = inp.spec()
        size = (spec.width, spec.height)
        if min(size) < 1 or max(size) > MAX_MAP_SIZE:
            problems.append(
                (
                    ERROR,
                    "MapSize",
                    f"{path} is {size[0]}x{size[1]}; sides must be 1..{MAX_MAP_SIZE}",
                )
            )
        elif min(size) < MIN_MAP_SIZE:
            problems.append((WARN, "MapSize", f"{path} is only {size[0]}x{size[1]} pixels"))
        if not problems:  # within the sides, the pixel budget (pavonine.limits) may still be lower
            try:
                check_image_spec(path, spec)
            except InputError as exc:
                problems.append((ERROR, "MapSize", str(exc)))
        colour = spec.nchannels - (1 if spec.alpha_channel >= 0 else 0)
        if spec.nchannels > 4:
            problems.append(
                (
                    ERROR,
                    "MapChannels",
                    f"{path} has {spec.nchannels} channels; expected 1 (grey) to 4",
                )
            )
        elif colour >= 3 and not any(p[0] == ERROR for p in problems):  # never decode a refused map
            pixels = inp.read_image(0, 0, 0, 3, "float")
            if pixels is None:
                problems.append(
                    (
                        ERROR,
                        "MapNotAnImage",
                        f"OpenImageIO cannot read pixels of {path}: {inp.geterror()}",
                    )
                )
            else:
                spread = float(np.max(np.ptp(np.asarray(pixels).reshape(-1, 3), axis=1)))
                if spread > 1.0 / 255.0:
                    problems.append(
                        (
                            WARN,
                            "MapNotGrey",
                            f"{path} has colour channels that differ (by up to {spread:.3f}); "
                            "Pavonine reads its first channel",
                        )
                    )
    finally:
        inp.close()
    return problems, size


def feather_maps(prim: Usd.Prim, time_range=None) -> list:
    """Maps exist, load with OpenImageIO, are grey (or convertible), have sane sizes, read raw."""
    if prim.IsPseudoRoot() or not _has_feather_api(prim):
        return []
    errors = []
    sizes: dict[str, tuple[int, int]] = {}
    for name in authoring.MAP_ATTRS.values():
        attr = _typed_attr(prim, name)  # a wrongly typed map is reported by feather_parameters
        value = attr.Get() if attr else None
        if value is None or not value.path:
            continue
        space = attr.GetColorSpace() if attr.HasColorSpace() else "raw"
        if space != "raw":
            errors.append(
                _error(
                    prim,
                    "MapColorSpace",
                    f"data map must be read raw, colorSpace is {space!r}",
                    name,
                )
            )
        if not value.resolvedPath:
            where = authoring.anchored_path(attr, value.path)
            errors.append(
                _error(
                    prim, "MapMissing", f"@{value.path}@ does not exist (looked for {where})", name
                )
            )
            continue
        problems, size = _image_problems(value.resolvedPath)
        for severity, err_name, message in problems:
            errors.append(_error(prim, err_name, message, name, severity))
        if size is not None:
            sizes[name] = size
    if len(set(sizes.values())) > 1:
        detail = ", ".join(f"{n.split(':')[1]} {w}x{h}" for n, (w, h) in sizes.items())
        first = next(iter(sizes))
        errors.append(_error(prim, "MapSizesDiffer", f"maps differ in size: {detail}", first, WARN))
    maps = {
        v.resolvedPath
        for v in (_get(prim, n) for n in authoring.MAP_ATTRS.values())
        if v and v.resolvedPath
    }
    for shader in _texture_shaders(prim):
        file_value = shader.GetInput("file").Get() if shader.GetInput("file") else None
        if file_value is None or file_value.resolvedPath not in maps:
            continue
        source = shader.GetInput("sourceColorSpace")
        space = source.Get() if source else None
        if space != "raw":
            errors.append(
                _error(
                    shader.GetPrim(),
                    "MapColorSpace",
                    f"reads data map {file_value.path} with sourceColorSpace {space!r}; must be 'raw'",
                    "inputs:sourceColorSpace",
                )
            )
    return errors


def _shader_at(material: UsdShade.Material, render_context: str) -> UsdShade.Shader | None:
    output = material.GetSurfaceOutput(render_context)
    if not output:
        return None
    sources = output.GetConnectedSources()[0] if output.HasConnectedSource() else []
    return UsdShade.Shader(sources[0].source.GetPrim()) if sources else None


def _same(a, b) -> bool:
    if isinstance(a, str) or isinstance(b, str):
        return a == b
    try:
        return [float(x) for x in a] == [float(x) for x in b]
    except TypeError:
        return float(a) == float(b)


def _fmt(value) -> str:
    """A value for a message: floats to 6 significant digits (USD values are float32)."""
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, (tuple, list)) or (
        hasattr(value, "__len__") and not isinstance(value, str)
    ):
        return (
            "(" + ", ".join(_fmt(float(v)) if isinstance(v, float) else str(v) for v in value) + ")"
        )
    return str(value)


def feather_derived_shaders(prim: Usd.Prim, time_range=None) -> list:
    """The bound MaterialX and UsdPreviewSurface shaders agree with the schema attributes."""
    if prim.IsPseudoRoot() or not _has_feather_api(prim) or not prim.IsA(UsdShade.Material):
        return []
    try:
        params = authoring.read_feather_parameters(prim).validate()
    except (ValueError, TypeError):
        return []  # reported by feather_parameters; nothing sound to derive from
    material = UsdShade.Material(prim)
    errors = []
    mtlx = _shader_at(material, authoring.MTLX_RENDER_CONTEXT)
    # Derived shaders are optional (a hand-written layer may have none); present ones must agree.
    if mtlx is not None:
        if mtlx.GetShaderId() != materialx.NODEDEF:
            errors.append(
                _error(
                    mtlx.GetPrim(),
                    "WrongShaderId",
                    f"is {mtlx.GetShaderId()!r}, expected {materialx.NODEDEF}",
                    "info:id",
                    WARN,
                )
            )
        expected = materialx.input_values(params)
        known = set(materialx.input_names())
        for inp in mtlx.GetInputs():
            name = inp.GetBaseName()
            if name not in known:
                errors.append(
                    _error(
                        mtlx.GetPrim(),
                        "UnknownShaderInput",
                        f"{materialx.NODEDEF} has no input {name!r}",
                        f"inputs:{name}",
                    )
                )
        for name, value in expected.items():
            if name in materialx.PER_TEXEL_INPUTS:
                continue  # per-texel values (maps), not derived from the schema
            inp = mtlx.GetInput(name)
            if not inp:
                continue
            if inp.HasConnectedSource():
                continue
            authored = inp.Get()
            if authored is None:
                continue
            if not _same(authored, authoring.mtlx_usd_value(name, value)):
                errors.append(
                    _error(
                        mtlx.GetPrim(),
                        "DerivedValueDrift",
                        f"is {_fmt(authored)}, but the schema attributes give {_fmt(value)} "
                        "(re-author with pavonine.schemas.authoring.sync_derived_shaders)",
                        f"inputs:{name}",
                    )
                )
    preview = _shader_at(material, "")
    if preview is not None and preview.GetShaderId() == "UsdPreviewSurface":
        diffuse = preview.GetInput("diffuseColor")
        authored = diffuse.Get() if diffuse and not diffuse.HasConnectedSource() else None
        if authored is not None:
            derived = _preview_color(params)
            if max(abs(a - b) for a, b in zip(authored, derived, strict=True)) > PREVIEW_TOLERANCE:
                errors.append(
                    _error(
                        preview.GetPrim(),
                        "DerivedValueDrift",
                        f"is {tuple(round(c, 4) for c in authored)}, but the optics model gives "
                        f"{tuple(round(c, 4) for c in derived)} for these schema attributes",
                        "inputs:diffuseColor",
                    )
                )
        rough = preview.GetInput("roughness")
        authored_r = rough.Get() if rough and not rough.HasConnectedSource() else None
        if authored_r is not None and abs(authored_r - authoring.preview_roughness(params)) > 1e-5:
            errors.append(
                _error(
                    preview.GetPrim(),
                    "DerivedValueDrift",
                    f"is {authored_r:g}, but pavonine:crescentSigma gives {authoring.preview_roughness(params):g}",
                    "inputs:roughness",
                )
            )
    errors += _stale_bake(prim, params)
    return errors


def _stale_bake(prim: Usd.Prim, params) -> list:
    """A warning when the textures were baked from other parameters (``customData`` recorded
    by ``pavonine bake``/``convert``)."""
    record = prim.GetCustomDataByKey(authoring.BAKE_KEY)
    if not isinstance(record, dict) or "parameters" not in record:
        return []
    if record["parameters"] == authoring.parameters_digest(params):
        return []
    return [
        _error(
            prim,
            "BakedTexturesStale",
            "the baked textures were made from other schema attributes; re-run pavonine bake",
            None,
            WARN,
        )
    ]


_PREVIEW_CACHE: dict = {}


def _preview_color(params) -> tuple[float, float, float]:
    """Preview colour of ``params``, memoised; :func:`prepare` fills the cache on the main
    thread first because USD runs prim validators on worker threads and Mitsuba must not be
    first imported concurrently."""
    if params not in _PREVIEW_CACHE:
        _PREVIEW_CACHE[params] = authoring.preview_color(params)
    return _PREVIEW_CACHE[params]


def prepare(stage: Usd.Stage) -> None:
    """Compute what validators need from Mitsuba on this (the main) thread; see
    :func:`_preview_color`."""
    for prim in stage.Traverse():
        if _has_feather_api(prim) and prim.IsA(UsdShade.Material):
            try:
                params = authoring.read_feather_parameters(prim).validate()
            except ValueError:
                continue
            _preview_color(params)


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

__all__ = ["TASKS", "ValidatorsNotRegisteredError", "validator_names"]
