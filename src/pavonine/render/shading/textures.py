"""``UsdUVTexture`` (and ``UsdTransform2d`` on its ``st``) → Mitsuba ``bitmap`` textures.

Follows the UsdPreviewSurface specification (UsdUVTexture):

* ``file`` is resolved through ``Ar`` and read with OpenImageIO from
  :func:`pavonine.base.asset_io.local_file` (so ``x.usdz[tex.png]`` works); ``<UDIM>`` paths are
  stitched into one atlas (tiles 1001-1100, all the size of the first).
* ``sourceColorSpace``: ``sRGB`` decodes the colour channels with the sRGB transfer function
  (IEC 61966-2-1), ``raw`` does not, ``auto`` decodes 8-bit images with 3 or 4 channels only
  (the spec's rule when the file carries no other information). Alpha is always linear.
* outputs ``rgb``/``r``/``g``/``b``/``a``: ``value = texel · scale + bias`` per channel (grey
  images give r = g = b, a missing alpha is 1), then the consumer's own affine map (e.g. a normal
  map's [-1, 1] → Mitsuba's [0, 1]).
* ``wrapS``/``wrapT``: Mitsuba has one wrap mode per texture (a warning when S ≠ T); ``black`` is
  a one-texel black border with ``clamp``; ``useMetadata`` uses the file's ``wrapmodes`` when it has
  them, else ``repeat``.
* ``st``: a ``UsdPrimvarReader_float2`` names the uv set (the mesh's texture coordinates); a
  ``UsdTransform2d`` in between becomes the bitmap's ``to_uv`` (``in · scale · rotate +
  translation``); an unconnected ``st`` reads the one texel at its value.
* ``fallback`` (the channel the output reads) when the file is missing or unreadable.

Mitsuba's uv is USD's ``(s, 1 − t)`` (image rows start at the top), so every uv transform is
conjugated by that flip.
"""

from __future__ import annotations

import math
import os
from typing import Any

import numpy as np
from pxr import Ar, Sdf, UsdShade

from pavonine.base.asset_io import AssetReadError, local_file
from pavonine.base.errors import InputError
from pavonine.base.limits import check_image, image_error
from pavonine.base.native_output import captured
from pavonine.render.shading.network import (
    COLOR,
    COMPONENTS,
    Affine,
    Network,
    as_mitsuba,
    shader_identifier,
)

CHANNELS = {"rgb": (0, 1, 2), "r": (0,), "g": (1,), "b": (2,), "a": (3,)}
WRAPS = {"clamp": "clamp", "mirror": "mirror", "repeat": "repeat", "black": "black"}
UDIM_TOKEN = "<UDIM>"
UDIM_TILES = range(1001, 1101)
#: USD st (v up) ↔ Mitsuba uv (v down): its own inverse
FLIP_V = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 1.0], [0.0, 0.0, 1.0]])


def uv_texture(
    shader: UsdShade.Shader, output: str, kind: str, affine: Affine, net: Network
) -> Any:
    """The Mitsuba value of ``shader.outputs:<output>`` read as ``kind`` (see module doc)."""
    where = str(shader.GetPath())
    net.audit(shader)
    channels = CHANNELS.get(output)
    fallback = np.asarray(net.constant(shader, "fallback", (0.0, 0.0, 0.0, 1.0)), dtype=float)
    fallback = np.resize(fallback, 4)
    if channels is None:
        net.warn(where, f"UsdUVTexture output {output!r} is not supported; using its fallback")
        return as_mitsuba(affine.apply(_fit(fallback[:3], kind)), kind)
    constant = _fit(fallback[list(channels)], kind)
    image = _image(shader, net)
    if image is None:
        return as_mitsuba(affine.apply(constant), kind)
    texels, to_uv, wrap = image
    scale = np.resize(np.asarray(net.constant(shader, "scale", (1, 1, 1, 1)), dtype=float), 4)
    bias = np.resize(np.asarray(net.constant(shader, "bias", (0, 0, 0, 0)), dtype=float), 4)
    values = texels * scale + bias  # UsdUVTexture: texel · scale + bias, per channel
    values = affine.apply(fit_channels(values[..., list(channels)], kind))
    uv = _st_source(shader, net)
    if uv is None:
        st = net.constant(shader, "st", None)
        if st is not None:  # an authored, unconnected st: every point reads the texel there
            return as_mitsuba(_texel_at(values, to_uv, np.asarray(st, dtype=float)), kind)
        net.warn(where, "st is neither connected nor set; reading the mesh's st primvar")
        uv = ("st", np.eye(3))
    name, transform = uv
    net.use_uv(name)
    return bitmap_dict(values, kind, wrap, FLIP_V @ to_uv @ transform @ FLIP_V)


