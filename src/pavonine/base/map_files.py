"""Reading and writing the feather's data maps (paper §3.3) through OpenImageIO.

Maps are single-channel *data*, never colour: they are written as 16-bit PNG (or half-float
EXR) tagged ``oiio:ColorSpace = "Raw"`` and read back as float32 in [0, 1] without any
colour transform. Arrays are indexed ``[row, column]`` with row 0 the *top* of the image,
as image files store them; feather space puts ``v = 0`` at the image's bottom row
(see :func:`sample_bilinear`).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
from scipy import ndimage

from pavonine.base.errors import InputError
from pavonine.base.image_files import write_image_file
from pavonine.base.limits import image_error, odd_aspects, open_image

#: Colour space written into every map (data, not colour).
DATA_COLORSPACE = "Raw"

#: Rec. 709 luma weights, used only when someone hands us an RGB(A) "grey" map.
_REC709_LUMA = np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)

#: How :func:`write_map` compresses a PNG with ``fast=True`` (the asset's copies of a recipe's
#: maps, which can be 8192 pixels high): every row with libpng's Sub filter (each 16-bit sample
#: less its left neighbour), deflated at zlib level 4. libpng's default (its adaptive choice
#: among the five filters per row, level 6; kept for baked textures) took three times the CPU:
#: the shipped eye feather's six 512x1024 maps 0.34 s and 1,614,583 bytes against 0.11 s and
#: 1,605,917 bytes; the same maps upsampled to 4096x8192 (``bench_convert.py --big``) 16.4 s and
#: 58.5 MB against 5.4 s and 48.1 MB (the four baked 1024x1024 textures grew 6 % this way).
#: Lossless either way: only the files' bytes differ, not one pixel.
FAST_PNG = {"png:filter": 16, "png:compressionLevel": 4}  # 16: PNG_FILTER_SUB (png.h)

#: How far a float map's values may lie outside [0, 1] and still be read (clamped): float
#: round-off of a value meant to be 0 or 1, never a value meant to be out of range.
RANGE_TOLERANCE = 1e-6


def write_map(
    path: str | os.PathLike,
    values: np.ndarray,
    *,
    description: str = "",
    attributes: dict[str, str] | None = None,
    fast: bool = False,
) -> None:
    """Write a 2-D array of values in [0, 1] as a single-channel data map (``attributes``:
    further header attributes, e.g. the ``pavonine:group`` of a set of maps; ``fast``: a PNG
    compressed as :data:`FAST_PNG`, for big maps).

    ``.png`` → 16-bit unsigned integer; ``.exr`` → half float (zip). Values are clipped to
    [0, 1]; NaN is rejected. The file appears atomically (written beside, then renamed).
    """
    path = Path(path)
    values = np.asarray(values, dtype=np.float32)
    if values.ndim != 2:
        raise ValueError(f"{path}: a map is a 2-D array, got shape {values.shape}")
    if not np.all(np.isfinite(values)):
        raise ValueError(f"{path}: map contains NaN or infinite values")
    height, width = values.shape
    suffix = path.suffix.lower()
    if suffix == ".png":
        spec = oiio.ImageSpec(width, height, 1, oiio.UINT16)
        for key, value in (FAST_PNG if fast else {}).items():
            spec.attribute(key, value)
        scaled = np.clip(values, 0.0, 1.0)  # one float32 buffer, scaled and rounded in place
        scaled *= 65535.0
        pixels = np.rint(scaled, out=scaled).astype(np.uint16)
    elif suffix == ".exr":
        spec = oiio.ImageSpec(width, height, 1, oiio.HALF)
        spec.attribute("compression", "zip")
        pixels = np.clip(values, 0.0, 1.0).astype(np.float32)
    else:
        raise ValueError(f"{path}: maps are written as .png or .exr, not {suffix!r}")
    spec.channelnames = ("Y",)
    spec.attribute("oiio:ColorSpace", DATA_COLORSPACE)
    spec.attribute("Software", "pavonine")
    if description:
        spec.attribute("ImageDescription", description)
    for key, value in (attributes or {}).items():
        spec.attribute(key, value)

    # A 2-D array is misread by the Python binding; pass (rows, columns, channels).
    write_image_file(path, np.ascontiguousarray(pixels[..., None]), spec)


@dataclass(frozen=True)
class DataMap:
    """A map as read: grey values ``[row, column]`` in [0, 1] and whether the file held floats."""

    values: np.ndarray
    is_float: bool

    @property
    def suffix(self) -> str:
        """The format the asset keeps it in: ``.exr`` (half) for float input, else ``.png`` (16-bit)."""
        return ".exr" if self.is_float else ".png"


#: One grey channel of 8 or 16 bits is decoded as stored and scaled here: ``k · (1 / (2ⁿ − 1))``
#: in float32 is OpenImageIO's own conversion to float for every ``k`` (tests/pipeline/test_maps.py), and
#: it halves what the decoder hands over (a 4096x8192 map: 1.45 s of CPU read as float, 0.96 s
#: this way).
INTEGER_SCALES = {
    oiio.UINT8: np.float32(1.0) / np.float32(255.0),
    oiio.UINT16: np.float32(1.0) / np.float32(65535.0),
}


def read_data_map(path: str | os.PathLike, field: str) -> DataMap:
    """Read a grey map and note its pixel type; see :func:`read_map`."""
    from pavonine.base.groups import check_group

    path = Path(path)
    where = f"{path}: {field}"
    check_group(path, where)  # not one of a set of maps mixed from two writes
    with open_image(path, where) as image:  # a regular file within the pixel budget
        spec = image.spec()
        stored = INTEGER_SCALES.get(spec.format.basetype) if spec.nchannels == 1 else None
        as_read = oiio.FLOAT if stored is None else spec.format.basetype
        pixels = image.read_image(0, 0, 0, spec.nchannels, as_read)
        error = image.geterror()
    if pixels is None:
        raise InputError(where, f"unreadable image ({image_error(error)})")
    if stored is not None:
        pixels = pixels.astype(np.float32)
        pixels *= stored
    grey = grey_values(pixels, spec)
    problem = value_problem(grey)
    if problem:
        raise InputError(where, problem)
    is_float = spec.format.basetype in (oiio.HALF, oiio.FLOAT, oiio.DOUBLE)
    if is_float or spec.nchannels >= 3:  # integers are read as k / (2ⁿ − 1), in [0, 1] already
        grey = np.clip(grey, 0.0, 1.0)  # (a luma of three can round a float32 ulp above 1)
    return DataMap(np.ascontiguousarray(grey), is_float)


def check_aspects(
    maps: Mapping[str, np.ndarray], where: Mapping[str, str], reference: str = "alpha"
) -> None:
    """Raise :class:`InputError` at ``where[name]`` (file and field) for the first map whose
    width:height differs from the ``reference`` map's (the first map when that one is absent):
    the maps all span the same feather."""
    sizes = {name: (values.shape[1], values.shape[0]) for name, values in maps.items()}
    reference, odd = odd_aspects(sizes, reference)
    if odd:
        (w, h), (ref_w, ref_h) = sizes[odd[0]], sizes[reference]
        raise InputError(
            where[odd[0]],
            f"aspect {w}x{h} differs from the {reference} map's {ref_w}x{ref_h}; "
            "all the maps must have the same width:height",
        )


def grey_values(pixels: np.ndarray, spec: oiio.ImageSpec) -> np.ndarray:
    """The grey ``[row, column]`` of an image's decoded pixels (all ``spec.nchannels``): the
    first channel, or the Rec. 709 luma of RGB(A)."""
    pixels = np.asarray(pixels, dtype=np.float32).reshape(spec.height, spec.width, spec.nchannels)
    if spec.nchannels >= 3:
        return pixels[..., :3] @ _REC709_LUMA
    return pixels[..., 0]


def value_problem(grey: np.ndarray) -> str | None:
    """Why a map's grey values are unusable (non-finite, or outside [0, 1] by more than
    :data:`RANGE_TOLERANCE`), or ``None``."""
    if not np.all(np.isfinite(grey)):
        return "contains NaN or infinite values"
    if grey.size == 0:
        return None
    low, high = float(grey.min()), float(grey.max())
    if low < -RANGE_TOLERANCE or high > 1.0 + RANGE_TOLERANCE:
        return f"values outside [0, 1] (min {low:g}, max {high:g})"
    return None


def read_map(path: str | os.PathLike, field: str) -> np.ndarray:
    """Read a grey map as float32 ``[row, column]`` in [0, 1]; ``field`` names it in errors.

    Accepts 8/16-bit integer or float images; one channel (or grey+alpha: the grey is used);
    RGB(A) is reduced to Rec. 709 luma. Pixel values are taken as stored (no colour
    transform). Raises :class:`InputError` naming the file and field when it is not a regular
    file, unreadable, empty, beyond the pixel budget (checked from the header, before decoding:
    :mod:`pavonine.base.limits`), non-finite or outside [0, 1] (beyond :data:`RANGE_TOLERANCE`).
    """
    return read_data_map(path, field).values


#: Texture wrap modes (Mitsuba's names) → SciPy's boundary modes for interpolation and filters
#: (``grid-wrap`` interpolates between the last and the first texel, as a repeating texture does).
WRAP_MODES = {"clamp": "nearest", "repeat": "grid-wrap", "mirror": "mirror"}
FILTER_MODES = {"clamp": "nearest", "repeat": "wrap", "mirror": "mirror"}


def sample_bilinear(values: np.ndarray, feather_uv: np.ndarray, wrap: str = "clamp") -> np.ndarray:
    """Bilinear lookup of a map at feather-space coordinates.

    ``feather_uv[:, 0] = u`` runs left → right across the image, ``feather_uv[:, 1] = v`` runs
    bottom → top: ``(0, 0)`` is the bottom-left corner of the image's bottom-left pixel and
    ``(1, 1)`` the top-right corner of its top-right pixel. Pixel centres sit at
    ``((col + 0.5) / W, 1 - (row + 0.5) / H)``; lookups beyond the outer centres clamp
    (``wrap="clamp"``), or the map repeats or mirrors (``"repeat"``, ``"mirror"``: the texture
    wrap modes, as Mitsuba's ``bitmap`` applies them).
    """
    height, width = values.shape
    uv = np.asarray(feather_uv, dtype=np.float64)
    cols = uv[:, 0] * width - 0.5
    rows = (1.0 - uv[:, 1]) * height - 0.5
    mode = WRAP_MODES[wrap]
    return ndimage.map_coordinates(values, [rows, cols], order=1, mode=mode).astype(np.float32)


def sample_nearest(values: np.ndarray, feather_uv: np.ndarray) -> np.ndarray:
    """The texel under each feather-space point (no filtering; see :func:`sample_bilinear` for
    the convention): how class maps are read, so that a lookup never blends two classes."""
    height, width = values.shape
    uv = np.asarray(feather_uv, dtype=np.float64)
    cols = np.clip(np.floor(uv[:, 0] * width), 0, width - 1).astype(np.int64)
    rows = np.clip(np.floor((1.0 - uv[:, 1]) * height), 0, height - 1).astype(np.int64)
    return values[rows, cols].astype(np.float32)


def area_reduce(values: np.ndarray, factor: int) -> np.ndarray:
    """Average ``factor × factor`` blocks of an image (trailing channel axes kept), edges padded
    by repetition: the box-filtered, smaller map (its extent unchanged)."""
    if factor <= 1:
        return values
    h, w = values.shape[:2]
    pad = ((0, (-h) % factor), (0, (-w) % factor)) + ((0, 0),) * (values.ndim - 2)
    padded = np.pad(values, pad, mode="edge") if h % factor or w % factor else values
    blocks = (padded.shape[0] // factor, factor, padded.shape[1] // factor, factor)
    return padded.reshape(blocks + values.shape[2:]).mean(axis=(1, 3))
