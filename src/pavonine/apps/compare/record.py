"""``baseline.json``, the record of a baseline (:mod:`pavonine.apps.compare.baselines`): how
it was rendered (``baseline``), how CI re-renders it (``check``) and its calibrated
``flip_threshold``. Every field comparisons use is checked when it is read, so that a bad value is
a one-line error naming the file and the field, never replaced by a default.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pavonine.apps.compare.methods import LoadedImage
from pavonine.base.errors import InputError
from pavonine.base.limits import check_seed

#: The record's layout (``format``); a newer one is refused rather than misread.
FORMAT_VERSION = 1


@dataclass(frozen=True)
class CheckSettings:
    """How a scene is rendered for CI: resolution (width, height), samples per pixel and seed.

    ``resolution=None`` means CI size: the stage's own aspect ratio, longer side ``CI_LONG_SIDE``.
    """

    resolution: tuple[int, int] | None = None
    spp: int = 64
    seed: int = 0

    def to_json(self) -> dict[str, Any]:
        size = list(self.resolution) if self.resolution else None
        return {"resolution": size, "spp": self.spp, "seed": self.seed}

    @classmethod
    def from_json(cls, data: Any, where: str) -> CheckSettings:
        """Settings recorded at ``where`` (``<baseline.json>: check``), every field checked."""
        if not isinstance(data, dict):
            raise InputError(
                where, f"must be an object with resolution, spp and seed, got {_shown(data)}"
            )
        size = _required(data, "resolution", where)
        if not isinstance(size, list) or len(size) != 2:
            raise InputError(f"{where}.resolution", f"must be [width, height], got {_shown(size)}")
        width, height = (_positive_int(v, f"{where}.resolution") for v in size)
        spp = _positive_int(_required(data, "spp", where), f"{where}.spp")
        seed = check_seed(f"{where}.seed", _required(data, "seed", where))
        return cls((width, height), spp, seed)


def recorded_settings(
    info: dict[str, Any], path: Path, mean: LoadedImage
) -> tuple[CheckSettings, CheckSettings, float]:
    """The baseline's settings, its check settings and its FLIP threshold from ``info`` (read
    from ``path`` by :func:`read_record`), the resolution checked against the ``mean`` image."""
    where = str(path)
    settings = CheckSettings.from_json(info["baseline"], f"{where}: baseline")
    if settings.resolution != mean.size:
        (width, height), size = settings.resolution or (0, 0), mean.size
        raise InputError(
            f"{where}: baseline.resolution",
            f"{width}x{height} differs from {mean.path.name}'s {size[0]}x{size[1]}",
        )
    check = CheckSettings.from_json(info["check"], f"{where}: check")
    threshold = info["flip_threshold"]
    if not _finite(threshold) or threshold <= 0:
        raise InputError(
            f"{where}: flip_threshold", f"must be a positive number, got {_shown(threshold)}"
        )
    return settings, check, float(threshold)


def read_record(path: Path, scene: str) -> dict[str, Any]:
    """``baseline.json``: a JSON object with the sections comparisons need (``baseline``,
    ``check``, ``flip_threshold``), or :class:`InputError` naming what is missing."""
    if not path.is_file():
        raise InputError(str(path), f"missing; run 'pavonine baseline update {scene}'")
    try:
        info = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise InputError(str(path), f"invalid JSON ({exc.msg} at line {exc.lineno})") from None
    except UnicodeDecodeError:
        raise InputError(str(path), "not UTF-8 text") from None
    if not isinstance(info, dict):
        raise InputError(str(path), f"must be a JSON object, got {_shown(info)}")
    version = info.get("format", FORMAT_VERSION)
    if not isinstance(version, int) or isinstance(version, bool) or version < 1:
        raise InputError(f"{path}: format", f"must be a whole number >= 1, got {_shown(version)}")
    if version > FORMAT_VERSION:
        raise InputError(
            f"{path}: format",
            f"{version} is newer than this Pavonine reads ({FORMAT_VERSION}); update Pavonine",
        )
    for key in ("baseline", "check", "flip_threshold"):
        if key not in info:
            raise InputError(f"{path}: {key}", f"missing; run 'pavonine baseline update {scene}'")
    return info


def _required(data: dict[str, Any], key: str, where: str) -> Any:
    """``data[key]``, or :class:`InputError` at ``<where>.<key>`` when absent."""
    if key not in data:
        raise InputError(f"{where}.{key}", "missing")
    return data[key]


def _positive_int(value: Any, where: str) -> int:
    """``value`` when it is a whole number ≥ 1 (not a bool, float or string)."""
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise InputError(where, f"must be a positive whole number, got {_shown(value)}")
    return value


def _finite(value: Any) -> bool:
    """A real, finite JSON number (not a bool or a string)."""
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _shown(value: Any) -> str:
    """``value`` (read from JSON) for a message, as JSON, shortened."""
    text = json.dumps(value)
    return text if len(text) <= 60 else text[:57] + "..."
