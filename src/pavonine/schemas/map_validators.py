"""Validator of the six maps a PavonineFeatherAPI material names: each exists (a file, or a
member of a ``.usdz`` package read through Ar), loads with OpenImageIO, is grey, has a sane size
within the pixel budget of :mod:`pavonine.base.limits`, and is read raw, by the schema and by the
``UsdUVTexture`` shaders that read it.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable

from pxr import Usd, UsdShade

from pavonine.base.native_output import captured
from pavonine.schemas import authoring
from pavonine.schemas.feather_api import (
    ERROR,
    WARN,
    has_feather_api,
    schema_value,
    typed_attr,
    validation_error,
)

#: Largest map side accepted (pixels); smallest side below which a map is suspicious.
MAX_MAP_SIZE = 16384
MIN_MAP_SIZE = 16


def _texture_shaders(material: Usd.Prim) -> Iterable[UsdShade.Shader]:
    for prim in Usd.PrimRange(material):
        shader = UsdShade.Shader(prim)
        if shader and shader.GetShaderId() == "UsdUVTexture":
            yield shader


def _pixel_problems(inp, path: str, colour: int) -> list[tuple[str, str, object]]:
    """[(severity, name, message)] of an open image's pixels, decoded as the pipeline reads
    them (:func:`pavonine.base.map_files.read_data_map`): unreadable (a truncated file),
    non-finite or out of [0, 1] values are errors; colour channels that differ warn."""
    import numpy as np

    from pavonine.base.limits import image_error
    from pavonine.base.map_files import grey_values, value_problem

    spec = inp.spec()
    pixels = inp.read_image(0, 0, 0, spec.nchannels, "float")
    if pixels is None:
        error = image_error(inp.geterror())
        return [(ERROR, "MapNotAnImage", f"OpenImageIO cannot read pixels of {path}: {error}")]
    problem = value_problem(grey_values(pixels, spec))
    if problem:
        return [(ERROR, "MapValues", f"{path}: {problem}")]
    if colour < 3:
        return []
    rgb = np.asarray(pixels).reshape(-1, spec.nchannels)[:, :3]
    spread = float(np.max(np.ptp(rgb, axis=1)))
    if spread <= 1.0 / 255.0:
        return []
    return [
        (
            WARN,
            "MapNotGrey",
            f"{path} has colour channels that differ (by up to {spread:.3f}); "
            "Pavonine reads its Rec. 709 luma",
        )
    ]


def _image_problems(path: str) -> tuple[list[tuple[str, str, object]], tuple[int, int] | None]:
    """[(severity, name, message)] for one image behind a resolved asset path (a file, or a
    member of a ``.usdz`` package read through Ar), and its (width, height)."""
    import OpenImageIO as oiio

    from pavonine.base.asset_io import local_file
    from pavonine.base.errors import InputError
    from pavonine.base.limits import check_image_spec, regular_file

    problems: list[tuple[str, str, object]] = []
    try:
        local = local_file(path)
    except OSError as exc:
        return [(ERROR, "MapMissing", f"cannot read {path}: {exc.strerror or exc}")], None
    try:
        regular_file(local, path)  # never open a FIFO or a device: it would block or not end
    except InputError as exc:
        return [(ERROR, "MapNotAnImage", str(exc))], None
    inp = oiio.ImageInput.open(local)
    if inp is None:
        message = oiio.geterror() or "unknown format"
        return [
            (ERROR, "MapNotAnImage", f"OpenImageIO cannot read {path}: {message.splitlines()[0]}")
        ], None
    try:
        spec = inp.spec()
        size = (spec.width, spec.height)
        if min(size) < 1 or max(size) > MAX_MAP_SIZE:
            problems.append(
                (
                    ERROR,
                    "MapSize",
                    f"{path} is {size[0]}x{size[1]}; sides must be 1..{MAX_MAP_SIZE}",
                )
            )
        elif min(size) < MIN_MAP_SIZE:
            problems.append((WARN, "MapSize", f"{path} is only {size[0]}x{size[1]} pixels"))
        if (
            not problems
        ):  # within the sides, the pixel budget (pavonine.base.limits) may still be lower
            try:
                check_image_spec(path, spec)
            except InputError as exc:
                problems.append((ERROR, "MapSize", str(exc)))
        colour = spec.nchannels - (1 if spec.alpha_channel >= 0 else 0)
        if spec.nchannels > 4:
            problems.append(
                (
                    ERROR,
                    "MapChannels",
                    f"{path} has {spec.nchannels} channels; expected 1 (grey) to 4",
                )
            )
        elif not any(p[0] == ERROR for p in problems):  # never decode a refused map
            problems += _pixel_problems(inp, path, colour)
    finally:
        inp.close()
    return problems, size


def _odd_sizes(prim: Usd.Prim, sizes: dict[str, tuple[int, int]], files: dict[str, str]) -> list:
    """A warning on each map (``sizes`` and ``files`` by attribute) whose size differs from the
    common one: the size most maps share, the alpha map's on a tie (convert measures the others
    against it)."""
    counts = Counter(sizes.values())
    if len(counts) < 2:
        return []
    alpha = sizes.get(authoring.MAP_ATTRS["alpha"])
    common = max(counts, key=lambda size: (counts[size], size == alpha))
    alike = ", ".join(n.split(":")[1] for n, size in sizes.items() if size == common)
    verb = "is" if counts[common] == 1 else "are"
    return [
        validation_error(
            prim,
            "MapSizesDiffer",
            f"maps differ in size: {files[name]} is {w}x{h}, while {alike} {verb} "
            f"{common[0]}x{common[1]}",
            name,
            WARN,
        )
        for name, (w, h) in sizes.items()
        if (w, h) != common
    ]


def feather_maps(prim: Usd.Prim, time_range=None) -> list:
    """Maps exist, load with OpenImageIO, are grey (or convertible), have sane sizes, read raw."""
    if prim.IsPseudoRoot() or not has_feather_api(prim):
        return []
    errors = []
    sizes: dict[str, tuple[int, int]] = {}
    files: dict[str, str] = {}
    for name in authoring.MAP_ATTRS.values():
        attr = typed_attr(prim, name)  # a wrongly typed map is reported by feather_parameters
        value = attr.Get() if attr else None
        if value is None or not value.path:
            continue
        space = attr.GetColorSpace() if attr.HasColorSpace() else "raw"
        if space != "raw":
            errors.append(
                validation_error(
                    prim,
                    "MapColorSpace",
                    f"data map must be read raw, colorSpace is {space!r}",
                    name,
                )
            )
        if not value.resolvedPath:
            where = authoring.anchored_path(attr, value.path)
            errors.append(
                validation_error(
                    prim, "MapMissing", f"@{value.path}@ does not exist (looked for {where})", name
                )
            )
            continue
        with captured(2):  # libpng's own lines: the finding says what it says
            problems, size = _image_problems(value.resolvedPath)
        for severity, err_name, message in problems:
            errors.append(validation_error(prim, err_name, message, name, severity))
        if size is not None:
            sizes[name], files[name] = size, value.resolvedPath
    errors += _odd_sizes(prim, sizes, files)
    maps = {
        v.resolvedPath
        for v in (schema_value(prim, n) for n in authoring.MAP_ATTRS.values())
        if v and v.resolvedPath
    }
    for shader in _texture_shaders(prim):
        file_value = shader.GetInput("file").Get() if shader.GetInput("file") else None
        if file_value is None or file_value.resolvedPath not in maps:
            continue
        source = shader.GetInput("sourceColorSpace")
        space = source.Get() if source else None
        if space != "raw":
            errors.append(
                validation_error(
                    shader.GetPrim(),
                    "MapColorSpace",
                    f"reads data map {file_value.path} with sourceColorSpace {space!r}; must be 'raw'",
                    "inputs:sourceColorSpace",
                )
            )
    return errors
