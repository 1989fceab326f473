"""MaterialX surfaces and images in USD → Mitsuba, approximately.

usd-core has no usdMtlx, so MaterialX nodes reach us as plain ``UsdShade`` shaders whose
``info:id`` is a MaterialX nodedef; the nodedefs themselves (input names and defaults) come from
the MaterialX Python package's standard libraries (:func:`nodedef_defaults`).

Surfaces (``ND_standard_surface_surfaceshader``, Autodesk Standard Surface 1.0;
``ND_open_pbr_surface_surfaceshader``, OpenPBR 1.1) become Mitsuba's ``principled`` BSDF, lobe by
lobe, as their MaterialX graphs combine them (``libraries/bxdf/*.mtlx``):

==========================  ======================  ===========================================
principled                  Standard Surface        OpenPBR
==========================  ======================  ===========================================
``base_color``              base_color · base       base_color · base_weight
                            · mix(1, coat_color, coat) (the coat tints what lies under it)
``metallic``                metalness               base_metalness
``roughness``               specular_roughness      specular_roughness
``specular`` (F0 / 0.08)    specular · F0(specular_IOR), F0 = ((n − 1)/(n + 1))²
``anisotropic``             specular_anisotropy     specular_roughness_anisotropy
``spec_trans``              transmission            transmission_weight
``sheen``                   sheen                   fuzz_weight
``clearcoat``               coat                    coat_weight
``clearcoat_gloss``         1 − coat_roughness      1 − coat_roughness
emission (area emitter)     emission_color · emission  emission_color · emission_luminance
opacity (``mask``)          luminance(opacity)      geometry_opacity
==========================  ======================  ===========================================

Every other input (subsurface, thin film, coloured specular, sheen colour, normals, ...) is
warned, naming it, when it is connected or set away from its default. Images (``ND_image_*``,
``ND_tiledimage_*``) become ``bitmap`` textures: the file through ``Ar`` (:mod:`.textures`), its
``colorSpace`` (``srgb_texture`` decoded, linear ones raw), the address modes, ``default`` when
the file cannot be read, and ``texcoord`` from ``ND_texcoord_vector2`` / ``ND_geompropvalue_vector2``
/ a ``UsdPrimvarReader_float2`` (``st`` when unconnected), through ``ND_place2d_vector2`` (pivot,
scale, rotate, offset, operationorder) when one sits in between.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import numpy as np
from pxr import Sdf, UsdShade

from pavonine.render.shading.network import COLOR, FLOAT, Affine, Network, shader_identifier
from pavonine.render.shading.spec import PRESENCE
from pavonine.render.shading.textures import (
    FLIP_V,
    bitmap_dict,
    bordered,
    fit_channels,
    load_image,
)

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709 / sRGB primaries, D65
F0_PER_SPECULAR = 0.08  # Mitsuba principled: F0 = 0.08 · specular
IMAGE_PREFIXES = ("ND_image_", "ND_tiledimage_")
ADDRESS_MODES = {"periodic": "repeat", "clamp": "clamp", "mirror": "mirror", "constant": "constant"}
SRGB_SPACES = ("srgb_texture", "sRGB", "srgb", "g22_rec709")
LINEAR_SPACES = ("", "raw", "lin_rec709", "lin_srgb", "scene-linear Rec.709-sRGB", "data")


@dataclass(frozen=True)
class Layout:
    """The input names under which a MaterialX surface keeps what ``principled`` needs."""

    base_weight: str
    base_color: str
    metallic: str
    roughness: str
    specular_weight: str
    specular_ior: str
    anisotropy: str
    transmission: str
    sheen: str
    coat: str
    coat_color: str
    coat_roughness: str
    emission_weight: str
    emission_color: str
    opacity: str


SURFACES = {
    "ND_standard_surface_surfaceshader": Layout(
        "base", "base_color", "metalness", "specular_roughness", "specular", "specular_IOR",
        "specular_anisotropy", "transmission", "sheen", "coat", "coat_color", "coat_roughness",
        "emission", "emission_color", "opacity",
    ),
    "ND_open_pbr_surface_surfaceshader": Layout(
        "base_weight", "base_color", "base_metalness", "specular_roughness", "specular_weight",
        "specular_ior", "specular_roughness_anisotropy", "transmission_weight", "fuzz_weight",
        "coat_weight", "coat_color", "coat_roughness", "emission_luminance", "emission_color",
        "geometry_opacity",
    ),
}  # fmt: skip


@functools.cache
def nodedef_defaults(node_id: str) -> dict[str, Any] | None:
    """Input name → default value of a MaterialX nodedef (``None`` for an unknown id)."""
    import MaterialX as mx

    library = _library()
    nodedef = library.getNodeDef(node_id)
    if nodedef is None:
        return None
    defaults: dict[str, Any] = {}
    for item in nodedef.getActiveInputs():
        value = item.getValue() if item.hasValueString() and item.getValueString() else None
        if isinstance(value, (mx.Color3, mx.Color4, mx.Vector2, mx.Vector3, mx.Vector4)):
            value = tuple(float(c) for c in value.asTuple())
        defaults[item.getName()] = value
    return defaults


@functools.cache
def _library():
    import MaterialX as mx

    library = mx.createDocument()
    mx.loadLibraries(mx.getDefaultDataLibraryFolders(), mx.getDefaultDataSearchPath(), library)
    return library


def audit(shader: UsdShade.Shader, node_id: str, net: Network) -> dict[str, Any]:
    """The nodedef's defaults; inputs it does not know are warned (they would be dropped)."""
    defaults = nodedef_defaults(node_id) or {}
    for shader_input in shader.GetInputs():
        name = shader_input.GetBaseName()
        if defaults and name not in defaults:
            net.warn(str(shader.GetPath()), f"input {name!r} is not an input of {node_id}; ignored")
    return defaults


