"""Train recipes: a TOML file naming the feather components and the rows of the displaying fan.

Every key is checked; an unknown key or a bad value is an :class:`InputError` naming the recipe
and the dotted key (``rows.2.count``), as feather recipes are (``docs/pipeline.md``).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from pavonine.base.limits import SEED_RANGE
from pavonine.pipeline.assemble.rattle_recipe import Rattle, parse_rattle
from pavonine.pipeline.convert.recipe import (
    _NAME_RE,
    _check_keys,
    _fail,
    _number,
    name_and_version,
    read_toml,
    resolve_relative,
)

LODS = ("high", "medium", "low")
#: The components' ``geometry`` variants a row may choose (docs/pipeline.md, "Barbs").
GEOMETRIES = ("sheet", "barbs")
#: Most feathers one train may hold (a real train has about 200; this is 10× that).
MAX_FEATHERS = 2_000
#: Bounds of the per-instance variation: the gradation offset moves the stacks along Table 1
#: between a class's black and white ends (t is clipped to [0, 1] by the BSDF); the structural
#: scale multiplies the structural share (a worn feather is browner, never more than fully iridescent).
MAX_GRADATION_OFFSET = 0.5
STRUCTURAL_SCALE_RANGE = (0.5, 1.0)
#: Bounds of a row's ``bend`` (× the component's depth): never flat (a train feather is curved,
#: docs/pipeline.md "Train recipe"), at most 8× (a 2 cm bend of a 30 cm feather becomes 16 cm).
BEND_RANGE = (0.25, 8.0)


@dataclass(frozen=True)
class Row:
    """One row of the fan: ``count`` feathers of ``component`` radiating from the centre."""

    component: str
    count: int
    radius_cm: float  # the feathers' bases sit on a circle of this radius around the centre
    length: float = 1.0  # scale of the component (1 = as converted)
    span_deg: float = 200.0  # the row spans ±span/2 from straight up
    dish_deg: float = 0.0  # tipped toward the viewer (+Z) by this much: the fan's dish
    depth_cm: float = 0.0  # offset toward the viewer (+Z): inner rows in front
    edge: str | None = None  # component of the row's outermost feathers (fishtails)
    edge_count: int = 0  # that many at each end
    stagger: float = 0.0  # shift by this fraction of a step (eyes of a row between the last's)
    geometry: str = "sheet"  # the components' geometry variant: "sheet" or "barbs"
    bend: float = 1.0  # × the component's depth: the sagitta of its rachis bend and vane cup
    edge_bend: float | None = None  # the same for the edge feathers (default: ``bend``)
    edge_droop_deg: float = 0.0  # the edge feathers turned this much further down, outward


@dataclass(frozen=True)
class Jitter:
    """Per-feather jitter, drawn uniformly in ±value from the recipe's seed."""

    length: float = 0.06  # relative length
    curvature: float = 0.3  # relative bend: scales the feather's depth (its bend and cup)
    rotation_deg: float = 2.0  # in the fan's plane
    twist_deg: float = 6.0  # about the feather's own axis
    tilt_deg: float = 3.0  # toward/away from the viewer


@dataclass(frozen=True)
class Variation:
    """Per-instance look, drawn uniformly from the recipe's seed (see ``render/instance_primvars``)."""

    gradation_offset: float = 0.15  # ± added to the gradation map
    structural_scale: tuple[float, float] = (0.85, 1.0)  # range multiplying the structural share


@dataclass(frozen=True)
class TrainRecipe:
    """A parsed, checked train recipe. Component paths are absolute."""

    path: Path
    name: str
    components: dict[str, Path]
    rows: tuple[Row, ...]
    seed: int = 0
    lod: str = "medium"
    version: str = "1.0"
    jitter: Jitter = field(default_factory=Jitter)
    variation: Variation = field(default_factory=Variation)
    rattle: Rattle | None = None  # [rattle]: the train animated (pipeline/assemble/rattle.py)

    @property
    def feather_count(self) -> int:
        return sum(row.count for row in self.rows)


_ROW_NUMBERS = {
    "radius_cm": (0.0, 1000.0),
    "length": (0.05, 20.0),
    "span_deg": (0.0, 360.0),
    "dish_deg": (-80.0, 80.0),
    "depth_cm": (-1000.0, 1000.0),
    "stagger": (0.0, 1.0),
    "bend": BEND_RANGE,
    "edge_bend": BEND_RANGE,
    "edge_droop_deg": (0.0, 60.0),
}
_JITTER_BOUNDS = {
    "length": 0.5,
    "curvature": 0.9,
    "rotation_deg": 45.0,
    "twist_deg": 45.0,
    "tilt_deg": 45.0,
}


def _in_range(path: Path, key: str, value: Any, low: float, high: float) -> float:
    number = float(
        _number(path, key, value, positive=False) if low >= 0 else _finite(path, key, value)
    )
    if not low <= number <= high:
        raise _fail(path, key, f"must lie in [{low:g}, {high:g}], got {number:g}")
    return number


