"""``UsdRender.Settings`` / ``RenderProduct`` → resolution, camera, pixel aspect, conform policy.

The stage's ``renderSettingsPrimPath`` metadata names the settings prim; without it the first
``RenderSettings`` prim is used. A ``RenderProduct``'s authored values override its settings'
(UsdRender's inheritance of ``RenderSettingsBase``). Command-line values override both.
"""

from __future__ import annotations

from dataclasses import dataclass

from pxr import Usd, UsdRender

from pavonine.pipeline.errors import InputError
from pavonine.render.diagnostics import Diagnostics

DEFAULT_RESOLUTION = (512, 512)


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
    return size[0], size[1]


@dataclass
class RenderSettingsSpec:
    """What the stage says about its image."""

    resolution: tuple[int, int] | None = None
    camera: str | None = None
    pixel_aspect: float = 1.0
    conform: str = "expandAperture"
    path: str | None = None


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
    """Resolution, camera and pixel aspect from the stage's RenderSettings and first RenderProduct."""
    settings = find_settings(stage)
    if settings is None:
        return RenderSettingsSpec()
    spec = RenderSettingsSpec(path=str(settings.GetPath()))
    sources: list[UsdRender.SettingsBase] = [settings]
    products = settings.GetProductsRel().GetForwardedTargets()
    if products:
        product = stage.GetPrimAtPath(products[0])
        if product and product.IsA(UsdRender.Product):
            sources.append(UsdRender.Product(product))
        if len(products) > 1:
            diag.warn(
                spec.path, f"{len(products)} render products; rendering the first ({products[0]})"
            )
    for source in sources:
        resolution = source.GetResolutionAttr()
        if resolution.HasAuthoredValue():
            w, h = resolution.Get()
            spec.resolution = (int(w), int(h))
        aspect = source.GetPixelAspectRatioAttr()
        if aspect.HasAuthoredValue():
            spec.pixel_aspect = float(aspect.Get())
        conform = source.GetAspectRatioConformPolicyAttr()
        if conform.HasAuthoredValue():
            spec.conform = str(conform.Get())
        targets = source.GetCameraRel().GetForwardedTargets()
        if targets:
            spec.camera = str(targets[0])
    if spec.pixel_aspect <= 0:
        diag.warn(spec.path, f"pixelAspectRatio {spec.pixel_aspect} is not positive; using 1")
        spec.pixel_aspect = 1.0
    return spec
