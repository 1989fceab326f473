"""USD materials → Mitsuba BSDF dictionaries.

* No bound material: grey diffuse (or the prim's constant ``displayColor``).
* ``UsdPreviewSurface`` → Mitsuba ``principled``; ``UsdUVTexture`` inputs → ``bitmap`` textures
  (colour maps decoded from sRGB, data maps raw), ``opacity`` < 1 → ``mask``.
* Materials with the applied API schema ``PavonineFeatherAPI`` → the feather BSDF
  (``pavonine.render.feather_bsdf``); the only other place that knows about feathers is
  :func:`feather_bsdf`. With ``PAVONINE_IGNORE_FEATHER_SCHEMA=1`` in the environment they render
  their UsdPreviewSurface instead, as a viewer that knows nothing of Pavonine would (used to
  compare the baked preview with the spectral feather).

Every missing or unreadable texture gives one warning naming the shader prim and the file, and the
shader's ``inputs:fallback`` (or a neutral constant) is used instead.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from pxr import Sdf, Usd, UsdGeom, UsdShade

from pavonine.render.diagnostics import Diagnostics

FEATHER_API = "PavonineFeatherAPI"
FEATHER_UV = "pavonine_featherUV"
BARB_TANGENT = "pavonine_barbTangent"
#: Names the converter gave these primvars before they had to be valid shading-language
#: identifiers (MaterialX ``geompropvalue``); meshes that carry only these are read through them.
LEGACY_PRIMVARS = {FEATHER_UV: "pavonine:featherUV", BARB_TANGENT: "pavonine:barbTangent"}
#: Environment variable: ``1`` renders feather materials through their UsdPreviewSurface.
IGNORE_FEATHER_SCHEMA = "PAVONINE_IGNORE_FEATHER_SCHEMA"
DEFAULT_GREY = 0.5
COLOR_INPUTS = ("diffuseColor", "emissiveColor", "specularColor")
#: UsdUVTexture outputs → channels of the RGBA texel
CHANNELS = {"rgb": (0, 1, 2), "r": (0,), "g": (1,), "b": (2,), "a": (3,)}


@dataclass
class MaterialSpec:
    """What a mesh needs to know about its material."""

    key: str  # cache key: the material's path, or a synthetic name
    bsdf: dict[str, Any]  # for mi.load_dict
    uv_primvar: str = "st"  # primvar passed to Mitsuba as the mesh's texcoords
    attributes: dict[str, str] = field(default_factory=dict)  # primvar → Mitsuba vertex attribute
    two_sided: bool = False  # the BSDF already shades both sides (no ``twosided`` wrapper)
    is_feather: bool = False

    def primvars_for(self, prim: Usd.Prim) -> tuple[str, dict[str, str]]:
        """``(uv primvar, attributes)`` for one mesh: a primvar the mesh lacks under its current
        name but carries under its legacy one (:data:`LEGACY_PRIMVARS`) is read by that."""
        api = UsdGeom.PrimvarsAPI(prim)

        def name(primvar: str) -> str:
            legacy = LEGACY_PRIMVARS.get(primvar)
            if legacy and not api.HasPrimvar(primvar) and api.HasPrimvar(legacy):
                return legacy
            return primvar

        return name(self.uv_primvar), {name(k): v for k, v in self.attributes.items()}


def default_material(display_color: tuple[float, float, float] | None = None) -> MaterialSpec:
    """Grey diffuse, or diffuse in the prim's constant ``displayColor``."""
    if display_color is None:
        return MaterialSpec(
            "__default_grey", {"type": "diffuse", "reflectance": _rgb([DEFAULT_GREY] * 3)}
        )
    key = "__display_color_" + "_".join(f"{c:.4f}" for c in display_color)
    return MaterialSpec(key, {"type": "diffuse", "reflectance": _rgb(display_color)})


def display_color(prim: Usd.Prim, time: Usd.TimeCode) -> tuple[float, float, float] | None:
    """A gprim's ``primvars:displayColor`` when it is one colour (constant or a single value)."""
    primvar = UsdGeom.PrimvarsAPI(prim).GetPrimvar("displayColor")
    if not primvar or not primvar.HasValue():
        return None
    values = primvar.ComputeFlattened(time)
    if values is None or len(values) != 1:
        return None
    return tuple(float(c) for c in values[0])  # type: ignore[return-value]


