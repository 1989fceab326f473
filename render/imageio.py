"""Images out: scene-linear EXR with its colour space in the header, display PNG through OCIO.

EXR: 32-bit float RGB written with OpenImageIO, ``oiio:ColorSpace`` = ``lin_rec709_scene``
(Linear Rec.709 (sRGB) in the OCIO built-in configs) and the standard EXR ``chromaticities``
(Rec.709 primaries, D65 white), plus the render's metadata as ``pavonine:*`` attributes.
PNG: the same pixels through OpenColorIO's built-in CG config, display ``sRGB - Display``
(view ``Un-tone-mapped`` unless told otherwise), as :mod:`pavonine.materials.colour` does.
Both are written atomically (a temporary file renamed on success).
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from typing import Any

import numpy as np

from pavonine.materials.colour import DEFAULT_VIEW, display_encode
from pavonine.pipeline.errors import InputError, atomic_path

EXR_COLORSPACE = "lin_rec709_scene"
REC709_CHROMATICITIES = (0.64, 0.33, 0.30, 0.60, 0.15, 0.06, 0.3127, 0.3290)


def write_exr(
    path: str | os.PathLike, rgb: np.ndarray, metadata: Mapping[str, Any] | None = None
) -> None:
    """Write H×W×3 scene-linear Rec.709 ``rgb`` as a float EXR with colour-space metadata."""
    import OpenImageIO as oiio

    pixels = _check_rgb(rgb)
    spec = oiio.ImageSpec(pixels.shape[1], pixels.shape[0], 3, oiio.FLOAT)
    spec.channelnames = ("R", "G", "B")
    spec.attribute("oiio:ColorSpace", EXR_COLORSPACE)
    spec.attribute("chromaticities", oiio.TypeDesc("float[8]"), REC709_CHROMATICITIES)
    spec.attribute("compression", "zip")
    spec.attribute("Software", "pavonine")
    for key, value in (metadata or {}).items():
        if isinstance(value, bool) or not isinstance(value, (int, float, str)):
            value = json.dumps(value, default=str)
        spec.attribute(f"pavonine:{key}", value)
    _write(path, pixels, spec)


def write_png(path: str | os.PathLike, rgb: np.ndarray, view: str = DEFAULT_VIEW) -> None:
    """Write scene-linear ``rgb`` as an 8-bit sRGB PNG through the OCIO display/view transform."""
    import OpenImageIO as oiio

    pixels = _check_rgb(rgb)
    display = display_encode(np.nan_to_num(pixels, nan=0.0, posinf=0.0, neginf=0.0), view=view)
    encoded = np.round(np.clip(display, 0.0, 1.0) * 255.0).astype(np.uint8)
    spec = oiio.ImageSpec(pixels.shape[1], pixels.shape[0], 3, oiio.UINT8)
    spec.attribute("oiio:ColorSpace", "srgb_rec709_display")
    spec.attribute("Software", f"pavonine (OCIO view {view!r})")
    _write(path, encoded, spec)


def read_exr(path: str | os.PathLike) -> tuple[np.ndarray, dict[str, Any]]:
    """Pixels (H×W×C float32) and header attributes of an image written by :func:`write_exr`."""
    import OpenImageIO as oiio

    image = oiio.ImageInput.open(os.fspath(path))
    if image is None:
        raise InputError(os.fspath(path), f"cannot read image: {oiio.geterror()}")
    try:
        spec = image.spec()
        pixels = image.read_image(oiio.FLOAT)
        attributes = {a.name: a.value for a in spec.extra_attribs}
    finally:
        image.close()
    return np.asarray(pixels), attributes


def _check_rgb(rgb: np.ndarray) -> np.ndarray:
    pixels = np.ascontiguousarray(np.asarray(rgb, dtype=np.float32))
    if pixels.ndim != 3 or pixels.shape[2] != 3:
        raise ValueError(f"expected an H×W×3 image, got shape {pixels.shape}")
    return pixels


def _write(path: str | os.PathLike, pixels: np.ndarray, spec) -> None:
    import OpenImageIO as oiio

    with atomic_path(path) as tmp:
        out = oiio.ImageOutput.create(os.fspath(tmp))
        if out is None:
            raise InputError(os.fspath(path), f"cannot write this image format: {oiio.geterror()}")
        try:
            if not out.open(os.fspath(tmp), spec) or not out.write_image(pixels):
                raise InputError(os.fspath(path), f"cannot write image: {out.geterror()}")
        finally:
            out.close()