def bitmap_dict(values: np.ndarray, kind: str, wrap: str, to_uv: np.ndarray) -> dict:
    """A ``bitmap`` dict of H×W×C linear values (colours above 1 wrapped in a scaled ``d65``)."""
    import mitsuba as mi

    values = np.ascontiguousarray(values, dtype=np.float32)
    texture: dict = {"type": "bitmap", "raw": kind != COLOR, "wrap_mode": wrap}
    if not np.allclose(to_uv, np.eye(3)):
        texture["to_uv"] = mi.ScalarTransform3f(to_uv.tolist())
    peak = float(values.max()) if values.size else 0.0
    if kind == COLOR:
        values = np.maximum(values, 0.0)
        if peak > 1.0:  # Mitsuba's spectral upsampling takes [0, 1]: carry the peak as a scale
            texture["bitmap"] = mi.Bitmap(values / peak)
            return {"type": "d65", "nested": texture, "scale": peak}
    texture["bitmap"] = mi.Bitmap(values)
    return texture


def _fit(values: np.ndarray, kind: str) -> np.ndarray:
    """A constant with the components ``kind`` needs (a single channel is broadcast)."""
    values = np.atleast_1d(values)
    return values[:1] if COMPONENTS[kind] == 1 else np.resize(values, 3)


def fit_channels(values: np.ndarray, kind: str) -> np.ndarray:
    """H×W×C → H×W×1 (first channel) or H×W×3 (one channel repeated) as ``kind`` needs."""
    if COMPONENTS[kind] == 1:
        return values[..., :1]
    if values.shape[2] == 1:
        return np.repeat(values, 3, axis=2)
    return values


def _texel_at(values: np.ndarray, to_uv: np.ndarray, st: np.ndarray) -> np.ndarray:
    """The texel (nearest) a fixed ``st`` reads, wrapped with repeat."""
    u, v, _ = to_uv @ np.array([st[0], st[1], 1.0])
    h, w = values.shape[:2]
    col = math.floor((u % 1.0) * w) % w
    row = math.floor((1.0 - (v % 1.0)) * h) % h
    return values[row, col]


# -- the image -----------------------------------------------------------------------------------


def _image(shader: UsdShade.Shader, net: Network) -> tuple[np.ndarray, np.ndarray, str] | None:
    """(H×W×4 linear RGBA texels, st → atlas-st matrix, Mitsuba wrap mode), or ``None`` (warned)."""
    where = str(shader.GetPath())
    asset = net.constant(shader, "file", None)
    if not isinstance(asset, Sdf.AssetPath) or not asset.path:
        net.warn(where, "UsdUVTexture has no inputs:file; using its fallback")
        return None
    space = str(net.constant(shader, "sourceColorSpace", "auto"))
    if space not in ("auto", "raw", "sRGB"):
        net.warn(where, f"sourceColorSpace {space!r} is not raw, sRGB or auto; using auto")
        space = "auto"
    image = load_image(shader.GetInput("file"), asset, space, where, net)
    if image is None:
        return None
    texels, to_uv, metadata_wrap = image
    return bordered(texels, to_uv, _wrap_mode(shader, metadata_wrap, net), np.zeros(4))


def load_image(
    file_input: UsdShade.Input, asset: Sdf.AssetPath, space: str, where: str, net: Network
) -> tuple[np.ndarray, np.ndarray, str | None] | None:
    """(H×W×4 texels, st → atlas-st matrix, the file's wrap metadata) of a texture node's file
    (``<UDIM>`` tiles stitched), decoded as ``space`` says; ``None`` (warned) if none is read."""
    if UDIM_TOKEN in asset.path:
        tiles = _udim_tiles(file_input, asset.path)
        if not tiles:
            net.warn(where, f"no UDIM tiles found for {asset.path!r}; using its fallback")
            return None
        return _udim_atlas(tiles, space, where, net)
    resolved = asset.resolvedPath
    if not resolved:
        net.warn(where, f"texture {asset.path!r} not found; using its fallback")
        return None
    return _decoded(resolved, space, where, net)


