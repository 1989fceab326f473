"""``UsdPreviewSurface`` → Mitsuba ``principled`` (the UsdPreviewSurface specification, input by input).

=====================  =============================================================================
input                  Mitsuba
=====================  =============================================================================
diffuseColor           ``base_color``
roughness              ``roughness`` (both perceptual: α = roughness²)
metallic               ``metallic`` (metallic workflow)
ior                    ``eta`` (metallic workflow: F0 = ((ior − 1)/(ior + 1))²); the transparency's
                       thin dielectric
useSpecularWorkflow,   ``specular`` = F0 / 0.08 with F0 the luminance of specularColor (Mitsuba's
specularColor          ``eta`` ↔ ``specular`` relation), ``spec_tint`` 1 when specularColor has
                       diffuseColor's hue, 0 when grey; any other hue, or a textured specularColor
                       (its mean is used), is approximated with a warning
clearcoat              ``clearcoat``
clearcoatRoughness     ``clearcoat_gloss`` = 1 − clearcoatRoughness
normal                 ``normalmap`` around the surface (tangent space, +X along +u, +Y along +v;
                       USD's [−1, 1] normal stored as Mitsuba's [0, 1] texture)
emissiveColor          an ``area`` emitter on the mesh (textures included)
opacity,               ``mask`` (presence / cut-out) or a blend with a thin dielectric
opacityThreshold,      (transparent), see :mod:`.spec`
opacityMode
displacement           the geometry is displaced (through the material's displacement output):
                       :mod:`.displacement` and :mod:`pavonine.render.displacement`
occlusion              ignored with a warning when authored (a path tracer computes occlusion)
=====================  =============================================================================

Inputs that are not part of UsdPreviewSurface (its ``Sdr`` definition) are warned about.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pxr import UsdShade

from pavonine.render.shading.network import COLOR, FLOAT, VECTOR, Affine, Network
from pavonine.render.shading.spec import PRESENCE, TRANSPARENT
from pavonine.render.shading.textures import bitmap_dict

PREVIEW_SURFACE = "UsdPreviewSurface"
DIFFUSE_DEFAULT = (0.18, 0.18, 0.18)
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709 / sRGB primaries, D65
F0_PER_SPECULAR = 0.08  # Mitsuba principled: F0 = 0.08 · specular
MIN_ETA = 1.0 + 1e-4
HUE_TOLERANCE = 0.05

#: The ``info:id``\ s translated here (MaterialX's nodedef of the same surface too).
PREVIEW_SURFACES = ("UsdPreviewSurface", "ND_UsdPreviewSurface_surfaceshader")


def preview_surface(shader: UsdShade.Shader, net: Network) -> dict[str, Any]:
    """The :class:`~.spec.MaterialSpec` fields of a UsdPreviewSurface (bsdf, opacity, emission...)."""
    where = str(shader.GetPath())
    net.audit(shader, PREVIEW_SURFACE)
    base = net.value(shader, "diffuseColor", COLOR, DIFFUSE_DEFAULT)
    bsdf: dict[str, Any] = {
        "type": "principled",
        "base_color": base,
        "roughness": net.value(shader, "roughness", FLOAT, 0.5),
        "clearcoat": net.value(shader, "clearcoat", FLOAT, 0.0),
        "clearcoat_gloss": net.value(shader, "clearcoatRoughness", FLOAT, 0.01, Affine(-1.0, 1.0)),
    }
    ior = _scalar(shader, "ior", 1.5, net)
    workflow = int(net.setting(shader, "useSpecularWorkflow", 0))
    if workflow == 1:
        _specular_workflow(shader, base, bsdf, net)
    else:
        bsdf["metallic"] = net.value(shader, "metallic", FLOAT, 0.0)
        bsdf["eta"] = max(ior, MIN_ETA)
        if net.differs(shader, "specularColor", (0.0, 0.0, 0.0)):
            net.warn(where, "specularColor is used only with useSpecularWorkflow = 1; ignored")
    bsdf = _normal_map(shader, bsdf, net)
    if net.differs(shader, "occlusion", 1.0):
        net.warn(where, "occlusion is ignored: the path tracer computes occlusion from the scene")
    emission = net.value(shader, "emissiveColor", COLOR, (0.0, 0.0, 0.0))
    if isinstance(emission, dict) and emission.get("type") == "rgb" and max(emission["value"]) <= 0:
        emission = None
    opacity, mode = _opacity(shader, net)
    return {
        "bsdf": bsdf,
        "opacity": opacity,
        "opacity_mode": mode,
        "ior": ior,
        "emission": emission,
    }


def _scalar(shader: UsdShade.Shader, name: str, fallback: float, net: Network) -> float:
    """A scalar input Mitsuba cannot texture (``eta``): its constant; a connection is warned."""
    if net.source(shader.GetInput(name)) is not None:
        net.warn(str(shader.GetPath()), f"{name} cannot be textured in Mitsuba; using {fallback}")
        return fallback
    return float(net.setting(shader, name, fallback))


def _specular_workflow(shader: UsdShade.Shader, base: Any, bsdf: dict, net: Network) -> None:
    """F0 = specularColor at normal incidence, white at grazing angles (Schlick), metallic unused."""
    where = str(shader.GetPath())
    if net.differs(shader, "metallic", 0.0):
        net.warn(where, "metallic is used only with useSpecularWorkflow = 0; ignored")
    value = net.value(shader, "specularColor", COLOR, (0.0, 0.0, 0.0))
    colour = _mean_colour(value)
    if colour is None:
        net.warn(where, "specularColor read from a primvar is not supported; using black")
        colour = np.zeros(3)
    elif not (isinstance(value, dict) and value.get("type") == "rgb"):
        net.warn(where, "a textured specularColor is approximated by its mean colour")
    f0 = float(np.clip(LUMINANCE @ colour, 0.0, 0.99))
    bsdf["specular"] = max(f0 / F0_PER_SPECULAR, 1e-4)
    bsdf["spec_tint"] = 0.0
    if f0 > 0 and np.ptp(colour / max(f0, 1e-9)) > HUE_TOLERANCE:
        hue = _mean_colour(base)
        if hue is not None and np.allclose(
            colour / f0, hue / max(LUMINANCE @ hue, 1e-9), atol=HUE_TOLERANCE
        ):
            bsdf["spec_tint"] = 1.0
        else:
            net.warn(
                where,
                "specularColor's hue differs from diffuseColor's; Mitsuba's principled BSDF can "
                "only tint towards diffuseColor, so its luminance is used (grey specular)",
            )


def _mean_colour(value: Any) -> np.ndarray | None:
    """Linear RGB of a constant, or the mean of a bitmap texture; ``None`` for a placeholder."""
    if isinstance(value, dict):
        kind = value.get("type")
        if kind == "rgb":
            return np.asarray(value["value"], dtype=float)
        if kind == "d65":
            inner = _mean_colour(value["nested"])
            return None if inner is None else inner * float(value["scale"])
        if kind == "bitmap":
            pixels = np.atleast_3d(np.array(value["bitmap"], dtype=float))
            return np.resize(pixels.reshape(-1, pixels.shape[2]).mean(axis=0), 3)
        return None
    return np.full(3, float(value))


def _normal_map(shader: UsdShade.Shader, bsdf: dict, net: Network) -> dict:
    """A ``normalmap`` around the surface when ``normal`` is connected (or not (0, 0, 1))."""
    where = str(shader.GetPath())
    if net.source(shader.GetInput("normal")) is None:
        normal = net.setting(shader, "normal", (0.0, 0.0, 1.0), VECTOR)
        if np.allclose(normal, (0.0, 0.0, 1.0)):
            return bsdf
        texel = (np.asarray(normal, dtype=float) * 0.5 + 0.5).reshape(1, 1, 3)
        return {
            "type": "normalmap",
            "normalmap": bitmap_dict(texel, VECTOR, "repeat", np.eye(3)),
            "bsdf": bsdf,
        }
    texture = net.value(shader, "normal", VECTOR, (0.0, 0.0, 1.0), Affine(0.5, 0.5))
    if not isinstance(texture, dict) or texture.get("type") != "bitmap":
        net.warn(where, "normal is not read from a texture; the geometric normals are used")
        return bsdf
    return {"type": "normalmap", "normalmap": texture, "bsdf": bsdf}


def _opacity(shader: UsdShade.Shader, net: Network) -> tuple[Any, str]:
    """(opacity value or texture, ``presence``/``transparent``) as the spec's three inputs say."""
    where = str(shader.GetPath())
    opacity = net.value(shader, "opacity", FLOAT, 1.0)
    mode = str(net.constant(shader, "opacityMode", TRANSPARENT))
    if mode not in (TRANSPARENT, PRESENCE):
        net.warn(where, f"opacityMode {mode!r} is not transparent or presence; using transparent")
        mode = TRANSPARENT
    threshold = float(net.setting(shader, "opacityThreshold", 0.0))
    if net.source(shader.GetInput("opacityThreshold")) is not None:
        net.warn(where, "opacityThreshold cannot be textured; using 0")
        threshold = 0.0
    if threshold > 0.0:
        return _cutout(opacity, threshold, where, net), PRESENCE
    return opacity, mode


def _cutout(opacity: Any, threshold: float, where: str, net: Network) -> Any:
    """``opacityThreshold`` > 0: opacity below it is 0, the rest 1 (a cut-out)."""
    if isinstance(opacity, float):
        return 1.0 if opacity >= threshold else 0.0
    if isinstance(opacity, dict) and opacity.get("type") == "bitmap":
        import mitsuba as mi

        values = np.atleast_3d(np.array(opacity["bitmap"], dtype=np.float32))
        cut = (values[..., :1] >= threshold).astype(np.float32)
        return {**opacity, "bitmap": mi.Bitmap(cut)}
    net.warn(where, "opacityThreshold applies to constant or textured opacity only; ignored")
    return opacity
