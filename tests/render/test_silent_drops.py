"""A silent drop is a bug: every UsdPreviewSurface input and every UsdLux attribute, set away from
its fallback, either changes the rendered image or produces a warning that names it.

The lists come from USD itself — the ``Sdr`` definition of UsdPreviewSurface and the schema
registry's definitions of the light types and the API schemas they take (``ShapingAPI``,
``ShadowAPI``, ``MeshLightAPI``...) — so an input or attribute added to USD is covered the day
usd-core ships it. Each variation is first translated without rendering (cheap); only when no
new warning names it is it rendered, and the image must then differ from the base image rendered
with the same seed (identical scenes give bit-identical images).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from pxr import Gf, Sdf, Sdr, Usd, UsdGeom, UsdLux
from render_helpers import bind, image, new_stage, preview, quad, render, sun

from pavonine.base.backend import select_variant
from pavonine.render.delegate import StageDelegate
from pavonine.render.diagnostics import Diagnostics, StageWarning
from pavonine.render.lights.common import NOT_LIGHTING, VIEWPORT_ONLY, lux_property_names

pytestmark = pytest.mark.render
LIGHT_TYPES = ("DistantLight", "SphereLight", "RectLight", "DiskLight", "CylinderLight",
               "DomeLight", "DomeLight_1")  # fmt: skip
APIS = ("ShapingAPI", "ShadowAPI")
#: the base each light starts from, so that every attribute can matter (e.g. colorTemperature
#: needs enableColorTemperature, a sun's normalize needs an angle, focus needs a cone)
LIGHT_BASE = {
    "inputs:enableColorTemperature": True,
    "inputs:colorTemperature": 4000.0,
    "inputs:intensity": 2.0,
    "inputs:angle": 2.0,
    "inputs:width": 0.5,
    "inputs:height": 0.4,
    "inputs:radius": 0.3,
    "inputs:length": 0.6,
    "treatAsPoint": True,
    "inputs:shaping:cone:angle": 60.0,
    "inputs:shaping:focus": 2.0,
}
#: no effect on an image by definition: handled by other translators, or a viewport guide
NO_EFFECT = {"xformOpOrder", "visibility", "purpose", "proxyPrim", "extent", "guideRadius"}


def test_the_no_effect_list_is_what_the_light_audit_skips():
    assert NO_EFFECT == NOT_LIGHTING | VIEWPORT_ONLY


def different(value, type_name: Sdf.ValueTypeName, allowed: list[str], tmp_path):
    """A value of ``type_name`` that differs from ``value`` (the fallback or the base value)."""
    if type_name == Sdf.ValueTypeNames.Asset:
        return Sdf.AssetPath(image(tmp_path / "other.exr", np.full((4, 8, 3), 0.3, np.float32)))
    if type_name == Sdf.ValueTypeNames.Bool:
        return not bool(value)
    if type_name in (Sdf.ValueTypeNames.Token, Sdf.ValueTypeNames.String):
        options = [a for a in allowed if a != value]
        return options[-1] if options else "pavonineTest"  # the last: farthest from the default
    if type_name == Sdf.ValueTypeNames.PathExpression:
        return Sdf.PathExpression("/Nothing")
    if type_name == Sdf.ValueTypeNames.Int:
        return 1 - int(value or 0)
    scalar = type_name.scalarType
    if scalar in (
        Sdf.ValueTypeNames.Color3f,
        Sdf.ValueTypeNames.Float3,
        Sdf.ValueTypeNames.Normal3f,
    ):
        base = np.asarray(value if value is not None else (0, 0, 0), dtype=float)
        other = (0.9, 0.3, 0.1) if not np.allclose(base, (0.9, 0.3, 0.1)) else (0.1, 0.3, 0.9)
        return (
            Gf.Vec3f(*(0.6, 0.0, 0.8))
            if type_name == Sdf.ValueTypeNames.Normal3f
            else Gf.Vec3f(*other)
        )
    number = float(value) if value is not None else 0.0
    return 30.0 if "cone:angle" in str(type_name) else (number * 0.5 if number else 0.5)


def warned(stage: Usd.Stage, name: str, before: set[str]) -> bool:
    """True when translating ``stage`` gives a new warning that names ``name``."""
    select_variant()
    diag = Diagnostics()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        StageDelegate(stage, Usd.TimeCode.Default(), diag).sync()
    return any(name in m for m in set(diag.messages) - before)


def messages(stage: Usd.Stage) -> set[str]:
    select_variant()
    diag = Diagnostics()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StageWarning)
        StageDelegate(stage, Usd.TimeCode.Default(), diag).sync()
    return set(diag.messages)


def check(
    stage: Usd.Stage, name: str, apply, base_image: np.ndarray, before: set[str]
) -> str | None:
    """None when the variation is warned (naming it) or changes the image; else the failure."""
    layer = stage.GetRootLayer()
    snapshot = layer.ExportToString()
    apply()
    try:
        if warned(stage, name, before):
            return None
        changed = render(stage, spp=4, resolution=(16, 16)).rgb
        if np.abs(changed - base_image).max() > 1e-6:
            return None
        return f"{name}: neither warned about nor changing the image"
    finally:
        layer.ImportFromString(snapshot)


def preview_stage(tmp_path):
    stage = new_stage(tmp_path / "preview.usda")
    sun(stage, illuminance=10.0, tilt_deg=8.0)
    backdrop = quad(stage, "/Backdrop", size=2.0, z=-1.0)
    bind(backdrop, preview(stage, "/Looks/Backdrop", diffuseColor=(0.2, 0.6, 0.2))[0])
    mesh = quad(stage, "/Card", size=0.8)
    material, shader = preview(
        stage, diffuseColor=(0.5, 0.5, 0.5), roughness=0.4, clearcoat=0.5, opacity=0.6
    )
    bind(mesh, material)
    return stage, shader


def test_every_preview_surface_input_changes_the_image_or_is_warned(tmp_path):
    node = Sdr.Registry().GetShaderNodeByIdentifier("UsdPreviewSurface")
    names = list(node.GetShaderInputNames())
    assert {"diffuseColor", "normal", "displacement", "occlusion", "opacityMode"} <= set(names)
    stage, shader = preview_stage(tmp_path)
    base_image = render(stage, spp=4, resolution=(16, 16)).rgb
    before = messages(stage)
    failures = []
    for name in names:
        prop = node.GetShaderInput(name)
        type_name = prop.GetTypeAsSdfType().GetSdfType()
        current = shader.GetInput(name).Get() if shader.GetInput(name) else None
        fallback = prop.GetDefaultValue() if current is None else current
        allowed = [option for option, _ in prop.GetOptions()]
        value = different(fallback, type_name, allowed, tmp_path)
        if name == "useSpecularWorkflow":
            value = 1

        def apply(name=name, type_name=type_name, value=value):
            shader.CreateInput(name, type_name).Set(value)

        failure = check(stage, name, apply, base_image, before)
        if failure:
            failures.append(failure)
    assert not failures, failures


def light_stage(tmp_path, kind: str) -> tuple[Usd.Stage, Usd.Prim]:
    stage = new_stage(tmp_path / f"{kind}.usda")
    floor = quad(stage, "/Floor", size=1.0)
    bind(floor, preview(stage, diffuseColor=(0.7, 0.7, 0.7), roughness=0.5)[0])
    sky = np.zeros((8, 16, 3), np.float32)
    sky[:4, :8] = (1.0, 0.5, 0.2)
    sky[4:] = 0.2
    prim = stage.DefinePrim("/Light", kind)
    for api in APIS:
        prim.ApplyAPI(api)
    UsdGeom.Xformable(prim).AddTranslateOp().Set(Gf.Vec3d(0.3, 0.2, 1.5))
    UsdGeom.Xformable(prim).AddRotateXOp().Set(10.0)
    for name, value in LIGHT_BASE.items():
        attr = prim.GetAttribute(name)
        if attr:
            attr.Set(value)
    if kind.startswith("DomeLight"):
        prim.GetAttribute("inputs:texture:file").Set(
            Sdf.AssetPath(image(tmp_path / "sky.exr", sky))
        )
    return stage, prim


def mesh_light_stage(tmp_path) -> tuple[Usd.Stage, Usd.Prim]:
    stage = new_stage(tmp_path / "meshlight.usda")
    floor = quad(stage, "/Floor", size=1.0)
    bind(floor, preview(stage, diffuseColor=(0.7, 0.7, 0.7))[0])
    glow = quad(stage, "/Glow", size=0.3, z=0.5)
    UsdLux.MeshLightAPI.Apply(glow.GetPrim())
    prim = glow.GetPrim()
    for api in APIS:
        prim.ApplyAPI(api)
    for name, value in LIGHT_BASE.items():
        attr = prim.GetAttribute(name)
        if attr:
            attr.Set(value)
    return stage, prim


@pytest.mark.parametrize("kind", [*LIGHT_TYPES, "MeshLightAPI"])
def test_every_light_attribute_changes_the_image_or_is_warned(tmp_path, kind):
    stage, prim = (
        mesh_light_stage(tmp_path) if kind == "MeshLightAPI" else light_stage(tmp_path, kind)
    )
    names = sorted(lux_property_names(prim) - NO_EFFECT)
    assert "inputs:intensity" in names and "inputs:shadow:enable" in names
    base_image = render(stage, spp=4, resolution=(16, 16)).rgb
    before = messages(stage)
    definition = prim.GetPrimDefinition()
    failures = []
    for name in names:
        prop = prim.GetProperty(name)
        if isinstance(prop, Usd.Relationship):

            def apply(prop=prop):
                prop.SetTargets(["/Floor"])

        elif prop.GetTypeName() == Sdf.ValueTypeNames.Opaque:
            continue  # the collection itself (collection:lightLink): holds no value to author
        else:
            spec = definition.GetSchemaAttributeSpec(name)
            allowed = [str(t) for t in (spec.allowedTokens or [])] if spec else []
            current = (
                prop.Get()
                if prop.HasAuthoredValue()
                else definition.GetAttributeFallbackValue(name)
            )
            type_name = prop.GetTypeName()
            value = different(current, type_name, allowed, tmp_path)
            if name == "inputs:shaping:cone:angle":
                value = 30.0 if not np.isclose(float(current), 30.0) else 45.0

            def apply(prop=prop, value=value):
                prop.Set(value)

        failure = check(stage, name, apply, base_image, before)
        if failure:
            failures.append(failure)
    assert not failures, failures


@pytest.mark.parametrize("kind", ["PortalLight", "GeometryLight"])
def test_lights_without_a_translation_are_warned_as_a_whole(tmp_path, kind):
    stage, _ = light_stage(tmp_path, kind)
    assert any(m.startswith("/Light:") and kind in m for m in messages(stage))