def bordered(
    texels: np.ndarray, to_uv: np.ndarray, wrap: str, outside: np.ndarray
) -> tuple[np.ndarray, np.ndarray, str]:
    """``black`` (UsdUVTexture) and ``constant`` (MaterialX) wraps: a one-texel border of
    ``outside`` (RGBA), clamped, so that the image reads ``outside`` beyond its edges."""
    if wrap not in ("black", "constant"):
        return texels, to_uv, wrap
    h, w = texels.shape[:2]
    padded = np.empty((h + 2, w + 2, texels.shape[2]))
    padded[...] = np.resize(outside, texels.shape[2])
    padded[1:-1, 1:-1] = texels
    border = np.array([[w / (w + 2), 0, 1 / (w + 2)], [0, h / (h + 2), 1 / (h + 2)], [0, 0, 1]])
    return padded, border @ to_uv, "clamp"


def _decoded(
    resolved: str, space: str, where: str, net: Network
) -> tuple[np.ndarray, np.ndarray, str | None] | None:
    key = (resolved, space)
    if key not in net.textures:
        try:
            net.textures[key] = read_texels(resolved, space)
        except TextureError as exc:
            net.warn(where, f"{exc}; using its fallback")
            net.textures[key] = None
    image = net.textures[key]
    return None if image is None else (image[0], np.eye(3), image[1])


class TextureError(ValueError):
    """An image a stage names that cannot be read (the message names it)."""


def read_texels(resolved: str, space: str = "auto") -> tuple[np.ndarray, str | None]:
    """H×W×4 float RGBA of a resolved asset path, decoded as ``space`` says, and its wrap metadata.

    Raises :class:`TextureError` (naming the file) when it cannot be read.
    """
    import OpenImageIO as oiio

    try:
        path = local_file(resolved)
    except (AssetReadError, OSError) as exc:
        raise TextureError(f"texture {resolved!r} cannot be read ({exc.strerror or exc})") from None
    try:
        check_image(path, resolved)  # a regular file within the pixel budget, from its header
    except InputError as exc:
        raise TextureError(f"texture {exc}") from None
    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)  # texels as stored, colour not premultiplied
    with captured(2):  # libpng's own lines: the TextureError below says it in one
        buf = oiio.ImageBuf(path, 0, 0, config)
        pixels = None if buf.has_error else buf.get_pixels(oiio.FLOAT)
    if pixels is None or buf.has_error:
        raise TextureError(
            f"cannot read texture {resolved!r}: {image_error(buf.geterror(), 'unknown format')}"
        )
    spec = buf.spec()
    values = np.asarray(pixels, dtype=np.float64).reshape(spec.height, spec.width, -1)
    count = min(values.shape[2], 4)
    srgb = space == "sRGB" or (
        space == "auto" and spec.format.basetype == oiio.UINT8 and count in (3, 4)
    )
    rgba = to_rgba(values[..., :count], decode_srgb=srgb)
    wrapmodes = spec.get_string_attribute("wrapmodes", "")
    return rgba, (wrapmodes.split(",")[0] or None) if wrapmodes else None


def to_rgba(values: np.ndarray, decode_srgb: bool) -> np.ndarray:
    """H×W×C values in [0, 1] → H×W×4 RGBA (grey → r = g = b; missing alpha = 1), sRGB decoded."""
    count = values.shape[2]
    colour = values[..., :3] if count >= 3 else np.repeat(values[..., :1], 3, axis=2)
    alpha = values[..., 3:4] if count >= 4 else values[..., 1:2] if count == 2 else None
    if alpha is None:
        alpha = np.ones((*colour.shape[:2], 1))
    if decode_srgb:
        colour = np.where(
            colour <= 0.04045, colour / 12.92, ((np.maximum(colour, 0) + 0.055) / 1.055) ** 2.4
        )  # sRGB EOTF, IEC 61966-2-1:1999
    return np.concatenate([colour, alpha], axis=2)


def _udim_tiles(file_input: UsdShade.Input, path: str) -> dict[int, str]:
    """Resolved paths of the UDIM tiles that exist, by tile number."""
    attr = file_input.GetAttr()
    stack = attr.GetPropertyStack()
    layer = stack[0].layer if stack else None
    resolver = Ar.GetResolver()
    tiles = {}
    for tile in UDIM_TILES:
        name = path.replace(UDIM_TOKEN, str(tile))
        anchored = Sdf.ComputeAssetPathRelativeToLayer(layer, name) if layer else name
        resolved = resolver.Resolve(anchored)
        if resolved and (Ar.IsPackageRelativePath(str(resolved)) or os.path.isfile(str(resolved))):
            tiles[tile] = str(resolved)
    return tiles