def is_feather_material(material: UsdShade.Material) -> bool:
    """True when the material carries the ``PavonineFeatherAPI`` applied schema.

    Reads the composed ``apiSchemas`` (``GetPrimTypeInfo``) so that it works whether or not the
    schema's plugin is registered in this process (``GetAppliedSchemas`` drops unknown schemas).
    """
    return FEATHER_API in material.GetPrim().GetPrimTypeInfo().GetAppliedAPISchemas()


def translate_material(
    material: UsdShade.Material, time: Usd.TimeCode, diag: Diagnostics
) -> MaterialSpec:
    """The Mitsuba BSDF of a bound USD material (feather, preview surface, or grey fallback)."""
    path = str(material.GetPath())
    if is_feather_material(material) and os.environ.get(IGNORE_FEATHER_SCHEMA) != "1":
        return feather_bsdf(material, time, diag)
    shader = _surface_shader(material)
    if shader is None:
        diag.warn(path, "material has no surface shader; rendering grey diffuse")
        return default_material()
    shader_id = shader.GetIdAttr().Get() if shader.GetIdAttr() else None
    if shader_id != "UsdPreviewSurface":
        diag.warn(path, f"surface shader {shader_id!r} is not supported; rendering grey diffuse")
        return default_material()
    bsdf, uv = preview_surface_bsdf(shader, time, diag)
    return MaterialSpec(path, bsdf, uv_primvar=uv)


def feather_bsdf(
    material: UsdShade.Material, time: Usd.TimeCode, diag: Diagnostics
) -> MaterialSpec:
    """The spectral feather BSDF (``pavonine.render.feather_bsdf``) of a ``PavonineFeatherAPI`` material.

    Parameters and the six maps come from ``pavonine.schemas.authoring``; maps are read through
    USD's asset resolver (``pavonine.asset_io.local_file``: members of a ``.usdz`` too). A map
    that cannot be read gets one warning and the map's neutral value.
    """
    from pavonine.asset_io import local_file
    from pavonine.render import feather_bsdf as plugin
    from pavonine.schemas import authoring

    path = str(material.GetPath())
    params = authoring.read_feather_parameters(material)
    maps = dict(authoring.resolve_maps(material))
    for name, file in list(maps.items()):
        if not file:
            continue
        try:
            maps[name] = local_file(file)
        except OSError:
            diag.warn(path, f"{name} map {file!r} not found; using the map's neutral value")
            maps[name] = None
    plugin.register()
    bsdf = plugin.feather_bsdf_dict(params, maps, barb_tangents=True)
    attributes = {BARB_TANGENT: plugin.BARB_TANGENT_ATTRIBUTE}
    return MaterialSpec(path, bsdf, FEATHER_UV, attributes, two_sided=True, is_feather=True)


def preview_surface_bsdf(
    shader: UsdShade.Shader, time: Usd.TimeCode, diag: Diagnostics
) -> tuple[dict, str]:
    """``UsdPreviewSurface`` → ``principled`` (wrapped in ``mask`` when opacity < 1); returns the uv primvar."""
    uv_names: list[str] = []
    bsdf: dict[str, Any] = {"type": "principled"}
    mapping = (
        ("diffuseColor", "base_color", (0.18, 0.18, 0.18)),
        ("roughness", "roughness", 0.5),
        ("metallic", "metallic", 0.0),
        ("clearcoat", "clearcoat", 0.0),
    )
    for usd_name, mi_name, fallback in mapping:
        bsdf[mi_name] = _input_value(shader, usd_name, fallback, time, diag, uv_names)
    ior = _constant(shader, "ior", 1.5, time)
    bsdf["eta"] = max(float(ior), 1.0 + 1e-4)
    clearcoat_roughness = _constant(shader, "clearcoatRoughness", 0.01, time)
    bsdf["clearcoat_gloss"] = 1.0 - float(clearcoat_roughness)
    opacity = _input_value(shader, "opacity", 1.0, time, diag, uv_names)
    threshold = float(_constant(shader, "opacityThreshold", 0.0, time))
    if threshold > 0.0:
        opacity = _opacity_cutout(opacity, threshold, str(shader.GetPath()), diag)
    if not (isinstance(opacity, float) and opacity >= 1.0):
        bsdf = {"type": "mask", "opacity": opacity, "bsdf": bsdf}
    return bsdf, (uv_names[0] if uv_names else "st")


