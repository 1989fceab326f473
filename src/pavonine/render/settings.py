"""``UsdRender`` settings → what to render: one :class:`ProductSpec` per ``RenderProduct``.

The stage's ``renderSettingsPrimPath`` metadata names the settings prim; without it the first
``RenderSettings`` prim is used. Every product in its ``products`` relationship is rendered, each
with its own camera, resolution, pixel aspect ratio, conform policy and ``orderedVars``; a
product's authored values override its settings' (UsdRender's inheritance of
``RenderSettingsBase``). Command-line values override both. A stage without settings (or without
products) renders one beauty image.

``disableMotionBlur`` and ``instantaneousShutter`` (either) make the product's shutter an instant
(:mod:`.motion.blur`). Any other authored attribute that is not honoured is warned about, naming it.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from pxr import Usd, UsdRender

from pavonine.base.errors import InputError
from pavonine.base.limits import check_pixel_count
from pavonine.render.diagnostics import Diagnostics
from pavonine.render.integrator_settings import (
    IntegratorSpec,
    field_of,
    is_honoured,
    read_integrator,
    read_sample_count,
    warn_ignored,
)

DEFAULT_RESOLUTION = (512, 512)
HONOURED = {
    "resolution",
    "pixelAspectRatio",
    "aspectRatioConformPolicy",
    "camera",
    "products",
    "orderedVars",
    "productName",
    "productType",
    "sourceName",
    "sourceType",
    "dataType",
    "disableMotionBlur",
    "instantaneousShutter",
    "disableDepthOfField",
    "includedPurposes",
}
#: what the delegate draws: gprims of these purposes (guide and proxy are skipped)
RENDERED_PURPOSES = ("default", "render")
LINEAR_REC709 = ("", "lin_rec709_scene", "lin_rec709", "Linear Rec.709 (sRGB)", "linear")


def parse_resolution(text: str, where: str = "--resolution") -> tuple[int, int]:
    """``"512x768"`` → (512, 768); ``"256"`` → (256, 256). Anything else is an :class:`InputError`.

    The one parser of image sizes given on the command line (``render``, ``baseline``, ``demo``).
    """
    parts = str(text).strip().lower().split("x")
    try:
        size = [int(p) for p in parts]
    except ValueError:
        size = []
    if len(size) == 1:
        size *= 2
    if len(size) != 2:
        raise InputError(where, f"expected WIDTHxHEIGHT (e.g. 512x512), got {text!r}")
    if min(size) < 1:
        raise InputError(where, f"width and height must be positive, got {text!r}")
    check_pixel_count(where, size[0], size[1])  # the pixel budget (pavonine.base.limits)
    return size[0], size[1]


@dataclass
class RenderVarSpec:
    """One ``RenderVar``: an image layer of a product."""

    path: str
    name: str  # the layer's name in the output (the RenderVar prim's name)
    source_name: str
    source_type: str = "raw"
    data_type: str = "color3f"


@dataclass
class ProductSpec:
    """One image to render and write."""

    path: str | None = None  # the RenderProduct prim (None: the stage has no products)
    product_name: str = ""  # ``productName`` (the output file, by convention)
    resolution: tuple[int, int] | None = None
    camera: str | None = None
    pixel_aspect: float = 1.0
    conform: str = "expandAperture"
    disable_dof: bool = False
    #: ``disableMotionBlur`` or ``instantaneousShutter``: the shutter is an instant
    #: (render/motion/blur.py)
    disable_blur: bool = False
    vars: list[RenderVarSpec] = field(default_factory=list)  # empty: the beauty image alone


@dataclass
class RenderSettingsSpec:
    """What the stage says about its images; the top-level fields are the first product's."""

    resolution: tuple[int, int] | None = None
    camera: str | None = None
    pixel_aspect: float = 1.0
    conform: str = "expandAperture"
    path: str | None = None
    products: list[ProductSpec] = field(default_factory=list)
    integrator: IntegratorSpec = field(default_factory=IntegratorSpec)  # hdmitsuba's settings
    sample_count: int | None = None  # ``mitsuba:sample_count`` (None: not authored)
    sample_count_field: str = ""  # where it is authored (``layer: /Prim.attribute``)


def find_settings(stage: Usd.Stage) -> UsdRender.Settings | None:
    """The stage's render settings prim (metadata first, then the first one in the stage)."""
    settings = UsdRender.Settings.GetStageRenderSettings(stage)
    if settings:
        return settings
    for prim in stage.Traverse():
        if prim.IsA(UsdRender.Settings):
            return UsdRender.Settings(prim)
    return None


def read_render_settings(stage: Usd.Stage, diag: Diagnostics) -> RenderSettingsSpec:
    """The settings and every product (a stage without them: one default product)."""
    settings = find_settings(stage)
    if settings is None:
        return RenderSettingsSpec(products=[ProductSpec()])
    base = _read_base(settings, ProductSpec(), diag)
    _audit(settings.GetPrim(), diag, reads_mitsuba=True)
    _check_purposes(settings, diag)
    products = []
    for target in settings.GetProductsRel().GetForwardedTargets():
        prim = stage.GetPrimAtPath(target)
        if not prim or not prim.IsA(UsdRender.Product):
            diag.warn(
                str(settings.GetPath()), f"products: {target} is not a RenderProduct; skipped"
            )
            continue
        products.append(_read_product(UsdRender.Product(prim), base, diag))
    if not products:
        products = [base]
    first = products[0]
    sample_count, sample_count_field = read_sample_count(settings.GetPrim())
    return RenderSettingsSpec(
        resolution=first.resolution,
        camera=first.camera,
        pixel_aspect=first.pixel_aspect,
        conform=first.conform,
        path=str(settings.GetPath()),
        products=products,
        integrator=read_integrator(settings.GetPrim(), diag),
        sample_count=sample_count,
        sample_count_field=sample_count_field,
    )