def _udim_atlas(
    tiles: dict[int, str], space: str, where: str, net: Network
) -> tuple[np.ndarray, np.ndarray, str | None] | None:
    """The tiles side by side (tile 1001 + u + 10 v at column u, row v from the bottom)."""
    images = {}
    for tile, resolved in tiles.items():
        image = _decoded(resolved, space, where, net)
        if image is not None:
            images[tile] = image[0]
    if not images:
        return None
    first = images[min(images)]
    h, w = first.shape[:2]
    cols = max((t - 1001) % 10 for t in images) + 1
    rows = max((t - 1001) // 10 for t in images) + 1
    atlas = np.zeros((rows * h, cols * w, 4))
    atlas[..., 3] = 1.0
    for tile, texels in images.items():
        if texels.shape[:2] != (h, w):
            net.warn(where, f"UDIM tile {tile} is not {w}×{h} like tile {min(images)}; skipped")
            continue
        u, v = (tile - 1001) % 10, (tile - 1001) // 10
        top = (rows - 1 - v) * h
        atlas[top : top + h, u * w : (u + 1) * w] = texels
    return atlas, np.diag([1.0 / cols, 1.0 / rows, 1.0]), "clamp"


# -- wrap modes and texture coordinates -------------------------------------------------------


def _wrap_mode(shader: UsdShade.Shader, metadata: str | None, net: Network) -> str:
    """Mitsuba's one wrap mode for ``wrapS``/``wrapT`` (a warning when they cannot be kept)."""
    modes = []
    for name in ("wrapS", "wrapT"):
        mode = str(net.constant(shader, name, "useMetadata"))
        if mode == "useMetadata":
            mode = {
                "periodic": "repeat",
                "clamp": "clamp",
                "mirror": "mirror",
                "black": "black",
            }.get(metadata or "", "repeat")
        if mode not in WRAPS:
            net.warn(
                str(shader.GetPath()),
                f"{name} {mode!r} is not a UsdUVTexture wrap mode; using repeat",
            )
            mode = "repeat"
        modes.append(mode)
    if modes[0] != modes[1]:
        net.warn(
            str(shader.GetPath()),
            f"wrapS {modes[0]!r} / wrapT {modes[1]!r}: Mitsuba has one wrap mode per texture; "
            f"using {modes[0]!r} for both",
        )
    return modes[0]


def _st_source(shader: UsdShade.Shader, net: Network) -> tuple[str, np.ndarray] | None:
    """(uv primvar name, st transform) of the texture's ``st``; ``None`` when unconnected."""
    source = net.source(shader.GetInput("st"))
    if source is None:
        return None
    node, _ = source
    transform = np.eye(3)
    node_id = shader_identifier(node)
    if node_id == "UsdTransform2d":
        transform = transform2d(node, net)
        inner = net.source(node.GetInput("in"))
        if inner is None:
            net.warn(str(node.GetPath()), "UsdTransform2d has no connected 'in'; reading st")
            return "st", transform
        node, _ = inner
        node_id = shader_identifier(node)
    if node_id.startswith("UsdPrimvarReader_"):
        net.audit(node)
        name = str(net.constant(node, "varname", "") or "")
        if not name:
            net.warn(str(node.GetPath()), "UsdPrimvarReader has no varname; reading st")
            name = "st"
        return name, transform
    net.warn(
        str(node.GetPath()),
        f"{node_id or 'a shader'} feeding a texture's st is not supported; reading the st primvar",
    )
    return "st", transform


def transform2d(shader: UsdShade.Shader, net: Network) -> np.ndarray:
    """``UsdTransform2d`` as a 3×3 matrix on column vectors: ``in · scale · rotate + translation``."""
    net.audit(shader)
    scale = np.resize(np.asarray(net.constant(shader, "scale", (1.0, 1.0)), dtype=float), 2)
    angle = math.radians(float(net.constant(shader, "rotation", 0.0)))  # counter-clockwise
    move = np.resize(np.asarray(net.constant(shader, "translation", (0.0, 0.0)), dtype=float), 2)
    c, s = math.cos(angle), math.sin(angle)
    rotate = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return np.array([[1, 0, move[0]], [0, 1, move[1]], [0, 0, 1]]) @ rotate @ np.diag([*scale, 1.0])