def _opacity_cutout(opacity: Any, threshold: float, where: str, diag: Diagnostics) -> Any:
    """``opacityThreshold`` > 0: opacity below it is 0, the rest 1 (UsdPreviewSurface spec)."""
    if isinstance(opacity, float):
        return 1.0 if opacity >= threshold else 0.0
    if isinstance(opacity, dict) and opacity.get("type") == "bitmap":
        import mitsuba as mi

        values = np.atleast_3d(np.array(opacity["bitmap"], dtype=np.float32))
        if values.shape[2] == 1 and opacity.get("raw"):
            cut = (values >= threshold).astype(np.float32)
            return {**opacity, "bitmap": mi.Bitmap(cut)}
    diag.warn(where, "opacityThreshold applies to one-channel opacity only; ignored")
    return opacity


def _surface_shader(material: UsdShade.Material) -> UsdShade.Shader | None:
    source = material.ComputeSurfaceSource()
    shader = source[0] if isinstance(source, tuple) else source
    return shader if shader and shader.GetPrim().IsValid() else None


def _constant(shader: UsdShade.Shader, name: str, fallback: Any, time: Usd.TimeCode) -> Any:
    shader_input = shader.GetInput(name)
    if shader_input:
        value = shader_input.Get(time)
        if value is not None:
            return value
    return fallback


def _input_value(
    shader: UsdShade.Shader,
    name: str,
    fallback: Any,
    time: Usd.TimeCode,
    diag: Diagnostics,
    uv_names: list[str],
) -> Any:
    """An input as a Mitsuba value: float, ``rgb`` dict, or ``bitmap`` dict when connected to a texture."""
    shader_input = shader.GetInput(name)
    value: Any = fallback
    if shader_input:
        connection = shader_input.GetConnectedSource()
        if connection:
            source, output_name, _kind = connection
            texture = _texture(
                UsdShade.Shader(source.GetPrim()), name, output_name, time, diag, uv_names
            )
            if texture is not None:
                return texture
            value = _texture_fallback(UsdShade.Shader(source.GetPrim()), fallback, time)
        else:
            authored = shader_input.Get(time)
            value = fallback if authored is None else authored
    return _as_mitsuba(value)


def _texture(
    shader: UsdShade.Shader,
    input_name: str,
    output_name: str,
    time: Usd.TimeCode,
    diag: Diagnostics,
    uv_names: list[str],
) -> dict | None:
    """A ``UsdUVTexture`` as a Mitsuba ``bitmap`` dict; ``None`` (with a warning) if it cannot be read."""
    where = str(shader.GetPath())
    if shader.GetIdAttr().Get() != "UsdUVTexture":
        diag.warn(
            where, f"shader {shader.GetIdAttr().Get()!r} feeding {input_name} is not supported"
        )
        return None
    file_input = shader.GetInput("file")
    asset = file_input.Get(time) if file_input else None
    if not isinstance(asset, Sdf.AssetPath) or not asset.path:
        diag.warn(where, "UsdUVTexture has no inputs:file; using its fallback")
        return None
    resolved = asset.resolvedPath
    if not resolved or not os.path.isfile(resolved):
        diag.warn(where, f"texture {asset.path!r} not found; using its fallback")
        return None
    bitmap = load_bitmap(resolved, where, diag)
    if bitmap is None:
        return None
    space = _constant(shader, "sourceColorSpace", "auto", time)
    is_colour = input_name in COLOR_INPUTS and output_name == "rgb"
    raw = space == "raw" or (space == "auto" and not is_colour)
    uv_names.append(_uv_primvar_name(shader, time))
    wrap = _wrap_mode(shader, time, diag)
    scale = np.asarray(_constant(shader, "scale", (1.0, 1.0, 1.0, 1.0), time), dtype=np.float64)
    bias = np.asarray(_constant(shader, "bias", (0.0, 0.0, 0.0, 0.0), time), dtype=np.float64)
    identity = np.array_equal(scale, np.ones(4)) and not np.any(bias)
    if output_name == "rgb" and identity:
        return {"type": "bitmap", "bitmap": bitmap, "raw": bool(raw), "wrap_mode": wrap}
    channels = CHANNELS.get(output_name)
    if channels is None:
        diag.warn(
            where, f"UsdUVTexture output {output_name!r} is not supported; using its fallback"
        )
        return None
    # A named channel (or scale/bias): decode in numpy, as UsdUVTexture defines it:
    # value = decoded texel · scale + bias, per channel (UsdPreviewSurface spec, UsdUVTexture).
    texels = texel_values(bitmap, decode_srgb=not raw)
    values = np.stack([texels[:, :, c] for c in channels], axis=2) * scale[list(channels)]
    values = values + bias[list(channels)]
    import mitsuba as mi

    linear = mi.Bitmap(np.ascontiguousarray(values, dtype=np.float32))
    # colour: linear floats, spectrally upsampled (raw=False); one channel: data (raw=True)
    return {"type": "bitmap", "bitmap": linear, "raw": len(channels) == 1, "wrap_mode": wrap}