def _read_base(
    source: UsdRender.SettingsBase, inherited: ProductSpec, diag: Diagnostics
) -> ProductSpec:
    """``inherited`` with the values ``source`` authors (RenderSettingsBase attributes)."""
    spec = replace(inherited)
    resolution = source.GetResolutionAttr()
    if resolution.HasAuthoredValue():
        w, h = resolution.Get()
        if w < 1 or h < 1:  # the answer --resolution gets (parse_resolution)
            raise InputError(
                field_of(resolution), f"width and height must be positive, got {w}x{h}"
            )
        spec.resolution = (int(w), int(h))
    aspect = source.GetPixelAspectRatioAttr()
    if aspect.HasAuthoredValue():
        value = float(aspect.Get())
        if not (value > 0 and np.isfinite(value)):
            raise InputError(field_of(aspect), f"must be a positive finite number, got {value}")
        spec.pixel_aspect = value
    conform = source.GetAspectRatioConformPolicyAttr()
    if conform.HasAuthoredValue():
        spec.conform = str(conform.Get())
    targets = source.GetCameraRel().GetForwardedTargets()
    if targets:
        spec.camera = str(targets[0])
    dof = source.GetDisableDepthOfFieldAttr()
    if dof.HasAuthoredValue():
        spec.disable_dof = bool(dof.Get())
    for attr in (source.GetDisableMotionBlurAttr(), source.GetInstantaneousShutterAttr()):
        if attr.HasAuthoredValue() and bool(attr.Get()):
            spec.disable_blur = True
    return spec


def _read_product(product: UsdRender.Product, base: ProductSpec, diag: Diagnostics) -> ProductSpec:
    spec = _read_base(product, base, diag)
    spec.path = str(product.GetPath())
    spec.product_name = str(product.GetProductNameAttr().Get() or "")
    kind = str(product.GetProductTypeAttr().Get() or "raster")
    if kind != "raster":
        diag.warn(spec.path, f"productType {kind!r} is not supported; rendered as a raster image")
    _audit(product.GetPrim(), diag)
    spec.vars = []
    stage = product.GetPrim().GetStage()
    for target in product.GetOrderedVarsRel().GetForwardedTargets():
        prim = stage.GetPrimAtPath(target)
        if not prim or not prim.IsA(UsdRender.Var):
            diag.warn(spec.path, f"orderedVars: {target} is not a RenderVar; skipped")
            continue
        var = UsdRender.Var(prim)
        _audit(prim, diag)
        spec.vars.append(
            RenderVarSpec(
                path=str(prim.GetPath()),
                name=prim.GetName(),
                source_name=str(var.GetSourceNameAttr().Get() or ""),
                source_type=str(var.GetSourceTypeAttr().Get() or "raw"),
                data_type=str(var.GetDataTypeAttr().Get() or "color3f"),
            )
        )
    return spec


def _check_purposes(settings: UsdRender.Settings, diag: Diagnostics) -> None:
    purposes = settings.GetIncludedPurposesAttr()
    if purposes.HasAuthoredValue():
        wanted = sorted(str(p) for p in purposes.Get() or [])
        if wanted != sorted(RENDERED_PURPOSES):
            diag.warn(
                str(settings.GetPath()),
                f"includedPurposes {wanted} is not supported; default and render prims are drawn",
            )


def _audit(prim: Usd.Prim, diag: Diagnostics, reads_mitsuba: bool = False) -> None:
    """Warn about the prim's authored UsdRender attributes that are not honoured, and its
    ``mitsuba:`` ones but those :mod:`.integrator_settings` reads (``reads_mitsuba``: on the
    RenderSettings prim only)."""
    definition = prim.GetPrimDefinition()
    for name in definition.GetPropertyNames():
        if name in HONOURED:
            continue
        attr = prim.GetAttribute(name)
        if not attr or not attr.HasAuthoredValue():
            continue
        value = attr.Get()
        if _equal(value, definition.GetAttributeFallbackValue(name)):
            continue
        if name == "renderingColorSpace" and str(value) in LINEAR_REC709:
            continue
        diag.warn(str(prim.GetPath()), f"{name} = {value!r} is not supported; ignored")
    for name in prim.GetPropertyNames():
        if not name.startswith("mitsuba:") or (reads_mitsuba and is_honoured(name)):
            continue
        reason = "read on the RenderSettings prim only" if is_honoured(name) else "not supported"
        warn_ignored(prim, name, reason, diag)


def _equal(value: Any, fallback: Any) -> bool:
    if value is None or fallback is None:
        return value is fallback
    try:
        return bool(np.array_equal(np.asarray(value), np.asarray(fallback)))
    except (TypeError, ValueError):
        return str(value) == str(fallback)
