"""Image I/O for renders, baselines and comparisons: the one place images are written.

EXR: 32-bit float RGB written with OpenImageIO, ``oiio:ColorSpace`` = ``lin_rec709_scene``
(Linear Rec.709 (sRGB) in the OCIO built-in configs) and the standard EXR ``chromaticities``
(Rec.709 primaries, D65 white), plus metadata as ``pavonine:*`` attributes (variance images too:
their values are in the same scene-linear space, squared).
PNG: the same pixels through a display transform (:mod:`pavonine.materials.display`: OCIO config,
display, view, exposure; the current one unless told otherwise, by default the pinned built-in CG
config, ``sRGB - Display``, ``Un-tone-mapped``), recorded as ``pavonine:ocio_config``,
``pavonine:display``, ``pavonine:view`` and ``pavonine:exposure`` so that readers can invert the
right transform. :func:`write_display_png` writes images that already are display-referred
(heat-maps).
Every file is written atomically (a temporary file renamed on success); :func:`write_renders`
writes a render's EXR, variance EXR and PNG under temporary names first and renames them as one
journalled group (:func:`pavonine.base.commit.commit_files`): EXR, then variance, then PNG.
All files of one call share a ``pavonine:render_id`` header attribute, and each file of one
image carries ``pavonine:group`` (the id and the image's other files), so a reader can tell
whether an EXR and a PNG come from the same render; Pavonine's readers check it
(:mod:`pavonine.base.groups`, docs/reliability.md).
"""

from __future__ import annotations

import contextlib
import json
import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pavonine.base.errors import InputError
from pavonine.base.image_files import write_image_file
from pavonine.materials.display import DisplayTransform, current_display

EXR_COLORSPACE = "lin_rec709_scene"
REC709_CHROMATICITIES = (0.64, 0.33, 0.30, 0.60, 0.15, 0.06, 0.3127, 0.3290)


def write_exr(
    path: str | os.PathLike,
    rgb: np.ndarray,
    metadata: Mapping[str, Any] | None = None,
    *,
    layers: Sequence[tuple[Sequence[str], np.ndarray]] | None = None,
) -> None:
    """Write H×W×3 scene-linear Rec.709 ``rgb`` as a float EXR with colour-space metadata.

    ``layers``: (channel names, H×W×C pixels) written instead of ``rgb``, in order — a multi-layer
    EXR (``R``, ``G``, ``B``, then e.g. ``albedo.R``, ``depth.Z``...).
    """
    import OpenImageIO as oiio

    if layers is None:
        layers = [(("R", "G", "B"), _check_rgb(rgb))]
    names = [name for channels, _ in layers for name in channels]
    planes = [np.asarray(pixels, dtype=np.float32) for _, pixels in layers]
    for (channels, _), plane in zip(layers, planes, strict=True):
        if (
            plane.ndim != 3
            or plane.shape[2] != len(channels)
            or plane.shape[:2] != planes[0].shape[:2]
        ):
            raise ValueError(f"layer {channels} has shape {plane.shape}")
    pixels = np.ascontiguousarray(np.concatenate(planes, axis=2))
    spec = oiio.ImageSpec(pixels.shape[1], pixels.shape[0], pixels.shape[2], oiio.FLOAT)
    spec.channelnames = tuple(names)
    spec.attribute("oiio:ColorSpace", EXR_COLORSPACE)
    spec.attribute("chromaticities", oiio.TypeDesc("float[8]"), REC709_CHROMATICITIES)
    spec.attribute("compression", "zip")
    spec.attribute("Software", "pavonine")
    for key, value in (metadata or {}).items():
        if isinstance(value, bool) or not isinstance(value, (int, float, str)):
            value = json.dumps(value, default=str)
        spec.attribute(f"pavonine:{key}", value)
    _write(path, pixels, spec)


def write_png(
    path: str | os.PathLike,
    rgb: np.ndarray,
    display: DisplayTransform | None = None,
    *,
    attributes: Mapping[str, str] | None = None,
) -> None:
    """Write scene-linear ``rgb`` as an 8-bit PNG through ``display`` (default: the current one);
    ``attributes``: further header attributes (``pavonine:render_id``)."""
    pixels = _check_rgb(rgb)
    transform = display or current_display()
    encoded = transform.encode(np.nan_to_num(pixels, nan=0.0, posinf=0.0, neginf=0.0))
    write_display_png(path, encoded, transform, attributes=attributes)


def write_display_png(
    path: str | os.PathLike,
    display: np.ndarray,
    transform: DisplayTransform | None = None,
    *,
    attributes: Mapping[str, str] | None = None,
) -> None:
    """Write a display-referred H×W×C image (C = 1, 3 or 4, values in [0, 1]) as an 8-bit PNG.

    ``transform``: the display transform the pixels were encoded with (recorded in the header);
    ``None`` for images that are not renders (heat-maps). ``attributes``: further header
    attributes.
    """
    import OpenImageIO as oiio

    pixels = np.asarray(display, dtype=np.float32)
    if pixels.ndim == 2:
        pixels = pixels[:, :, None]
    if pixels.ndim != 3 or pixels.shape[2] not in (1, 3, 4):
        raise ValueError(f"expected an H×W×1, ×3 or ×4 image, got shape {pixels.shape}")
    encoded = np.round(np.clip(np.nan_to_num(pixels), 0.0, 1.0) * 255.0).astype(np.uint8)
    spec = oiio.ImageSpec(pixels.shape[1], pixels.shape[0], pixels.shape[2], oiio.UINT8)
    spec.attribute("oiio:ColorSpace", "srgb_rec709_display")
    if transform is None:
        spec.attribute("Software", "pavonine")
    else:
        spec.attribute("Software", f"pavonine (OCIO view {transform.view!r})")
        for key, value in transform.attributes().items():
            spec.attribute(key, value)
    for key, value in (attributes or {}).items():
        spec.attribute(key, value)
    _write(path, np.ascontiguousarray(encoded), spec)