# -- surfaces --------------------------------------------------------------------------------------


def surface(shader: UsdShade.Shader, node_id: str, net: Network) -> dict[str, Any]:
    """The :class:`~.spec.MaterialSpec` fields of a Standard Surface or OpenPBR shader."""
    layout = SURFACES[node_id]
    where = str(shader.GetPath())
    defaults = audit(shader, node_id, net)

    def default(name: str) -> Any:
        return defaults.get(name)

    def weight(name: str) -> float:
        """A scalar weight Mitsuba cannot texture here: its constant (a connection is warned)."""
        if net.source(shader.GetInput(name)) is not None:
            net.warn(where, f"a connected {name} is not supported here; using {default(name)}")
            return float(default(name))
        return float(net.setting(shader, name, default(name)))

    bsdf: dict[str, Any] = {
        "type": "principled",
        "base_color": _base_color(shader, layout, weight, default, net),
        "metallic": net.value(shader, layout.metallic, FLOAT, default(layout.metallic)),
        "roughness": net.value(shader, layout.roughness, FLOAT, default(layout.roughness)),
        "anisotropic": net.value(shader, layout.anisotropy, FLOAT, default(layout.anisotropy)),
        "spec_trans": net.value(shader, layout.transmission, FLOAT, default(layout.transmission)),
        "sheen": net.value(shader, layout.sheen, FLOAT, default(layout.sheen)),
        "clearcoat": net.value(shader, layout.coat, FLOAT, default(layout.coat)),
        "clearcoat_gloss": net.value(
            shader, layout.coat_roughness, FLOAT, default(layout.coat_roughness), Affine(-1.0, 1.0)
        ),
    }
    ior = weight(layout.specular_ior)
    f0 = ((ior - 1.0) / (ior + 1.0)) ** 2
    bsdf["specular"] = max(weight(layout.specular_weight) * f0 / F0_PER_SPECULAR, 1e-4)
    emission = net.value(
        shader,
        layout.emission_color,
        COLOR,
        default(layout.emission_color),
        Affine(weight(layout.emission_weight)),
    )
    if isinstance(emission, dict) and emission.get("type") == "rgb" and max(emission["value"]) <= 0:
        emission = None
    translated = {getattr(layout, f) for f in Layout.__dataclass_fields__}
    for name, value in defaults.items():
        if name in translated:
            continue
        # inputs without a default value (normal, tangent: geometric properties) count when set
        if value is None and not net.is_authored(shader, name):
            continue
        if value is None or net.differs(shader, name, value):
            net.warn(
                where,
                f"{name} is not translated to Mitsuba's principled BSDF (an approximation of "
                f"{node_id}); ignored",
            )
    return {
        "bsdf": bsdf,
        "opacity": _opacity(shader, layout.opacity, default(layout.opacity), net),
        "opacity_mode": PRESENCE,
        "emission": emission,
    }


