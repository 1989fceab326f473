"""Feather recipes: a TOML file naming the six maps, the material and the geometry options.

The smallest recipe is a name, the six maps and a preset; every other key has a default
(``docs/pipeline.md`` lists them all). Unknown keys and bad values are errors that name the
recipe file and the dotted key (``InputError``), so a typo never silently falls back to a
default.
"""

from __future__ import annotations

import errno
import math
import os
import re
import tomllib
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from pavonine.base.errors import InputError
from pavonine.base.limits import name_too_long, read_small_file
from pavonine.materials.dispersion import Dispersion
from pavonine.materials.parameters import (
    AXES,
    FLOAT32_MAX,
    FREYER_2020_REGIONS,
    MAX_LAYER_COUNT,
    STACK_QUANTITIES,
    FeatherParameters,
    LayerStack,
    OcellarClass,
    ParameterError,
    freyer_class,
    preset,
)
from pavonine.pipeline.convert.barb_form import FORM_RANGES, FormOptions
from pavonine.pipeline.maps.paint import MAP_NAMES

#: A USD identifier; always used with ``fullmatch`` (``$`` would accept a trailing newline).
_NAME_RE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


@dataclass(frozen=True)
class LodTargets:
    """Target triangle counts (vane + rachis) of the three levels of detail."""

    high: int = 100_000
    medium: int = 25_000
    low: int = 5_000


@dataclass(frozen=True)
class BarbOptions:
    """The barbs as ribbons (``[geometry.barbs]``; :mod:`pavonine.pipeline.convert.barb_curves`);
    lengths in centimetres."""

    enabled: bool = True  # write the ``geometry = barbs`` variant
    spacing_cm: float = 0.225  # between barbs along the rachis, on each side
    tip_barbs: int = 240  # barbs radiating from the rachis tip, per full turn (0: none)
    segment_cm: float = 0.2  # ribbon vertex spacing along a barb
    width_share: float = 1.0  # ribbon width as a share of the local spacing between barbs


@dataclass(frozen=True)
class GeometryOptions:
    """Geometry options of a recipe (``[geometry]``); lengths in centimetres."""

    length_cm: float = (
        30.0  # length of the mapped area (the maps' height); width follows the aspect
    )
    rachis_length: float = 0.9  # fraction of the mapped length the rachis runs up the vane
    calamus_cm: float = 2.0  # bare shaft (quill) below the vane
    rachis_radius_cm: float = 0.12  # at the base; tapers toward the tip
    rachis_tip_radius_cm: float = 0.025
    bend_cm: float = 1.5  # sagitta of the feather's curve along its length (toward -z)
    cup_cm: float = 0.4  # how far the vane edges curl back across the width (toward -z)
    displacement_cm: float = 0.05  # height of the barb streaks at displacement 1
    alpha_threshold: float = 0.25  # alpha (box-filtered to the mesh pitch) where the vane is cut
    base_triangles: int = 6_000  # coarse mesh atlased by xatlas before refinement
    lod: LodTargets = field(default_factory=LodTargets)
    barbs: BarbOptions = field(default_factory=BarbOptions)
    form: FormOptions = field(default_factory=FormOptions)


#: Bake resolutions a recipe may ask for (texels along each side of the square atlas).
BAKE_RESOLUTION_RANGE = (16, 8192)


@dataclass(frozen=True)
class BakeOptions:
    """Baking options of a recipe (``[bake]``)."""

    resolution: int = 1024  # texels along each side of the baked textures


@dataclass(frozen=True)
class Recipe:
    """A parsed, checked feather recipe. Map paths are absolute."""

    path: Path
    name: str
    maps: dict[str, Path]
    material: FeatherParameters
    geometry: GeometryOptions
    version: str = "1.0"
    preset_name: str = "paper-table1"
    bake: BakeOptions = field(default_factory=BakeOptions)

    @property
    def label(self) -> str:
        return str(self.path)