def png_display(attributes: Mapping[str, Any]) -> DisplayTransform | None:
    """The display transform a PNG written by :func:`write_png` records (``None`` if unknown)."""
    recorded = DisplayTransform.from_attributes(attributes)
    if recorded is not None:
        return recorded
    view = png_view(attributes)
    return None if view is None else DisplayTransform(view=view)


def png_view(attributes: Mapping[str, Any]) -> str | None:
    """The OCIO view a PNG written by :func:`write_png` was encoded with (``None`` if unknown)."""
    view = attributes.get("pavonine:view")
    if isinstance(view, str) and view:
        return view
    match = re.fullmatch(r"pavonine \(OCIO view '(.+)'\)", str(attributes.get("Software", "")))
    return match.group(1) if match else None


def write_render(
    exr_path: str | os.PathLike,
    rgb: np.ndarray,
    metadata: Mapping[str, Any] | None = None,
    *,
    png_path: str | os.PathLike | None = None,
    display: DisplayTransform | None = None,
    layers: Sequence[tuple[Sequence[str], np.ndarray]] | None = None,
) -> None:
    """Write a render's EXR and (optionally) its display PNG: both appear, or neither does."""
    write_renders([RenderFiles(exr_path, rgb, metadata, png_path, layers)], display)


@dataclass
class RenderFiles:
    """One image's files: its EXR (``layers``, else ``rgb``), optionally the beauty's display PNG
    and the beauty's per-pixel variance (an EXR of its own)."""

    exr_path: str | os.PathLike
    rgb: np.ndarray
    metadata: Mapping[str, Any] | None = None
    png_path: str | os.PathLike | None = None
    layers: Sequence[tuple[Sequence[str], np.ndarray]] | None = None
    variance_path: str | os.PathLike | None = None
    variance: np.ndarray | None = None


def write_renders(outputs: Sequence[RenderFiles], display: DisplayTransform | None = None) -> None:
    """Write several images' files: all of them appear, or none does. PNGs go through
    ``display`` (default: the current display transform).

    Every file is written complete under a hidden temporary name beside its target; then all
    are renamed as one journalled group (per image: EXR, variance, PNG; see
    :func:`pavonine.base.commit.commit_files`), after finishing what a crashed earlier run
    left in the same folders (:func:`pavonine.base.commit.recover`). Every file carries the
    same ``pavonine:render_id``.
    """
    from pavonine.base.commit import commit_files, recover, temporary_file
    from pavonine.base.groups import GROUP_ATTRIBUTE, group_marks, new_group_id

    render_id = new_group_id()
    for folder in {Path(os.path.abspath(p)).parent for out in outputs for p in _paths(out)}:
        recover(folder)
    with contextlib.ExitStack() as stack:
        moves: list[tuple[Path, Path]] = []
        for out in outputs:
            # One image's files: each names the others (base/groups.py).
            marks = group_marks(render_id, _paths(out))
            exr_tmp = stack.enter_context(temporary_file(out.exr_path))
            metadata = {**(out.metadata or {}), "render_id": render_id}
            write_exr(
                exr_tmp,
                out.rgb,
                {**metadata, "group": marks[Path(out.exr_path)]},
                layers=out.layers,
            )
            moves.append((exr_tmp, Path(out.exr_path)))
            if out.variance_path:
                var_tmp = stack.enter_context(temporary_file(out.variance_path))
                quantity = {"quantity": "variance of the mean (scene-linear units squared)"}
                write_exr(
                    var_tmp,
                    out.variance,
                    {**metadata, **quantity, "group": marks[Path(out.variance_path)]},
                )
                moves.append((var_tmp, Path(out.variance_path)))
            if out.png_path:
                png_tmp = stack.enter_context(temporary_file(out.png_path))
                attributes = {
                    "pavonine:render_id": render_id,
                    GROUP_ATTRIBUTE: marks[Path(out.png_path)],
                }
                write_png(png_tmp, out.rgb, display, attributes=attributes)
                moves.append((png_tmp, Path(out.png_path)))
        try:
            commit_files(moves)
        except OSError as exc:
            raise InputError(str(out.exr_path), f"cannot write: {exc.strerror or exc}") from None


def _paths(out: RenderFiles) -> list[str | os.PathLike]:
    return [p for p in (out.exr_path, out.png_path, out.variance_path) if p]


def read_exr(path: str | os.PathLike) -> tuple[np.ndarray, dict[str, Any]]:
    """Pixels (H×W×C float32) and header attributes of an image written by :func:`write_exr`."""
    import OpenImageIO as oiio

    from pavonine.base.limits import image_error, open_image

    with open_image(path) as image:  # a regular file within the pixel budget
        spec = image.spec()
        pixels = image.read_image(oiio.FLOAT)
        attributes = {a.name: a.value for a in spec.extra_attribs}
        error = image.geterror() if pixels is None else ""
    if pixels is None:
        raise InputError(os.fspath(path), f"cannot read image: {image_error(error)}")
    return np.asarray(pixels), attributes


def _check_rgb(rgb: np.ndarray) -> np.ndarray:
    pixels = np.ascontiguousarray(np.asarray(rgb, dtype=np.float32))
    if pixels.ndim != 3 or pixels.shape[2] != 3:
        raise ValueError(f"expected an H×W×3 image, got shape {pixels.shape}")
    return pixels


def _write(path: str | os.PathLike, pixels: np.ndarray, spec) -> None:
    write_image_file(path, pixels, spec)
