"""Render ceilings: how many pixels, samples per pixel and instances one render may ask for.

A stage (or a command line) can ask for a render that would run for days or exhaust memory:
``resolution = (100000, 100000)`` in its RenderSettings, a baseline whose ``check.spp`` is 10^12,
a PointInstancer with millions of instances. Each is refused *before* the expensive work starts
(before the stage is translated into Mitsuba objects, before Mitsuba builds the scene) with one
line naming the field and the flag that raises the ceiling. The ceilings are generous for real
work and overridable: ``--max-pixels``, ``--max-spp``, ``--max-instances`` on ``render``,
``check-renders`` and ``baseline update`` (``0`` = no ceiling). ``docs/reliability.md`` (Render
limits) documents them.

Coordinates are bounded too (:data:`MAX_COORDINATE`): Mitsuba works in float32, where squared
lengths of points beyond ~1e19 overflow, so a point or transform beyond the bound is treated like a
non-finite one (its faces or prim skipped with a warning naming the prim and the attribute).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pavonine.base.errors import InputError

#: Pixels of one image (width × height, before pixel-aspect resampling): 8192 × 8192. Memory:
#: Mitsuba's film and Pavonine's float64 pass buffers take ~100 bytes per pixel (6.7 GB here).
MAX_PIXELS = 8192 * 8192
#: Samples per pixel of one image (the shipped baselines use 512; their checks 128).
MAX_SPP = 65536
#: Mitsuba ``instance`` objects in one scene (PointInstancer instances plus instanceable prims).
#: Mitsuba 3.9's LLVM variants trace every instance into the render kernel: measured 11 s for
#: 50 instances and 54 s for 200 at 16×12, 1 spp (``tests/render/test_render_limits.py`` docstring),
#: so 1000 already means minutes before the first sample; the shipped train has 192.
MAX_INSTANCES = 1000
#: Largest |coordinate| (scene units) of a point or a world translation the renderer accepts.
MAX_COORDINATE = 1e15

FLAGS = {"pixels": "--max-pixels", "spp": "--max-spp", "instances": "--max-instances"}


@dataclass(frozen=True)
class RenderLimits:
    """Ceilings for one render; ``None`` means no ceiling (``--max-… 0``)."""

    pixels: int | None = MAX_PIXELS
    spp: int | None = MAX_SPP
    instances: int | None = MAX_INSTANCES

    @classmethod
    def from_flags(
        cls, pixels: int | None = None, spp: int | None = None, instances: int | None = None
    ) -> RenderLimits:
        """Limits from command-line values: ``None`` keeps the default, ``0`` lifts the ceiling."""

        def pick(value: int | None, default: int) -> int | None:
            if value is None:
                return default
            return None if value == 0 else int(value)

        return cls(pick(pixels, MAX_PIXELS), pick(spp, MAX_SPP), pick(instances, MAX_INSTANCES))

    def check_resolution(self, size: tuple[int, int], where: str) -> None:
        """Refuse an image of ``size`` (width, height) beyond :attr:`pixels` (or not positive)."""
        width, height = (int(v) for v in size)
        if width < 1 or height < 1:
            raise InputError(where, f"resolution must be positive, got {width}x{height}")
        if self.pixels is not None and width * height > self.pixels:
            raise InputError(
                where,
                f"{width}x{height} is {width * height:,} pixels, above the render ceiling of "
                f"{self.pixels:,} (raise it with {FLAGS['pixels']} N, or 0 for none)",
            )

    def check_spp(self, spp: int, where: str = "--spp") -> None:
        """Refuse ``spp`` samples per pixel beyond :attr:`spp` (or below 1)."""
        if spp < 1:
            raise InputError(where, f"must be at least 1, got {spp}")
        if self.spp is not None and spp > self.spp:
            raise InputError(
                where,
                f"{spp:,} samples per pixel is above the render ceiling of {self.spp:,} "
                f"(raise it with {FLAGS['spp']} N, or 0 for none)",
            )

    def check_instances(self, total: int, where: str) -> None:
        """Refuse a scene that would hold ``total`` instances, beyond :attr:`instances`."""
        if self.instances is not None and total > self.instances:
            raise InputError(
                where,
                f"{total:,} instances in the scene is above the render ceiling of "
                f"{self.instances:,} (raise it with {FLAGS['instances']} N, or 0 for none)",
            )


DEFAULT_LIMITS = RenderLimits()


def coordinates_ok(values, bound: float = MAX_COORDINATE) -> bool:
    """All of ``values`` (numbers or arrays) are finite and within ±``bound``."""
    import numpy as np

    array = np.asarray(values, dtype=np.float64)
    return bool(np.all(np.isfinite(array)) and np.all(np.abs(array) <= bound))


def finite_number(value: object) -> bool:
    """``value`` is a real, finite number."""
    try:
        return math.isfinite(float(value))  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return False