def texel_values(bitmap, decode_srgb: bool) -> np.ndarray:
    """H×W×4 float RGBA in [0, 1] of a ``mi.Bitmap``, as ``UsdUVTexture`` reads a file.

    Integer formats are normalised; grey images give r = g = b; a missing alpha is 1. With
    ``decode_srgb`` the colour channels of an sRGB-encoded file are linearised with the sRGB
    transfer function (IEC 61966-2-1); alpha is always linear.
    """
    pixels = np.array(bitmap)
    if pixels.ndim == 2:
        pixels = pixels[:, :, None]
    if np.issubdtype(pixels.dtype, np.integer):
        values = pixels.astype(np.float64) / float(np.iinfo(pixels.dtype).max)
    else:
        values = pixels.astype(np.float64)
    count = values.shape[2]
    colour = values[:, :, :3] if count >= 3 else np.repeat(values[:, :, :1], 3, axis=2)
    alpha = values[:, :, 3:4] if count >= 4 else values[:, :, 1:2] if count == 2 else None
    if alpha is None:
        alpha = np.ones((*colour.shape[:2], 1))
    if decode_srgb and bitmap.srgb_gamma():
        colour = np.where(
            colour <= 0.04045, colour / 12.92, ((colour + 0.055) / 1.055) ** 2.4
        )  # sRGB EOTF, IEC 61966-2-1:1999
    return np.concatenate([colour, alpha], axis=2)


def _wrap_mode(shader: UsdShade.Shader, time: Usd.TimeCode, diag: Diagnostics) -> str:
    """Mitsuba's one ``wrap_mode`` for ``wrapS``/``wrapT`` (a warning when they cannot be kept)."""
    wrap_s = str(_constant(shader, "wrapS", "useMetadata", time))
    wrap_t = str(_constant(shader, "wrapT", "useMetadata", time))
    modes = {"clamp": "clamp", "mirror": "mirror", "repeat": "repeat", "useMetadata": "repeat"}
    if wrap_s != wrap_t or wrap_s not in modes:
        diag.warn(
            str(shader.GetPath()),
            f"wrapS {wrap_s!r} / wrapT {wrap_t!r}: Mitsuba has one wrap mode (repeat, clamp or "
            f"mirror); using {modes.get(wrap_s, 'repeat')!r}",
        )
    return modes.get(wrap_s, "repeat")


def load_bitmap(path: str, where: str, diag: Diagnostics):
    """``mi.Bitmap`` of an image file, or ``None`` with a warning naming ``where`` and the file."""
    import mitsuba as mi

    try:
        return mi.Bitmap(path)
    except Exception as exc:
        diag.warn(where, f"cannot read texture {path!r}: {str(exc).splitlines()[0]}")
        return None


def _uv_primvar_name(texture: UsdShade.Shader, time: Usd.TimeCode) -> str:
    st_input = texture.GetInput("st")
    if st_input:
        connection = st_input.GetConnectedSource()
        if connection:
            reader = UsdShade.Shader(connection[0].GetPrim())
            name = _constant(reader, "varname", "st", time)
            return str(name)
    return "st"


def _texture_fallback(texture: UsdShade.Shader, fallback: Any, time: Usd.TimeCode) -> Any:
    value = _constant(texture, "fallback", None, time)
    if value is None:
        return fallback
    if isinstance(fallback, float):
        return float(value[0])
    return tuple(value)[:3]


def _as_mitsuba(value: Any) -> Any:
    if isinstance(value, (int, float)):
        return float(value)
    components = tuple(float(c) for c in value)
    return _rgb(components[:3])


def _rgb(color) -> dict:
    return {"type": "rgb", "value": [float(c) for c in color]}