_MATERIAL_SCALARS = {
    "melanin_index": float,
    "medium_index": float,
    "crescent_sigma_deg": float,
    "block_sigma_deg": float,
    "rod_length_um": float,
    "interference": str,
    "lattice": str,
    "melanin_color": list,
    "glitter": float,
    "glitter_seed": int,
    "block_length_um": float,
    "barbule_width_um": float,
}
#: Dispersive materials of the physical mode: recipe key -> (field, Dispersion parts), [a, b] each.
_DISPERSION_KEYS = {
    "melanin_dispersion": ("melanin", ("cauchy_a", "cauchy_b")),
    "melanin_absorption": ("melanin", ("extinction", "extinction_scale")),
    "keratin_dispersion": ("keratin", ("cauchy_a", "cauchy_b")),
}
_STACK_KEYS = {q: q for q in STACK_QUANTITIES}


def _fail(path: Path, key: str, message: str) -> InputError:
    return InputError(f"{path}: {key}", message)


def _check_keys(path: Path, table: dict, allowed: set[str], prefix: str) -> None:
    for key in table:
        if key not in allowed:
            dotted = f"{prefix}{key}"
            raise _fail(path, dotted, f"unknown key (allowed here: {', '.join(sorted(allowed))})")


def _number(path: Path, key: str, value: Any, *, positive: bool = True, integer=False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise _fail(path, key, f"expected a number, got {value!r}")
    if integer and not isinstance(value, int):
        raise _fail(path, key, f"expected an integer, got {value!r}")
    if math.isnan(value) or math.isinf(value):
        raise _fail(path, key, f"must be finite, got {value}")
    if positive and value <= 0:
        raise _fail(path, key, f"must be positive, got {value}")
    if not positive and value < 0:
        raise _fail(path, key, f"must not be negative, got {value}")
    if abs(value) > FLOAT32_MAX:  # stored as USD floats: float32 would make it inf
        raise _fail(path, key, f"must be within ±{FLOAT32_MAX:.4g} (a 32-bit float), got {value:g}")
    return value


#: Range of ``geometry.length_cm``: below it xatlas loses float32 precision and fails; above it
#: (10 m) the displacement streaks drown in float32 rounding of the positions.
LENGTH_RANGE_CM = (0.1, 1000.0)
#: Upper bounds of the other lengths as a multiple of ``length_cm``. The base surface of
#: ``surface.FeatherFrame`` (bend and cup sagittas, calamus below the vane) degenerates into a
#: sliver that the atlas stage segfaults or hangs on far beyond them (``bend_cm``, ``cup_cm`` or
#: ``calamus_cm = 1e6``); a feather whose shaft or barb streaks are a tenth of its length is
#: already no feather.
LENGTH_SHARES = {
    "bend_cm": 1.0,
    "cup_cm": 1.0,
    "calamus_cm": 1.0,
    "rachis_radius_cm": 0.1,
    "displacement_cm": 0.1,
}
#: Most triangles a level of detail may ask for: four times the benchmark's 1 M-triangle high LOD
#: (``benchmarks/bench_convert.py``); more would run for minutes and exhaust memory.
MAX_LOD_TRIANGLES = 4_000_000


def _parse_geometry(path: Path, table: dict) -> GeometryOptions:
    defaults = GeometryOptions()
    allowed = {f.name for f in fields(GeometryOptions)}
    _check_keys(path, table, allowed, "geometry.")
    values: dict[str, Any] = {}
    for f in fields(GeometryOptions):
        if f.name not in table:
            continue
        key = f"geometry.{f.name}"
        raw = table[f.name]
        if f.name == "lod":
            if not isinstance(raw, dict):
                raise _fail(path, key, "expected a table [geometry.lod]")
            _check_keys(path, raw, {"high", "medium", "low"}, "geometry.lod.")
            lod = {k: int(_number(path, f"{key}.{k}", v, integer=True)) for k, v in raw.items()}
            for k, v in lod.items():
                if v > MAX_LOD_TRIANGLES:
                    raise _fail(
                        path,
                        f"{key}.{k}",
                        f"must be at most {MAX_LOD_TRIANGLES:,} triangles, got {v:,}",
                    )
            targets = LodTargets(**lod)
            if not targets.high >= targets.medium >= targets.low >= 100:
                raise _fail(
                    path,
                    key,
                    "need high >= medium >= low >= 100 triangles, got "
                    f"high = {targets.high}, medium = {targets.medium}, low = {targets.low}",
                )
            values["lod"] = targets
        elif f.name == "barbs":
            continue  # checked against the final length_cm below
        elif f.name == "form":
            values["form"] = _parse_form(path, raw)
        elif f.name == "base_triangles":
            values[f.name] = int(_number(path, key, raw, integer=True))
            if not 200 <= values[f.name] <= 60_000:
                raise _fail(path, key, f"must lie in [200, 60000], got {raw}")
        elif f.name in ("bend_cm", "cup_cm", "displacement_cm", "calamus_cm"):
            values[f.name] = float(_number(path, key, raw, positive=False))
        else:
            values[f.name] = float(_number(path, key, raw))
    options = GeometryOptions(
        **{**{f.name: getattr(defaults, f.name) for f in fields(defaults)}, **values}
    )
    low, high = LENGTH_RANGE_CM
    if not low <= options.length_cm <= high:
        raise _fail(
            path,
            "geometry.length_cm",
            f"must lie in [{low:g}, {high:g}] cm, got {options.length_cm:g}",
        )
    for name, share in LENGTH_SHARES.items():
        value = getattr(options, name)
        bound = share * options.length_cm
        if value > bound:
            limit = "length_cm" if share == 1.0 else f"{share:g} x length_cm"
            default = "" if name in table else " (the default; set it in [geometry])"
            raise _fail(
                path,
                f"geometry.{name}",
                f"must be at most {limit} = {bound:g} cm, got {value:g}{default}",
            )
    if not 0.0 < options.rachis_length <= 1.0:
        raise _fail(
            path, "geometry.rachis_length", f"must lie in (0, 1], got {options.rachis_length}"
        )
    if not 0.0 < options.alpha_threshold < 1.0:
        raise _fail(
            path, "geometry.alpha_threshold", f"must lie in (0, 1), got {options.alpha_threshold}"
        )
    if options.rachis_tip_radius_cm > options.rachis_radius_cm:
        raise _fail(path, "geometry.rachis_tip_radius_cm", "must not exceed rachis_radius_cm")
    if "barbs" in table:
        options = replace(options, barbs=_parse_barbs(path, table["barbs"], options))
    return options


#: Finest barb spacing and ribbon segment, as a share of ``length_cm`` (a 30 cm feather: 0.15 mm
#: and 0.3 mm), and most barbs radiating from the tip: they bound the barbs' vertex count.
MIN_BARB_SPACING_SHARE = 1.0 / 2000.0
MIN_SEGMENT_SHARE = 1.0 / 1000.0
MAX_TIP_BARBS = 4000


def _switchable_table(path: Path, raw: Any, key: str, options: type) -> dict[str, Any]:
    """A sub-table ``[key]`` of the dataclass ``options``' keys checked, with its ``enabled``
    switch read; the values read so far (the caller reads the rest)."""
    if not isinstance(raw, dict):
        raise _fail(path, key, f"expected a table [{key}]")
    _check_keys(path, raw, {f.name for f in fields(options)}, f"{key}.")
    values: dict[str, Any] = {}
    if "enabled" in raw:
        if not isinstance(raw["enabled"], bool):
            raise _fail(path, f"{key}.enabled", f"expected true or false, got {raw['enabled']!r}")
        values["enabled"] = raw["enabled"]
    return values


def _parse_barbs(path: Path, raw: Any, geometry: GeometryOptions) -> BarbOptions:
    """``[geometry.barbs]``: every key checked, lengths against the feather's ``length_cm``."""
    key = "geometry.barbs"
    values = _switchable_table(path, raw, key, BarbOptions)
    if "tip_barbs" in raw:
        count = int(
            _number(path, f"{key}.tip_barbs", raw["tip_barbs"], positive=False, integer=True)
        )
        if count != 0 and not 4 <= count <= MAX_TIP_BARBS:
            raise _fail(
                path,
                f"{key}.tip_barbs",
                f"must be 0 (no barbs radiate from the tip) or lie in [4, {MAX_TIP_BARBS}], "
                f"got {count}",
            )
        values["tip_barbs"] = count
    length = geometry.length_cm
    for name, low in (
        ("spacing_cm", MIN_BARB_SPACING_SHARE * length),
        ("segment_cm", MIN_SEGMENT_SHARE * length),
    ):
        if name in raw:
            value = float(_number(path, f"{key}.{name}", raw[name]))
            high = 0.1 * length
            if not low <= value <= high:
                raise _fail(
                    path,
                    f"{key}.{name}",
                    f"must lie in [{low:g}, {high:g}] cm for length_cm = {length:g}, got {value:g}",
                )
            values[name] = value
    if "width_share" in raw:
        share = float(_number(path, f"{key}.width_share", raw["width_share"]))
        if share > 2.0:
            raise _fail(path, f"{key}.width_share", f"must lie in (0, 2], got {share:g}")
        values["width_share"] = share
    return BarbOptions(**values)


def _parse_form(path: Path, raw: Any) -> FormOptions:
    """``[geometry.form]``: every key checked (ranges in :data:`barb_form.FORM_RANGES`)."""
    key = "geometry.form"
    values = _switchable_table(path, raw, key, FormOptions)
    if "seed" in raw:
        seed = int(_number(path, f"{key}.seed", raw["seed"], positive=False, integer=True))
        if seed > 0x7FFFFFFF:
            raise _fail(path, f"{key}.seed", f"must lie in [0, 2147483647], got {seed}")
        values["seed"] = seed
    for name, (low, high) in FORM_RANGES.items():
        if name in raw:
            value = float(_number(path, f"{key}.{name}", raw[name], positive=False))
            if not low <= value <= high:
                raise _fail(
                    path, f"{key}.{name}", f"must lie in [{low:g}, {high:g}], got {value:g}"
                )
            values[name] = value
    return FormOptions(**values)


def _check_count(path: Path, key: str, value: float) -> None:
    """Layer counts are whole numbers (the asset stores them as USD ``int2``)."""
    if not float(value).is_integer():
        raise _fail(path, key, f"a layer count must be a whole number, got {value!r}")
    if value > MAX_LAYER_COUNT:
        raise _fail(path, key, f"must be at most {MAX_LAYER_COUNT} layers, got {value:g}")


def _stack_end(value: Any, end: int) -> Any:
    """A cell's value at the black (``end`` 0) or white (1) end: a number or a one-item list is
    the same at both ends, a pair is [black, white]."""
    return value[min(end, len(value) - 1)] if isinstance(value, list) else value


def _parse_classes(path: Path, params: FeatherParameters, table: dict) -> FeatherParameters:
    """``[material.class.<k>]`` tables: ``region`` takes a Freyer & Stavenga 2020 region with the
    freyer2020 gradation rule, then ``cortex`` and ``<axis>`` cells override single cells: a
    value or [black, white]."""
    classes = list(params.classes)
    for index_key, axes in table.items():
        prefix = f"material.class.{index_key}"
        if not index_key.isdigit() or int(index_key) >= len(classes):
            raise _fail(
                path, prefix, f"unknown class; the preset has classes 0..{len(classes) - 1}"
            )
        if not isinstance(axes, dict):
            raise _fail(path, prefix, "expected a table with 'long' and/or 'short'")
        _check_keys(path, axes, {*AXES, "cortex", "region"}, f"{prefix}.")
        k = int(index_key)
        if "region" in axes:
            region = axes["region"]
            if not isinstance(region, str) or region not in FREYER_2020_REGIONS:
                raise _fail(
                    path,
                    f"{prefix}.region",
                    f"unknown region {region!r}; known: {', '.join(sorted(FREYER_2020_REGIONS))}",
                )
            classes[k] = freyer_class(region)
        per_axis = {axis: getattr(classes[k], axis) for axis in AXES}
        cortex = classes[k].cortex
        if "cortex" in axes:
            value = axes["cortex"]
            items = value if isinstance(value, list) else [value]
            if len(items) not in (1, 2):
                raise _fail(path, f"{prefix}.cortex", "expected a number or [black, white]")
            for item in items:
                _number(path, f"{prefix}.cortex", item, positive=False)
            cortex = tuple(float(_stack_end(value, end)) for end in (0, 1))
        for axis, cells in ((a, c) for a, c in axes.items() if a in AXES):
            if not isinstance(cells, dict):
                raise _fail(path, f"{prefix}.{axis}", "expected a table of interval/radius/count")
            _check_keys(path, cells, set(_STACK_KEYS), f"{prefix}.{axis}.")
            for qty, value in cells.items():
                key = f"{prefix}.{axis}.{qty}"
                items = value if isinstance(value, list) else [value]
                if len(items) not in (1, 2):
                    raise _fail(path, key, "expected a number or [black, white]")
                for item in items:
                    _number(path, key, item, positive=qty not in ("spacing", "channel"))
                    if qty == "count":
                        _check_count(path, key, item)
            ends = []
            for end in (0, 1):
                old = per_axis[axis][end]
                ends.append(
                    LayerStack(
                        *(
                            float(_stack_end(cells.get(q, getattr(old, q)), end))
                            for q in STACK_QUANTITIES
                        )
                    )
                )
            per_axis[axis] = tuple(ends)
        classes[k] = OcellarClass(**per_axis, cortex=cortex)
    return params.with_(classes=tuple(classes))


_FIELD_RE = re.compile(r"^class\[(\d+)\]\.(long|short)\.(black|white)\.(\w+)$")


def parameter_key(field_name: str) -> str:
    """The recipe key of a :class:`ParameterError` field (``class[2].long.white.radius`` →
    ``material.class.2.long.radius (white end)``)."""
    match = _FIELD_RE.match(field_name)
    if match:
        k, axis, end, qty = match.groups()
        return f"material.class.{k}.{axis}.{qty} ({end} end)"
    return f"material.{field_name}"


def _parse_material(path: Path, table: dict) -> tuple[FeatherParameters, str]:
    allowed = {"preset", "class", *_MATERIAL_SCALARS, *_DISPERSION_KEYS}
    _check_keys(path, table, allowed, "material.")
    name = table.get("preset", "paper-table1")
    if not isinstance(name, str):
        raise _fail(path, "material.preset", f"expected a preset name, got {name!r}")
    try:
        params = preset(name)
    except ParameterError as exc:
        raise _fail(path, "material.preset", exc.reason) from None
    changes: dict[str, Any] = {}
    for key, kind in _MATERIAL_SCALARS.items():
        if key not in table:
            continue
        value = table[key]
        dotted = f"material.{key}"
        if kind is float:
            changes[key] = float(_number(path, dotted, value, positive=False))
        elif kind is int:
            changes[key] = int(_number(path, dotted, value, positive=False, integer=True))
        elif kind is str:
            if not isinstance(value, str):
                raise _fail(path, dotted, f"expected a string, got {value!r}")
            changes[key] = value
        else:
            if not (isinstance(value, list) and len(value) == 3):
                raise _fail(path, dotted, "expected [r, g, b] (linear sRGB)")
            changes[key] = tuple(float(_number(path, dotted, c, positive=False)) for c in value)
    for key, (field_name, parts) in _DISPERSION_KEYS.items():
        if key not in table:
            continue
        value = table[key]
        dotted = f"material.{key}"
        if not (isinstance(value, list) and len(value) == 2):
            raise _fail(path, dotted, f"expected [{parts[0]}, {parts[1]}]")
        current = changes.get(field_name, getattr(params, field_name))
        numbers = [float(_number(path, dotted, v, positive=False)) for v in value]
        changes[field_name] = Dispersion(
            **{**vars(current), **dict(zip(parts, numbers, strict=True))}
        )
    params = params.with_(**changes)
    if "class" in table:
        if not isinstance(table["class"], dict):
            raise _fail(path, "material.class", "expected tables [material.class.<k>.<axis>]")
        params = _parse_classes(path, params, table["class"])
    try:
        params.validate()
    except ParameterError as exc:
        raise _fail(path, parameter_key(exc.field), exc.reason) from None
    return params, name


def read_toml(path: str | os.PathLike) -> tuple[Path, dict]:
    """A recipe file's absolute path and its TOML tables; :class:`InputError` if unreadable.

    Only a regular file of at most :data:`pavonine.base.limits.MAX_RECIPE_BYTES` is read (a FIFO,
    ``/dev/zero`` or a symlink loop is refused before it is opened); it must be UTF-8 TOML.
    """
    where = str(path)
    try:
        path = Path(path).absolute()
        where = str(path)
        data = read_small_file(path, where, missing="recipe not found")
        path = path.resolve()
    except (OSError, RuntimeError) as exc:  # Python 3.11's resolve() raises RuntimeError on loops
        raise InputError(where, f"cannot resolve ({exc})") from None
    try:
        text = data.decode("utf-8-sig")  # a leading byte-order mark (Windows editors) is dropped
    except UnicodeDecodeError as exc:
        raise InputError(
            str(path), f"not UTF-8 text (byte {exc.start}); recipes are UTF-8 TOML"
        ) from None
    try:
        return path, tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(str(path), f"not valid TOML ({exc})") from None
    except RecursionError:
        raise InputError(str(path), "not valid TOML (arrays or tables nested too deeply)") from None


def resolve_relative(path: Path, key: str, value: str) -> Path:
    """``value`` (a path in the recipe at ``path``) made absolute, symbolic links resolved; a
    symbolic link loop or an unusable path is an :class:`InputError` naming the key."""
    try:
        return (path.parent / value).resolve()
    except (OSError, RuntimeError, ValueError) as exc:  # 3.11 raises RuntimeError on a loop
        loop = isinstance(exc, RuntimeError) or getattr(exc, "errno", None) == errno.ELOOP
        reason = "symbolic link loop" if loop else f"unusable path ({exc})"
        raise _fail(path, key, f"{value}: {reason}") from None


def name_and_version(path: Path, data: dict, example: str) -> tuple[str, str]:
    """A recipe's ``name`` (a USD identifier) and ``version`` (default ``"1.0"``), checked."""
    if "name" not in data:
        raise _fail(path, "name", f'missing (the asset\'s name, e.g. name = "{example}")')
    name = data["name"]
    if not isinstance(name, str) or not _NAME_RE.fullmatch(name):
        raise _fail(
            path, "name", f"must be a USD identifier ([A-Za-z_][A-Za-z0-9_]*), got {name!r}"
        )
    too_long = name_too_long(name, path.parent)  # the output is checked again (convert)
    if too_long:
        raise _fail(path, "name", too_long)
    version = data.get("version", "1.0")
    if not isinstance(version, str):
        raise _fail(path, "version", f"expected a string, got {version!r}")
    return name, version


def parse_recipe(path: str | os.PathLike) -> Recipe:
    """Read and check a recipe; raises :class:`InputError` naming the file and key."""
    path, data = read_toml(path)
    _check_keys(path, data, {"name", "version", "maps", "material", "geometry", "bake"}, "")
    name, version = name_and_version(path, data, "eye_feather")
    maps_table = data.get("maps")
    if not isinstance(maps_table, dict):
        raise _fail(path, "maps", "missing table [maps] naming the six maps")
    _check_keys(path, maps_table, set(MAP_NAMES), "maps.")
    maps: dict[str, Path] = {}
    for map_name in MAP_NAMES:
        if map_name not in maps_table:
            raise _fail(path, f"maps.{map_name}", "missing")
        value = maps_table[map_name]
        if not isinstance(value, str) or not value:
            raise _fail(path, f"maps.{map_name}", f"expected a file path, got {value!r}")
        maps[map_name] = resolve_relative(path, f"maps.{map_name}", value)
    material_table = data.get("material", {})
    if not isinstance(material_table, dict):
        raise _fail(path, "material", "expected a table [material]")
    params, preset_name = _parse_material(path, material_table)
    if "glitter_seed" not in material_table:
        params = params.with_(glitter_seed=asset_seed(name))
    geometry_table = data.get("geometry", {})
    if not isinstance(geometry_table, dict):
        raise _fail(path, "geometry", "expected a table [geometry]")
    geometry = _parse_geometry(path, geometry_table)
    return Recipe(path, name, maps, params, geometry, version, preset_name, _parse_bake(path, data))


def asset_seed(name: str) -> int:
    """The glitter seed of an asset whose recipe names none: CRC-32 of its name (31 bits), so
    that two assets do not sparkle alike and one asset always sparkles the same."""
    import zlib

    return zlib.crc32(name.encode("utf-8")) & 0x7FFFFFFF


def _parse_bake(path: Path, data: dict) -> BakeOptions:
    table = data.get("bake", {})
    if not isinstance(table, dict):
        raise _fail(path, "bake", "expected a table [bake]")
    _check_keys(path, table, {"resolution"}, "bake.")
    if "resolution" not in table:
        return BakeOptions()
    value = int(_number(path, "bake.resolution", table["resolution"], integer=True))
    low, high = BAKE_RESOLUTION_RANGE
    if not low <= value <= high:
        raise _fail(path, "bake.resolution", f"must lie in [{low}, {high}] texels, got {value}")
    return BakeOptions(value)
