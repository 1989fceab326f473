"""Validator of the shaders derived from a PavonineFeatherAPI material's attributes: the bound
MaterialX shader's inputs and the UsdPreviewSurface's colour and roughness agree with the schema
attributes, and the baked textures were made from them. :func:`prepare` computes, on the main
thread, what this validator needs from Mitsuba.
"""

from __future__ import annotations

from pxr import Usd, UsdShade

from pavonine.materials import materialx
from pavonine.schemas import authoring
from pavonine.schemas.feather_api import WARN, has_feather_api, validation_error

PREVIEW_TOLERANCE = 2e-3


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
    if prim.IsPseudoRoot() or not has_feather_api(prim) or not prim.IsA(UsdShade.Material):
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
                validation_error(
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
                    validation_error(
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
                    validation_error(
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
                    validation_error(
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
                validation_error(
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
        validation_error(
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
        if has_feather_api(prim) and prim.IsA(UsdShade.Material):
            try:
                params = authoring.read_feather_parameters(prim).validate()
            except ValueError:
                continue
            _preview_color(params)