def _base_color(shader, layout: Layout, weight, default, net: Network) -> Any:
    """base_color · base weight · mix(1, coat_color, coat): the coat's tint folded into the base
    where one of the two is a constant grey (else the coat's tint is warned and left out)."""
    base = weight(layout.base_weight)
    colour_default = default(layout.base_color)
    coat = 0.0 if net.source(shader.GetInput(layout.coat)) else weight(layout.coat)
    tinted = coat > 0 and net.differs(shader, layout.coat_color, default(layout.coat_color))
    if not tinted:
        return net.value(shader, layout.base_color, COLOR, colour_default, Affine(base))
    base_colour = net.value(shader, layout.base_color, COLOR, colour_default)
    if _grey(base_colour) is not None:  # grey base: the coat colour (a texture too) carries it
        grey = base * _grey(base_colour)
        return net.value(
            shader,
            layout.coat_color,
            COLOR,
            default(layout.coat_color),
            Affine(grey * coat, grey * (1.0 - coat)),
        )
    coat_colour = net.value(shader, layout.coat_color, COLOR, default(layout.coat_color))
    if _grey(coat_colour) is not None:
        tint = 1.0 - coat + coat * _grey(coat_colour)
        return net.value(shader, layout.base_color, COLOR, colour_default, Affine(base * tint))
    if base_colour.get("type") == "rgb" and coat_colour.get("type") == "rgb":
        mixed = np.asarray(base_colour["value"]) * (
            1 - coat + coat * np.asarray(coat_colour["value"])
        )
        return {"type": "rgb", "value": [float(c) for c in mixed * base]}
    net.warn(
        str(shader.GetPath()),
        f"{layout.coat_color} tints a textured {layout.base_color}; Mitsuba cannot multiply two "
        "textures, so the coat's tint is left out",
    )
    return net.value(shader, layout.base_color, COLOR, colour_default, Affine(base))


def _grey(value: Any) -> float | None:
    """The grey level of a constant ``rgb`` dict with r = g = b, else ``None``."""
    if isinstance(value, dict) and value.get("type") == "rgb" and np.ptp(value["value"]) < 1e-6:
        return float(value["value"][0])
    return None


def _opacity(shader: UsdShade.Shader, name: str, default: Any, net: Network) -> Any:
    """A float opacity (OpenPBR) as read; a colour one (Standard Surface) by its luminance."""
    if np.ndim(default) == 0:
        return net.value(shader, name, FLOAT, default)
    if net.source(shader.GetInput(name)) is not None:
        net.warn(str(shader.GetPath()), f"a connected {name} is read by its first channel")
        return net.value(shader, name, FLOAT, default[0])
    colour = net.value(shader, name, COLOR, default)
    return float(LUMINANCE @ np.asarray(colour["value"]))


# -- images ----------------------------------------------------------------------------------------


def image(shader: UsdShade.Shader, node_id: str, kind: str, affine: Affine, net: Network) -> Any:
    """The Mitsuba texture of an ``ND_image_*`` / ``ND_tiledimage_*`` node read as ``kind``."""
    from pavonine.render.shading.network import as_mitsuba, coerce

    where = str(shader.GetPath())
    defaults = audit(shader, node_id, net)
    fallback = net.constant(shader, "default", defaults.get("default", 0.0))
    constant = as_mitsuba(affine.apply(coerce(fallback, kind, 0.0)), kind)
    asset = net.constant(shader, "file", None)
    if not isinstance(asset, Sdf.AssetPath) or not asset.path:
        net.warn(where, f"{node_id} has no file; using its default")
        return constant
    file_input = shader.GetInput("file")
    space = str(file_input.GetAttr().GetColorSpace() or "")
    if space not in SRGB_SPACES + LINEAR_SPACES:
        net.warn(where, f"colorSpace {space!r} is not supported; the file is read as linear")
    loaded = load_image(file_input, asset, "sRGB" if space in SRGB_SPACES else "raw", where, net)
    if loaded is None:
        return constant
    texels, to_uv, _ = loaded
    wrap = _address_mode(shader, node_id, net)
    outside = np.resize(np.asarray(fallback, dtype=float), 4)
    texels, to_uv, wrap = bordered(texels, to_uv, wrap, outside)
    channels = _channels(node_id)
    values = affine.apply(fit_channels(texels[..., :channels], kind))
    uv_name, transform = _texcoord(shader, net)
    if node_id.startswith("ND_tiledimage_"):
        transform = _tiling(shader, net) @ transform
    net.use_uv(uv_name)
    texture = bitmap_dict(values, kind, wrap, FLIP_V @ to_uv @ transform @ FLIP_V)
    filtertype = str(net.constant(shader, "filtertype", "linear"))
    if filtertype == "closest":
        (texture.get("nested") or texture)["filter_type"] = "nearest"
    elif filtertype != "linear":
        net.warn(where, f"filtertype {filtertype!r} is rendered as linear")
    return texture


def _channels(node_id: str) -> int:
    """Channels the node's output type reads from the file (ND_image_color3 → 3, ..._float → 1)."""
    kind = node_id.rsplit("_", 1)[-1]
    return {"float": 1, "vector2": 2, "color3": 3, "vector3": 3, "color4": 4, "vector4": 4}.get(
        kind, 3
    )