def _finite(path: Path, key: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise _fail(path, key, f"expected a finite number, got {value!r}")
    return float(value)


def _parse_row(path: Path, index: int, table: Any, components: dict[str, Path]) -> Row:
    prefix = f"rows.{index}"
    if not isinstance(table, dict):
        raise _fail(path, prefix, "expected a table [[rows]]")
    _check_keys(path, table, {f.name for f in fields(Row)}, f"{prefix}.")
    values: dict[str, Any] = {}
    for key in ("component", "edge"):
        if key in table:
            name = table[key]
            if not isinstance(name, str) or name not in components:
                known = ", ".join(sorted(components))
                raise _fail(path, f"{prefix}.{key}", f"unknown component {name!r} (known: {known})")
            values[key] = name
    if "component" not in values:
        raise _fail(path, f"{prefix}.component", "missing (a name from [components])")
    for key in ("count", "edge_count"):
        if key in table:
            values[key] = int(
                _number(path, f"{prefix}.{key}", table[key], positive=key == "count", integer=True)
            )
    if "count" not in values:
        raise _fail(path, f"{prefix}.count", "missing (feathers in this row)")
    for key, (low, high) in _ROW_NUMBERS.items():
        if key in table:
            values[key] = _in_range(path, f"{prefix}.{key}", table[key], low, high)
    if "radius_cm" not in values:
        raise _fail(path, f"{prefix}.radius_cm", "missing (radius of the feathers' bases)")
    if "geometry" in table:
        if table["geometry"] not in GEOMETRIES:
            raise _fail(
                path,
                f"{prefix}.geometry",
                f"expected one of {', '.join(GEOMETRIES)}, got {table['geometry']!r}",
            )
        values["geometry"] = table["geometry"]
    row = Row(**values)
    if 2 * row.edge_count > row.count:
        raise _fail(
            path, f"{prefix}.edge_count", f"{row.edge_count} at each end exceeds count {row.count}"
        )
    if row.edge_count and row.edge is None:
        raise _fail(path, f"{prefix}.edge", "missing (the component of the edge feathers)")
    return row


def _parse_jitter(path: Path, table: Any) -> Jitter:
    if not isinstance(table, dict):
        raise _fail(path, "jitter", "expected a table [jitter]")
    _check_keys(path, table, set(_JITTER_BOUNDS), "jitter.")
    return Jitter(
        **{k: _in_range(path, f"jitter.{k}", v, 0.0, _JITTER_BOUNDS[k]) for k, v in table.items()}
    )


def _parse_variation(path: Path, table: Any) -> Variation:
    if not isinstance(table, dict):
        raise _fail(path, "variation", "expected a table [variation]")
    _check_keys(path, table, {"gradation_offset", "structural_scale"}, "variation.")
    values: dict[str, Any] = {}
    if "gradation_offset" in table:
        values["gradation_offset"] = _in_range(
            path, "variation.gradation_offset", table["gradation_offset"], 0.0, MAX_GRADATION_OFFSET
        )
    if "structural_scale" in table:
        pair = table["structural_scale"]
        key = "variation.structural_scale"
        if not (isinstance(pair, list) and len(pair) == 2):
            raise _fail(path, key, "expected [low, high]")
        low, high = (_in_range(path, key, v, *STRUCTURAL_SCALE_RANGE) for v in pair)
        if low > high:
            raise _fail(path, key, f"low {low:g} exceeds high {high:g}")
        values["structural_scale"] = (low, high)
    return Variation(**values)


def parse_train_recipe(path: str | os.PathLike) -> TrainRecipe:
    """Read and check a train recipe; raises :class:`InputError` naming the file and key."""
    path, data = read_toml(path)
    allowed = {
        "name",
        "version",
        "seed",
        "lod",
        "components",
        "rows",
        "jitter",
        "variation",
        "rattle",
    }
    _check_keys(path, data, allowed, "")
    name, version = name_and_version(path, data, "peacock_train")
    seed = int(_number(path, "seed", data.get("seed", 0), positive=False, integer=True))
    low, high = SEED_RANGE
    if seed > high:
        raise _fail(path, "seed", f"must lie in [{low}, {high}], got {seed}")
    lod = data.get("lod", "medium")
    if not isinstance(lod, str) or lod not in LODS:
        raise _fail(path, "lod", f"must be one of {', '.join(LODS)}, got {lod!r}")
    table = data.get("components")
    if not isinstance(table, dict) or not table:
        raise _fail(
            path, "components", "missing table [components] (prototype name = component asset)"
        )
    components: dict[str, Path] = {}
    for key, value in table.items():
        if not _NAME_RE.fullmatch(key):
            raise _fail(path, f"components.{key}", "must be a USD identifier")
        if not isinstance(value, str) or not value:
            raise _fail(path, f"components.{key}", f"expected a file path, got {value!r}")
        asset = resolve_relative(path, f"components.{key}", value)
        if not asset.is_file():
            raise _fail(path, f"components.{key}", f"no such component asset: {asset}")
        components[key] = asset
    rows_table = data.get("rows")
    if not isinstance(rows_table, list) or not rows_table:
        raise _fail(path, "rows", "missing [[rows]] (at least one row of the fan)")
    rows = tuple(_parse_row(path, i, row, components) for i, row in enumerate(rows_table))
    recipe = TrainRecipe(
        path,
        name,
        components,
        rows,
        seed,
        lod,
        version,
        _parse_jitter(path, data.get("jitter", {})),
        _parse_variation(path, data.get("variation", {})),
        parse_rattle(path, data["rattle"]) if "rattle" in data else None,
    )
    if recipe.feather_count > MAX_FEATHERS:
        raise _fail(path, "rows", f"{recipe.feather_count} feathers; at most {MAX_FEATHERS:,}")
    return recipe