def _address_mode(shader: UsdShade.Shader, node_id: str, net: Network) -> str:
    """Mitsuba's one wrap mode for ``uaddressmode``/``vaddressmode`` (tiled images repeat)."""
    if node_id.startswith("ND_tiledimage_"):
        return "repeat"
    modes = [
        str(net.constant(shader, name, "periodic")) for name in ("uaddressmode", "vaddressmode")
    ]
    wraps = [ADDRESS_MODES.get(mode) for mode in modes]
    if None in wraps or wraps[0] != wraps[1]:
        net.warn(
            str(shader.GetPath()),
            f"address modes {modes[0]!r}/{modes[1]!r}: Mitsuba has one wrap mode per texture; "
            f"using {wraps[0] or 'repeat'!r}",
        )
    return wraps[0] or "repeat"


def _tiling(shader: UsdShade.Shader, net: Network) -> np.ndarray:
    """``ND_tiledimage``: uv' = (uv · uvtiling − uvoffset) / realworldimagesize · realworldtilesize."""

    def pair(name: str, default: tuple[float, float]) -> np.ndarray:
        return np.resize(np.asarray(net.constant(shader, name, default), dtype=float), 2)

    tiling, offset = pair("uvtiling", (1.0, 1.0)), pair("uvoffset", (0.0, 0.0))
    scale = pair("realworldtilesize", (1.0, 1.0)) / np.maximum(
        pair("realworldimagesize", (1.0, 1.0)), 1e-12
    )
    return np.array(
        [
            [tiling[0] * scale[0], 0.0, -offset[0] * scale[0]],
            [0.0, tiling[1] * scale[1], -offset[1] * scale[1]],
            [0.0, 0.0, 1.0],
        ]
    )


def place2d(shader: UsdShade.Shader, net: Network) -> np.ndarray:
    """``ND_place2d_vector2`` as a 3×3 matrix on uv, as its graph in MaterialX's
    ``stdlib_ng.mtlx`` computes it: SRT (``operationorder`` 0) ``R((t − pivot) / scale) − offset
    + pivot``, TRS (1) ``R(t − pivot − offset) / scale + pivot``; ``R`` turns by ``rotate``
    degrees clockwise (``mx_rotate_vector2``)."""
    where = str(shader.GetPath())
    for name in ("pivot", "scale", "rotate", "offset", "operationorder"):
        if net.source(shader.GetInput(name)) is not None:
            net.warn(where, f"a connected {name} is not supported; using its value or default")

    def pair(name: str, default: tuple[float, float]) -> np.ndarray:
        return np.resize(np.asarray(net.constant(shader, name, default), dtype=float), 2)

    pivot, offset = pair("pivot", (0.0, 0.0)), pair("offset", (0.0, 0.0))
    scale = pair("scale", (1.0, 1.0))
    scale = np.where(np.abs(scale) > 1e-12, scale, 1e-12)
    angle = np.radians(float(net.constant(shader, "rotate", 0.0)))
    c, s = np.cos(angle), np.sin(angle)

    def move(v: np.ndarray) -> np.ndarray:
        return np.array([[1.0, 0.0, v[0]], [0.0, 1.0, v[1]], [0.0, 0.0, 1.0]])

    rotate = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    divide = np.diag([1.0 / scale[0], 1.0 / scale[1], 1.0])
    if int(net.constant(shader, "operationorder", 0)) == 1:
        return move(pivot) @ divide @ rotate @ move(-offset) @ move(-pivot)
    return move(pivot) @ move(-offset) @ rotate @ divide @ move(-pivot)


def _texcoord(shader: UsdShade.Shader, net: Network) -> tuple[str, np.ndarray]:
    """(uv primvar, transform) of an image's ``texcoord``; ``st`` when it is not connected."""
    source = net.source(shader.GetInput("texcoord"))
    if source is None:
        return "st", np.eye(3)
    node, _ = source
    node_id = shader_identifier(node)
    if node_id == "ND_place2d_vector2":
        name, inner = _texcoord(node, net)
        return name, place2d(node, net) @ inner
    if node_id == "ND_texcoord_vector2":
        return "st", np.eye(3)
    if node_id == "ND_geompropvalue_vector2" or node_id.startswith("UsdPrimvarReader_"):
        name = str(net.constant(node, "geomprop" if node_id.startswith("ND_") else "varname", ""))
        return name or "st", np.eye(3)
    net.warn(
        str(node.GetPath()),
        f"{node_id or 'a shader'} feeding an image's texcoord is not supported; reading st",
    )
    return "st", np.eye(3)
